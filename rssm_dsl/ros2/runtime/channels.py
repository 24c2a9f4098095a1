"""The four communication modes of RSSM on ROS 2 topics (docs/ros2.md of rssmc,
"Communication modes on ROS 2").

A channel joins a producer's output buffer to a consumer's input buffer. On the wire it is

* the data topic ``/<agent>/<node>/<buffer>`` of the producer, carrying the value as a plain
  message: a standard one where the type has a standard counterpart
  (``std_msgs/msg/Float64``, ``geometry_msgs/msg/Vector3``, ...), otherwise the generated
  record message or ``<Type>Sample``; any ROS node can subscribe to it;
* the sample-info topic ``<data topic>/info`` carrying ``SampleInfo`` (``epoch``, ``seq``,
  ``digest``, ``stamp``) for every message the producer publishes on the data topic (resends
  too);
* when the producer is blocking, the acknowledgement topic ``<data topic>/ack`` carrying
  ``Ack`` (``epoch``, ``seq``) from the consumer back to the producer.

``epoch`` is a random number drawn by the producer at start, so a restarted producer's
samples count as new; ``seq`` numbers its samples from 1; ``digest`` is :func:`digest` of
the data message, which pairs the info with its data message (the two topics are not ordered
with respect to each other); ``stamp`` is the time of the producer's iteration that sent the
sample (:attr:`Outbox.clock`: its tick on the node's ROS clock, simulated time with
``use_sim_time``; the instant of the measurement for the device that keeps simulated time).
A sample is *there* for the consumer once both its info and a
data message with that digest have arrived; two samples of equal content have equal digests
and are interchangeable. The consumer counts the samples it never took (``overwritten``: gaps
in ``seq``).

All three topics use the same QoS on both sides (:data:`DATA_QOS`): reliable, keep-last
depth 1, volatile. Depth 1 is the net's one-place slot: a newer sample replaces one never
taken; volatile durability means no stale ("latched") sample is ever delivered to a late
subscriber.

* producer non-blocking: publish and go on; a sample nobody took is overwritten;
* producer blocking: publish, then wait for the consumer's ``Ack`` of exactly this sample,
  which the consumer sends when its receive operation *takes* the sample (not when it
  arrives); data and info are re-published every ``resend_period`` until acknowledged, and
  the consumer acknowledges an info of a sample it already took again;
* consumer blocking: wait until a sample newer than the last one taken is there, take it;
* consumer non-blocking: take the newest sample if one newer than the last taken is there,
  otherwise keep the buffer as it is (new(x) stays false).
"""

from __future__ import annotations

import array
import hashlib
import random
import struct
import time
from collections import OrderedDict
from collections.abc import Callable, Iterator
from typing import Any

import numpy as np
from builtin_interfaces.msg import Time as TimeMsg  # type: ignore[import-not-found]
from rclpy.node import Node
from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy

from rssm_core.modes import Pairing, Rule, rule
from rssm_core.records import dataclass
from rssm_core.values import Desc

from .messages import STAMPED_KINDS, from_msg, to_msg

DATA_QOS = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=1,
                      reliability=ReliabilityPolicy.RELIABLE,
                      durability=DurabilityPolicy.VOLATILE)
INFO_QOS = DATA_QOS
ACK_QOS = DATA_QOS
PENDING = 8          # data messages and infos a consumer keeps while they wait for their pair


@dataclass(frozen=True)
class ChannelSpec:
    """One end of a channel, as the generator describes it."""

    buffer: str              # the buffer on this side
    channel: str             # "a1.c.cmd->a1.e.lwr.setpoint"
    topic: str               # absolute data topic (the producer's)
    msg: Any                 # the data topic's message class
    info: Any                # the SampleInfo message class
    ack: Any                 # the Ack message class
    desc: Desc               # message descriptor of the data message (see .messages)
    pairing: Pairing         # the producer's and the consumer's mode

    @property
    def info_topic(self) -> str:
        return self.topic + "/info"

    @property
    def ack_topic(self) -> str:
        return self.topic + "/ack"

    @property
    def rule(self) -> Rule:
        return rule(self.pairing)

    @property
    def modes(self) -> str:
        return self.pairing.text


