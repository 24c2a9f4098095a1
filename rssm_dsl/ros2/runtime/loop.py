"""What subsystem and device nodes share: their channel ends, the pacing timer, and
spinning the node while an operation waits.

Time: the node's ROS clock paces the iterations (its timer). With the standard parameter
``use_sim_time`` that clock is ``/clock`` (simulated time, published by the device that
simulates the system: runtime/simclock.py), and so are the iterations' times, the overruns
and the stamps; otherwise iterations are timed on the monotonic clock."""

from __future__ import annotations

import time
from collections.abc import Callable, Generator, Iterator
from typing import Any

from rclpy.executors import SingleThreadedExecutor
from rclpy.node import Node

from .channels import ChannelSpec, Inbox, Outbox
from .params import SetupError, declare
from .simclock import ReadyAnnouncer

WAIT_SLICE = 0.05          # seconds spun at a time while an operation waits
Arrangement = tuple[Any, ...]     # ("buf", NAME) | ("seq", (...)) | ("par", (...))


class Loop:
    def __init__(self, node: Node, executor: SingleThreadedExecutor,
                 inputs: tuple[ChannelSpec, ...], outputs: tuple[ChannelSpec, ...],
                 rate_hz: float, resend_period: float) -> None:
        self.node, self.executor = node, executor
        self.log = node.get_logger()
        self.inboxes = {c.buffer: Inbox(node, c) for c in inputs}
        self.outboxes = {c.buffer: Outbox(node, c, resend_period) for c in outputs}
        self.ticked = 0
        self.overruns = 0
        self.last_start: float | None = None
        self.period = 1.0 / rate_hz if rate_hz > 0 else 0.0
        self.sim_time = bool(node.get_parameter("use_sim_time").value)
        self.ready: ReadyAnnouncer | None = None   # on use_sim_time (simclock.py)
        self.clock = node.get_clock()
        self.timer = node.create_timer(self.period, self._on_tick) if self.period else None
        # the current iteration's tick on the node's ROS clock (ns): the stamp of what it sends
        self.first_ns: int | None = None
        self.tick_ns = 0
        for box in self.outboxes.values():
            box.clock = self.tick

    def tick(self) -> int:
        return self.tick_ns

    def _mark_tick(self) -> None:
        """The tick the iteration belongs to: the last one at or before now, the periods
        counted from the first iteration (as the interpreter's ticks are from time 0); without
        a rate, when it started."""
        ns = self.clock.now().nanoseconds
        if self.first_ns is None or not self.period:
            self.first_ns = self.first_ns if self.first_ns is not None else ns
            self.tick_ns = ns
            return
        period = round(self.period * 1e9)
        self.tick_ns = self.first_ns + (ns - self.first_ns) // period * period

    def now(self) -> float:
        """Seconds on the node's time: simulated with use_sim_time, else monotonic."""
        if self.sim_time:
            return float(self.clock.now().nanoseconds) * 1e-9
        return time.monotonic()

    def _on_tick(self) -> None:
        self.ticked += 1

    def events(self) -> int:
        return (self.ticked + sum(b.events for b in self.inboxes.values())
                + sum(b.events for b in self.outboxes.values()))

    def spin(self, timeout: float) -> None:
        self.executor.spin_once(timeout_sec=timeout)

    def drain(self) -> None:
        """Run every callback that is ready now (samples that arrived go to their inbox)."""
        quiet = 0
        while quiet < 2:
            before = self.events()
            self.spin(0.0)
            quiet = quiet + 1 if self.events() == before else 0

    def drive(self, gen: Generator[None, None, Any]) -> Any:
        """Run an operation that yields while it waits, spinning the node meanwhile."""
        try:
            while True:
                next(gen)
                self.spin(WAIT_SLICE)
        except StopIteration as stop:
            return stop.value

    def wait_for_peers(self) -> None:
        """Wait until every channel's topics are matched on the other side, so that no
        sample is published before its reader exists; and, with parameter ``rssm.observers``
        N > 0, until every output's topics have N subscribers more (a recorder, rosbag)."""
        observers = declare(self.node, "rssm.observers", 0)
        if isinstance(observers, bool) or not isinstance(observers, int) or observers < 0:
            raise SetupError(f"parameter rssm.observers must be an int >= 0, not {observers!r}")
        ends: list[Inbox | Outbox] = [*self.inboxes.values(), *self.outboxes.values()]
        next_log = time.monotonic() + 5.0
        while True:
            missing = [box.spec for box in ends if not box.matched(observers)]
            if not missing:
                if self.sim_time:
                    self.ready = ReadyAnnouncer(self.node)
                return
            if time.monotonic() >= next_log:
                self.log.info("waiting for the peers of " + ", ".join(
                    f"{c.channel} ({c.topic})" for c in missing))
                next_log = time.monotonic() + 5.0
            self.spin(0.1)

    def wait_tick(self) -> None:
        """Pace the iterations at the node's rate (the first one starts at once, and the
        periods count from it); an iteration that starts two periods or more after the
        previous one is an overrun."""
        now = self.now()
        last = self.last_start
        if self.timer is not None and last is None:
            self.timer.reset()
        elif self.timer is not None and last is not None:
            while not self.ticked:
                self.spin(WAIT_SLICE)
            now = self.now()
            if now - last >= 2 * self.period:
                self.overruns += 1
        self.ticked = 0
        self.last_start = now
        self._mark_tick()

    def take(self, buffer: str) -> Generator[None, None, tuple[bool, Any]]:
        """The receive operation of one buffer per its consumer mode: (taken, value)."""
        box = self.inboxes[buffer]
        if box.blocking:
            while not box.fresh():
                yield
        else:
            self.drain()
            if not box.fresh():
                return False, None
        return True, box.take()

    def arranged(self, arr: Arrangement,
                 leaf: Callable[[str], Iterator[None]]) -> Generator[None, None, None]:
        """A series-parallel arrangement: `seq` one after the other, `par` all at once."""
        kind = arr[0]
        if kind == "buf":
            yield from leaf(arr[1])
        elif kind == "seq":
            for item in arr[1]:
                yield from self.arranged(item, leaf)
        else:
            running: list[Iterator[None]] = [self.arranged(item, leaf) for item in arr[1]]
            while running:
                running = [g for g in running if _advance(g)]
                if running:
                    yield

    def flush(self, timeout: float) -> None:
        boxes: list[Inbox | Outbox] = [*self.outboxes.values(), *self.inboxes.values()]
        for box in boxes:
            box.flush(timeout)


def _advance(gen: Iterator[None]) -> bool:
    """Advance a waiting operation by one step; False once it has finished."""
    try:
        next(gen)
    except StopIteration:
        return False
    return True
