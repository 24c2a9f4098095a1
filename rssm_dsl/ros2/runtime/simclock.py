"""The clock of a simulated system: with ``use_sim_time`` the device node whose class simulates
its process (a class attribute ``simulation = True``, as the MuJoCo devices of rssmc's
standard library have) is the system's clock, as a robot simulator is in ROS.

Each iteration of the device advances the simulated time by exactly one period (``step`` gets
the period, not the wall-clock time that passed) and publishes it on ``/clock``
(``rosgraph_msgs/msg/Clock``) once its outputs are sent, so a node that wakes on that time
finds the measurement of that instant there. Every other node, on ``use_sim_time``, runs its
timer, its stamps and its traces on that clock. The iterations are paced against the
monotonic clock at ``rssm.real_time_factor`` simulated seconds per wall-clock second: a
late iteration starts at once but never less than one paced period after the previous one,
so the other nodes always get their share of wall time; nothing waits for them (the
communication modes stay as the specification says: a controller too slow for the chosen
factor misses periods, and its node counts them as overruns).
"""

from __future__ import annotations

import time
from collections.abc import Callable

from rclpy.node import Node
from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy
from rosgraph_msgs.msg import Clock  # type: ignore[import-not-found]

from .channels import time_msg
from .params import SetupError

CLOCK_TOPIC = "/clock"
# reliable keeps the newest time for reliable readers too; rclpy's own reader (best effort,
# depth 1) matches it
CLOCK_QOS = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=1,
                       reliability=ReliabilityPolicy.RELIABLE,
                       durability=DurabilityPolicy.VOLATILE)


def is_simulation(impl: object) -> bool:
    """The device class simulates its process (it can run on simulated time)."""
    return bool(getattr(impl, "simulation", False))


class SimClock:
    """Simulated time of a system, kept and published by its simulating device's node."""

    def __init__(self, node: Node, period: float, real_time_factor: float) -> None:
        if period <= 0:
            raise SetupError("a device that is the clock of a simulation needs a frequency "
                             "(parameter rssm.rate_hz > 0)")
        if not real_time_factor > 0:
            raise SetupError(f"parameter rssm.real_time_factor must be > 0, not "
                             f"{real_time_factor!r}")
        self.pub = node.create_publisher(Clock, CLOCK_TOPIC, CLOCK_QOS)
        self.period_ns = round(period * 1e9)
        self.wall_period = period / real_time_factor
        self.ns = 0
        self.last_start: float | None = None
        self.late = 0                 # iterations that started a paced period late or more

    def check_alone(self, node: Node) -> None:
        """Refuse a second clock: another node publishing /clock (seen once discovered; the
        devices' peers are matched by then)."""
        others = node.count_publishers(CLOCK_TOPIC) - 1
        if others > 0:
            raise SetupError(f"{others} other node(s) publish {CLOCK_TOPIC}: with use_sim_time "
                             "one simulating device per system can be the clock")

    def now_ns(self) -> int:
        return self.ns

    def wait(self, spin: Callable[[float], None]) -> None:
        """Until one paced period after the previous iteration started (spinning the node)."""
        now = time.monotonic()
        if self.last_start is not None:
            due = self.last_start + self.wall_period
            if now >= due + self.wall_period:
                self.late += 1
            while now < due:
                spin(due - now)
                now = time.monotonic()
        self.last_start = now

    def advance(self) -> None:
        """One period of simulated time has passed (the device stepped)."""
        self.ns += self.period_ns

    def publish(self) -> None:
        self.pub.publish(Clock(clock=time_msg(self.ns)))
