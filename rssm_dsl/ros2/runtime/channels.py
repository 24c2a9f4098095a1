"""The four communication modes of RSSM on ROS 2 topics (docs/ros2.md of rssmc,
"Communication modes on ROS 2").

A channel joins a producer's output buffer to a consumer's input buffer. On the wire it is
one data topic, ``/<agent>/<node>/<buffer>`` of the producer, carrying ``<Type>Sample``
messages (``epoch``, ``seq``, ``value``), plus, when the producer is blocking, an
acknowledgement topic ``<data topic>/ack`` carrying ``Ack`` messages (``epoch``, ``seq``)
from the consumer back to the producer. Both sides use the same QoS (:data:`DATA_QOS`,
:data:`ACK_QOS`): reliable, keep-last depth 1, volatile. Depth 1 is the net's one-place slot:
a newer sample replaces one never taken; volatile durability means no stale ("latched")
sample is ever delivered to a late subscriber.

* producer non-blocking: publish and go on; a sample nobody took is overwritten;
* producer blocking: publish, then wait for the consumer's ``Ack`` of exactly this sample,
  which the consumer sends when its receive operation *takes* the sample (not when it
  arrives); the sample is re-published every ``resend_period`` until acknowledged;
* consumer blocking: wait until a sample newer than the last one taken is there, take it;
* consumer non-blocking: take the newest sample if one newer than the last taken is there,
  otherwise keep the buffer as it is (new(x) stays false).

``epoch`` is a random number drawn by the producer at start, so a restarted producer's
samples count as new; ``seq`` numbers its samples from 1. The consumer counts the samples it
never took (``overwritten``: gaps in ``seq``).
"""

from __future__ import annotations

import random
import time
from collections.abc import Iterator
from dataclasses import dataclass
from typing import Any

from rclpy.node import Node
from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy

from rssm_core.modes import Pairing, Rule, rule
from rssm_core.values import Desc

from .messages import from_msg, to_msg

DATA_QOS = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=1,
                      reliability=ReliabilityPolicy.RELIABLE,
                      durability=DurabilityPolicy.VOLATILE)
ACK_QOS = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=1,
                     reliability=ReliabilityPolicy.RELIABLE,
                     durability=DurabilityPolicy.VOLATILE)


@dataclass(frozen=True)
class ChannelSpec:
    """One end of a channel, as the generator describes it."""

    buffer: str              # the buffer on this side
    channel: str             # "a1.c.cmd->a1.e.lwr.setpoint"
    topic: str               # absolute data topic (the producer's)
    sample: Any              # the <Type>Sample message class
    ack: Any                 # the Ack message class
    desc: Desc               # message descriptor of the value (see .messages)
    pairing: Pairing         # the producer's and the consumer's mode

    @property
    def ack_topic(self) -> str:
        return self.topic + "/ack"

    @property
    def rule(self) -> Rule:
        return rule(self.pairing)

    @property
    def modes(self) -> str:
        return self.pairing.text


class Outbox:
    """The producer's end of a channel."""

    def __init__(self, node: Node, spec: ChannelSpec, resend_period: float) -> None:
        self.spec = spec
        self.blocking = spec.rule.producer_waits_until_taken
        self.resend_period = resend_period
        self.pub = node.create_publisher(spec.sample, spec.topic, DATA_QOS)
        self.ack_sub = (node.create_subscription(spec.ack, spec.ack_topic, self._on_ack, ACK_QOS)
                        if spec.rule.acknowledged else None)
        self.to_msg = to_msg(spec.desc)
        self.epoch = random.getrandbits(32)
        self.seq = 0
        self.acked = 0
        self.resent = 0
        self.last: Any = None
        self.sent_at = 0.0
        self.events = 0

    def _on_ack(self, msg: Any) -> None:
        self.events += 1
        if msg.epoch == self.epoch and msg.seq > self.acked:
            self.acked = msg.seq

    def matched(self) -> bool:
        if self.pub.get_subscription_count() < 1:
            return False
        return self.ack_sub is None or self.ack_sub.get_publisher_count() >= 1

    def publish(self, value: Any) -> int:
        self.seq += 1
        msg = self.spec.sample(epoch=self.epoch, seq=self.seq, value=self.to_msg(value))
        self.pub.publish(msg)
        self.last = msg
        self.sent_at = time.monotonic()
        return self.seq

    def send(self, value: Any) -> Iterator[None]:
        """The send operation; a blocking producer yields until the consumer took it."""
        self.publish(value)
        if not self.blocking:
            return
        while self.acked < self.seq:
            if time.monotonic() - self.sent_at >= self.resend_period:
                self.pub.publish(self.last)
                self.sent_at = time.monotonic()
                self.resent += 1
            yield

    def flush(self, timeout: float) -> None:
        """Wait (bounded) until the reliable writer has delivered what it holds."""
        from rclpy.duration import Duration

        self.pub.wait_for_all_acked(Duration(nanoseconds=int(timeout * 1e9)))


class Inbox:
    """The consumer's end of a channel: a one-sample mailbox of the newest sample."""

    def __init__(self, node: Node, spec: ChannelSpec) -> None:
        self.spec = spec
        self.blocking = spec.rule.consumer_waits_for_data
        self.sub = node.create_subscription(spec.sample, spec.topic, self._on_sample, DATA_QOS)
        self.ack_pub = (node.create_publisher(spec.ack, spec.ack_topic, ACK_QOS)
                        if spec.rule.acknowledged else None)
        self.from_msg = from_msg(spec.desc)
        self.latest: Any = None
        self.taken_epoch: int | None = None
        self.taken_seq = 0
        self.taken = 0
        self.overwritten = 0
        self.events = 0

    def _on_sample(self, msg: Any) -> None:
        self.events += 1
        if self._is_new(msg):
            if (self.latest is None or msg.epoch != self.latest.epoch
                    or msg.seq > self.latest.seq):
                self.latest = msg
        elif self.ack_pub is not None:     # a resend of a sample already taken: ack again
            self.ack_pub.publish(self.spec.ack(epoch=msg.epoch, seq=msg.seq))

    def _is_new(self, msg: Any) -> bool:
        return bool(msg.epoch != self.taken_epoch or msg.seq > self.taken_seq)

    def matched(self) -> bool:
        if self.sub.get_publisher_count() < 1:
            return False
        return self.ack_pub is None or self.ack_pub.get_subscription_count() >= 1

    def fresh(self) -> bool:
        """A sample newer than the last one taken is there (the channel is `full`)."""
        return self.latest is not None and bool(self._is_new(self.latest))

    def take(self) -> Any:
        """Take the newest sample (the receive operation); acknowledge it if asked to."""
        msg = self.latest
        if msg.epoch == self.taken_epoch:
            self.overwritten += msg.seq - self.taken_seq - 1
        else:
            self.overwritten += msg.seq - 1
        self.taken_epoch, self.taken_seq = msg.epoch, msg.seq
        self.taken += 1
        if self.ack_pub is not None:
            self.ack_pub.publish(self.spec.ack(epoch=msg.epoch, seq=msg.seq))
        return self.from_msg(msg.value)

    def flush(self, timeout: float) -> None:
        if self.ack_pub is not None:
            from rclpy.duration import Duration

            self.ack_pub.wait_for_all_acked(Duration(nanoseconds=int(timeout * 1e9)))