def time_msg(ns: int) -> Any:
    """A ``builtin_interfaces/Time`` of nanoseconds on a ROS clock."""
    return TimeMsg(sec=ns // 1_000_000_000, nanosec=ns % 1_000_000_000)


def _canonical(value: Any, out: list[bytes]) -> None:
    """The bytes of a message's content, field by field (what :func:`digest` hashes)."""
    if hasattr(value, "get_fields_and_field_types"):
        for name in value.get_fields_and_field_types():
            _canonical(getattr(value, name), out)
    elif isinstance(value, bool | np.bool_):
        out.append(b"b1" if value else b"b0")
    elif isinstance(value, int | np.integer):
        out.append(b"i" + int(value).to_bytes(9, "little", signed=True))
    elif isinstance(value, float | np.floating):
        out.append(b"f" + struct.pack("<d", float(value)))
    elif isinstance(value, str):
        data = value.encode("utf-8")
        out.append(b"s" + len(data).to_bytes(8, "little") + data)
    elif isinstance(value, bytes | bytearray):
        out.append(b"y" + len(value).to_bytes(8, "little") + bytes(value))
    elif isinstance(value, np.ndarray):
        out.append(b"n" + value.dtype.str.encode() + len(value).to_bytes(8, "little")
                   + np.ascontiguousarray(value).tobytes())
    elif isinstance(value, array.array):
        out.append(b"a" + value.typecode.encode() + len(value).to_bytes(8, "little")
                   + value.tobytes())
    else:
        items = list(value)
        out.append(b"l" + len(items).to_bytes(8, "little"))
        for item in items:
            _canonical(item, out)


def digest(msg: Any) -> int:
    """64 bits of BLAKE2b over the content of a message: equal for equal messages."""
    out: list[bytes] = []
    _canonical(msg, out)
    return int.from_bytes(hashlib.blake2b(b"".join(out), digest_size=8).digest(), "little")


class Outbox:
    """The producer's end of a channel."""

    def __init__(self, node: Node, spec: ChannelSpec, resend_period: float) -> None:
        self.spec = spec
        self.node = node
        self.blocking = spec.rule.producer_waits_until_taken
        self.resend_period = resend_period
        self.pub = node.create_publisher(spec.msg, spec.topic, DATA_QOS)
        self.info_pub = node.create_publisher(spec.info, spec.info_topic, INFO_QOS)
        self.ack_sub = (node.create_subscription(spec.ack, spec.ack_topic, self._on_ack, ACK_QOS)
                        if spec.rule.acknowledged else None)
        self.to_msg = to_msg(spec.desc)
        self.stamped = spec.desc[0] in STAMPED_KINDS
        self.frame_id = ""
        self.joint_names: list[str] = []
        if self.stamped:
            self._declare_header_params()
        self.epoch = random.getrandbits(32)
        self.seq = 0
        self.acked = 0
        self.resent = 0
        self.last: tuple[Any, Any] | None = None
        self.sent_at = 0.0
        self.events = 0
        # the time stamps of samples and headers (ns): the node's clock, unless its loop
        # gives the time of the iteration (loop.py: its tick; simclock.py)
        self.clock: Callable[[], int] = lambda: node.get_clock().now().nanoseconds

    def _declare_header_params(self) -> None:
        """``rssm.frame_id.<buffer>`` (the header's frame) and, for JointState,
        ``rssm.joint_names.<buffer>`` (default joint_1 .. joint_N)."""
        from rcl_interfaces.msg import ParameterDescriptor

        buffer = self.spec.buffer
        value = self.node.declare_parameter(f"rssm.frame_id.{buffer}", "",
                                            ParameterDescriptor(dynamic_typing=True)).value
        self.frame_id = str(value)
        if self.spec.desc[0] == "joints":
            default = [f"joint_{k}" for k in range(1, self.spec.desc[2] + 1)]
            names = self.node.declare_parameter(f"rssm.joint_names.{buffer}", default,
                                                ParameterDescriptor(dynamic_typing=True)).value
            self.joint_names = [str(n) for n in names]

    def _on_ack(self, msg: Any) -> None:
        self.events += 1
        if msg.epoch == self.epoch and msg.seq > self.acked:
            self.acked = msg.seq

    def matched(self, observers: int = 0) -> bool:
        """The consumer (and ``observers`` more subscribers) read the data and info topics,
        and the consumer's acknowledgements are heard when it sends them."""
        need = 1 + observers
        if (self.pub.get_subscription_count() < need
                or self.info_pub.get_subscription_count() < need):
            return False
        return self.ack_sub is None or self.ack_sub.get_publisher_count() >= 1

    def publish(self, value: Any) -> int:
        self.seq += 1
        msg = self.to_msg(value)
        stamp = time_msg(self.clock())
        if self.stamped:
            msg.header.stamp = stamp
            msg.header.frame_id = self.frame_id
            if self.joint_names:
                msg.name = self.joint_names
        info = self.spec.info(epoch=self.epoch, seq=self.seq, digest=digest(msg), stamp=stamp)
        self.last = (msg, info)
        self._put()
        return self.seq

    def _put(self) -> None:
        assert self.last is not None
        msg, info = self.last
        self.pub.publish(msg)
        self.info_pub.publish(info)
        self.sent_at = time.monotonic()

    def send(self, value: Any) -> Iterator[None]:
        """The send operation; a blocking producer yields until the consumer took it."""
        self.publish(value)
        if not self.blocking:
            return
        while self.acked < self.seq:
            if time.monotonic() - self.sent_at >= self.resend_period:
                self._put()
                self.resent += 1
            yield

    def flush(self, timeout: float) -> None:
        """Wait (bounded) until the reliable writers have delivered what they hold."""
        from rclpy.duration import Duration

        self.pub.wait_for_all_acked(Duration(nanoseconds=int(timeout * 1e9)))
        self.info_pub.wait_for_all_acked(Duration(nanoseconds=int(timeout * 1e9)))


@dataclass(frozen=True)
class Sample:
    """A sample that is there: its info and its data message."""

    epoch: int
    seq: int
    msg: Any


class Inbox:
    """The consumer's end of a channel: a one-sample mailbox of the newest sample."""

    def __init__(self, node: Node, spec: ChannelSpec) -> None:
        self.spec = spec
        self.blocking = spec.rule.consumer_waits_for_data
        self.sub = node.create_subscription(spec.msg, spec.topic, self._on_data, DATA_QOS)
        self.info_sub = node.create_subscription(spec.info, spec.info_topic, self._on_info,
                                                 INFO_QOS)
        self.ack_pub = (node.create_publisher(spec.ack, spec.ack_topic, ACK_QOS)
                        if spec.rule.acknowledged else None)
        self.from_msg = from_msg(spec.desc)
        self.data: OrderedDict[int, Any] = OrderedDict()    # digest -> data message
        self.infos: list[Any] = []                          # infos waiting for their data
        self.latest: Sample | None = None
        self.taken_epoch: int | None = None
        self.taken_seq = 0
        self.taken = 0
        self.overwritten = 0
        self.events = 0

    def _on_data(self, msg: Any) -> None:
        self.events += 1
        key = digest(msg)
        self.data[key] = msg
        self.data.move_to_end(key)
        while len(self.data) > PENDING:
            self.data.popitem(last=False)
        self._pair()

    def _on_info(self, info: Any) -> None:
        self.events += 1
        if not self._is_new(info.epoch, info.seq):
            if self.ack_pub is not None:    # a resend of a sample already taken: ack again
                self.ack_pub.publish(self.spec.ack(epoch=info.epoch, seq=info.seq))
            return
        self.infos = [*self.infos[-(PENDING - 1):], info]
        self._pair()

    def _pair(self) -> None:
        """The newest info whose data message is there makes its sample the latest (when it
        is newer); it and the infos before it are done."""
        for k in range(len(self.infos) - 1, -1, -1):
            info = self.infos[k]
            msg = self.data.get(info.digest)
            if msg is None:
                continue
            latest = self.latest
            if latest is None or info.epoch != latest.epoch or info.seq > latest.seq:
                self.latest = Sample(info.epoch, info.seq, msg)
            del self.infos[:k + 1]
            return

    def _is_new(self, epoch: int, seq: int) -> bool:
        return bool(epoch != self.taken_epoch or seq > self.taken_seq)

    def matched(self, observers: int = 0) -> bool:
        """The producer's data and info topics are heard (``observers``: see Outbox)."""
        if self.sub.get_publisher_count() < 1 or self.info_sub.get_publisher_count() < 1:
            return False
        return self.ack_pub is None or self.ack_pub.get_subscription_count() >= 1

    def fresh(self) -> bool:
        """A sample newer than the last one taken is there (the channel is `full`)."""
        return self.latest is not None and self._is_new(self.latest.epoch, self.latest.seq)

    def take(self) -> Any:
        """Take the newest sample (the receive operation); acknowledge it if asked to."""
        sample = self.latest
        assert sample is not None
        if sample.epoch == self.taken_epoch:
            self.overwritten += sample.seq - self.taken_seq - 1
        else:
            self.overwritten += sample.seq - 1
        self.taken_epoch, self.taken_seq = sample.epoch, sample.seq
        self.taken += 1
        if self.ack_pub is not None:
            self.ack_pub.publish(self.spec.ack(epoch=sample.epoch, seq=sample.seq))
        return self.from_msg(sample.msg)

    def flush(self, timeout: float) -> None:
        if self.ack_pub is not None:
            from rclpy.duration import Duration

            self.ack_pub.wait_for_all_acked(Duration(nanoseconds=int(timeout * 1e9)))
