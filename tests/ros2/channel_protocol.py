"""The channel protocol of the generated ROS 2 nodes (rssm_dsl/ros2/runtime/channels.py),
checked without DDS: an Outbox and an Inbox on fake nodes whose publishers put messages on an
in-process bus that the script delivers by hand, in any order, twice or never. Run with the
ROS venv's Python (real rclpy and std_msgs message classes; only the transport is fake):

    .cache/ros2-venv/bin/python tests/ros2/channel_protocol.py

Each scenario states a rule of docs/ros2.md ("Communication modes on ROS 2") and asserts it;
the script prints one line per scenario and exits 1 at the first that fails.
"""

from __future__ import annotations

import sys
from collections import defaultdict
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any

sys.path.insert(0, str(Path(__file__).resolve().parents[2]))

from std_msgs.msg import Float64  # type: ignore[import-not-found]

from rssm_core.modes import Mode, pairing
from rssm_dsl.ros2.runtime.channels import ChannelSpec, Inbox, Outbox
from rssm_dsl.ros2.runtime.loop import Loop


@dataclass
class Info:                      # the fields of the generated SampleInfo message
    epoch: int
    seq: int
    digest: int
    stamp: Any


@dataclass
class Ack:                       # the fields of the generated Ack message
    epoch: int
    seq: int


class Bus:
    """Topics as queues: a publish appends, :meth:`deliver` hands the oldest (or a chosen)
    message of a topic to its subscribers."""

    def __init__(self) -> None:
        self.queues: dict[str, list[Any]] = defaultdict(list)
        self.subs: dict[str, list[Callable[[Any], None]]] = defaultdict(list)

    def deliver(self, topic: str, index: int = 0) -> Any:
        msg = self.queues[topic].pop(index)
        for cb in self.subs[topic]:
            cb(msg)
        return msg

    def drop(self, topic: str) -> None:
        self.queues[topic].clear()

    def all(self, *topics: str) -> None:
        for t in topics:
            while self.queues[t]:
                self.deliver(t)


class _Pub:
    def __init__(self, bus: Bus, topic: str) -> None:
        self.bus, self.topic = bus, topic

    def publish(self, msg: Any) -> None:
        self.bus.queues[self.topic].append(msg)

    def get_subscription_count(self) -> int:
        return len(self.bus.subs[self.topic])


class _Sub:
    def __init__(self, bus: Bus, topic: str) -> None:
        self.bus, self.topic = bus, topic

    def get_publisher_count(self) -> int:
        return 1


class _Clock:
    class _Now:
        nanoseconds = 0

    def now(self) -> Any:
        return self._Now()


class FakeNode:
    def __init__(self, bus: Bus) -> None:
        self.bus = bus

    def create_publisher(self, _type: Any, topic: str, _qos: Any) -> _Pub:
        return _Pub(self.bus, topic)

    def create_subscription(self, _type: Any, topic: str, cb: Callable[[Any], None],
                            _qos: Any) -> _Sub:
        self.bus.subs[topic].append(cb)
        return _Sub(self.bus, topic)

    def get_clock(self) -> _Clock:
        return _Clock()


TOPIC = "/a1/c/x"
DATA, INFO, ACK = TOPIC, TOPIC + "/info", TOPIC + "/ack"


def channel(producer: Mode, consumer: Mode, resend: float = 3600.0
            ) -> tuple[Bus, Outbox, Inbox]:
    bus = Bus()
    spec = ChannelSpec("x", "a1.c.x->a2.c.x", TOPIC, Float64, Info, Ack,
                       ("msg", Float64, "data", ("float",)), pairing(producer, consumer))
    return bus, Outbox(FakeNode(bus), spec, resend), Inbox(FakeNode(bus), spec)


def done(op: Iterator[None]) -> bool:
    """Advance a send operation one step (the first publishes): True once it has ended."""
    try:
        next(op)
    except StopIteration:
        return True
    return False


B, N = Mode.BLOCKING, Mode.NONBLOCKING
SCENARIOS: list[Callable[[], None]] = []


def scenario(f: Callable[[], None]) -> Callable[[], None]:
    SCENARIOS.append(f)
    return f


@scenario
def blocking_send_ends_only_once_the_sample_is_taken() -> None:
    bus, out, inbox = channel(B, B)
    op = out.send(1.5)
    assert not done(op)
    bus.all(DATA, INFO)
    assert inbox.fresh() and not done(op), "arrived is not taken: the producer still waits"
    assert not bus.queues[ACK], "no acknowledgement before the receive takes the sample"
    assert inbox.take() == 1.5
    assert not done(op), "taken, but the Ack has not reached the producer yet"
    bus.all(ACK)
    assert done(op)


@scenario
def a_lost_ack_is_recovered_by_a_resend() -> None:
    bus, out, inbox = channel(B, N, resend=0.0)
    op = out.send(2.0)
    assert not done(op)
    bus.all(DATA, INFO)
    inbox.take()
    bus.drop(ACK)                                   # the acknowledgement is lost
    assert not done(op)                             # resends (period 0: at once)
    assert out.resent >= 1 and bus.queues[INFO]
    bus.all(DATA, INFO)                             # the consumer sees a sample it took
    assert not inbox.fresh(), "a resend of a taken sample is not fresh data again"
    bus.all(ACK)                                    # ... and acknowledges it again
    assert done(op)
    assert inbox.taken == 1


@scenario
def info_before_data_the_sample_is_there_only_with_both() -> None:
    bus, out, inbox = channel(N, B)
    list(out.send(3.0))
    bus.all(INFO)
    assert not inbox.fresh(), "an info without its data is no sample yet"
    bus.all(DATA)
    assert inbox.fresh() and inbox.take() == 3.0


@scenario
def nonblocking_producer_overwrites_and_the_consumer_counts_the_loss() -> None:
    bus, out, inbox = channel(N, N)
    for v in (1.0, 2.0, 3.0):
        assert done(out.send(v)), "a non-blocking send never waits"
    assert out.ack_sub is None and inbox.ack_pub is None, "nothing is acknowledged"
    bus.all(DATA, INFO)
    assert inbox.take() == 3.0, "the newest sample"
    assert inbox.overwritten == 2
    assert not inbox.fresh(), "after the take nothing is fresh: new(x) false, buffer kept"


@scenario
def an_older_sample_arriving_late_does_not_replace_a_newer_one() -> None:
    bus, out, inbox = channel(N, B)
    list(out.send(1.0))
    list(out.send(2.0))
    bus.deliver(DATA, 1)
    bus.deliver(INFO, 1)                            # sample 2 first
    bus.all(DATA, INFO)                             # then sample 1
    assert inbox.take() == 2.0


@scenario
def a_restarted_producer_is_new_data() -> None:
    bus, out, inbox = channel(B, B)
    op = out.send(5.0)
    assert not done(op)
    bus.all(DATA, INFO)
    inbox.take()
    bus.all(ACK)
    assert done(op)
    out.epoch += 1                                  # a restart draws a new epoch
    out.seq = 0
    out.acked = 0
    op = out.send(6.0)
    assert not done(op)
    bus.all(DATA, INFO)
    assert inbox.fresh() and inbox.take() == 6.0, "seq 1 of a new epoch counts as new"
    bus.all(ACK)
    assert done(op)


@scenario
def an_ack_of_another_epoch_or_an_older_sample_releases_nothing() -> None:
    bus, out, inbox = channel(B, B)
    op = out.send(1.0)
    assert not done(op)
    bus.all(DATA, INFO)
    bus.queues[ACK].append(Ack(epoch=out.epoch ^ 1, seq=out.seq))
    bus.queues[ACK].append(Ack(epoch=out.epoch, seq=out.seq - 1))
    bus.all(ACK)
    assert not done(op)
    inbox.take()
    bus.all(ACK)
    assert done(op)


@scenario
def a_blocking_producer_sends_the_next_sample_only_after_the_ack() -> None:
    bus, out, inbox = channel(B, N)
    op = out.send(1.0)
    assert not done(op)
    bus.all(DATA, INFO)
    for _ in range(3):
        assert not done(op)
    assert [i.seq for i in bus.queues[INFO]] == [], "no new sample while waiting"
    inbox.take()
    bus.all(ACK)
    assert done(op)
    op = out.send(2.0)
    assert not done(op)
    bus.all(DATA, INFO)
    assert inbox.take() == 2.0 and inbox.overwritten == 0, "nothing lost under blocking"


@scenario
def a_nonblocking_receive_takes_in_what_has_arrived_before_it_decides() -> None:
    """The node's receive operation (runtime/loop.py, Loop.take): a sample that has arrived
    but whose callbacks have not run yet is taken in first (the executor is drained), so a
    non-blocking receive finds it."""
    bus, out, inbox = channel(N, N)
    list(out.send(4.0))

    class Node:                 # the part of a Loop that Loop.take uses
        def __init__(self) -> None:
            self.inboxes = {"x": inbox}

        def drain(self) -> None:
            bus.all(DATA, INFO)

    op = Loop.take(Node(), "x")  # type: ignore[arg-type]
    try:
        next(op)
        raise AssertionError("a non-blocking receive does not wait")
    except StopIteration as stop:
        assert stop.value == (True, 4.0), stop.value
    op = Loop.take(Node(), "x")  # type: ignore[arg-type]
    try:
        next(op)
    except StopIteration as stop:
        assert stop.value == (False, None), "nothing newer: nothing taken"


def main() -> int:
    for s in SCENARIOS:
        try:
            s()
        except AssertionError as e:
            print(f"FAIL {s.__name__}: {e}")
            return 1
        print(f"ok {s.__name__}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
