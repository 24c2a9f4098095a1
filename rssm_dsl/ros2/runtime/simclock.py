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

The clock starts once the system is up: every node on ``use_sim_time``, having matched its
channels' peers, says so on ``/rssm/ready`` (``ReadyAnnouncer``), and the clock's device
publishes time 0 and steps only when it has heard the other ``rssm.system_nodes - 1`` nodes
(the generator writes the system's node count there). Without it a node still discovering
its peers would miss the first periods: the LWR4+'s effector node, say, leaving the arm
without torque for its first tens of milliseconds.
"""

from __future__ import annotations

import time
from collections.abc import Callable

from rclpy.clock import Clock as RosClock
from rclpy.clock import ClockType
from rclpy.node import Node
from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy
from rosgraph_msgs.msg import Clock  # type: ignore[import-not-found]
from std_msgs.msg import String  # type: ignore[import-not-found]

from .channels import time_msg
from .params import SetupError

CLOCK_TOPIC = "/clock"
READY_TOPIC = "/rssm/ready"
# every node's one announcement stays for the clock's reader, however late it subscribes
READY_QOS = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=1,
                       reliability=ReliabilityPolicy.RELIABLE,
                       durability=DurabilityPolicy.TRANSIENT_LOCAL)
READY_LOG_EVERY = 5.0     # seconds between the clock's "waiting for" lines
READY_REPEAT = 0.25       # seconds between a waiting node's announcements
# reliable keeps the newest time for reliable readers too; rclpy's own reader (best effort,
# depth 1) matches it
CLOCK_QOS = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=1,
                       reliability=ReliabilityPolicy.RELIABLE,
                       durability=DurabilityPolicy.VOLATILE)


class ReadyAnnouncer:
    """Says on READY_TOPIC that this node matched its peers: at once, then again every
    READY_REPEAT wall-clock seconds until its simulated time starts (one announcement alone
    was seen lost now and then between processes, leaving the clock waiting for good)."""

    def __init__(self, node: Node) -> None:
        self.node = node
        self.pub = node.create_publisher(String, READY_TOPIC, READY_QOS)
        self.msg = String(data=node.get_fully_qualified_name())
        self.pub.publish(self.msg)
        self.timer = node.create_timer(READY_REPEAT, self._again,
                                       clock=RosClock(clock_type=ClockType.STEADY_TIME))

    def _again(self) -> None:
        if self.node.get_clock().now().nanoseconds > 0:     # the clock has started
            self.timer.cancel()
            return
        self.pub.publish(self.msg)


def wait_for_system(node: Node, nodes: int, clock: SimClock,
                    spin: Callable[[float], None]) -> None:
    """Until the other ``nodes - 1`` nodes of the system announced that they are ready and
    each one's ``/clock`` reader is matched with ``clock``'s writer (a node whose time source
    has not found the clock yet would sleep through the first periods)."""
    me = node.get_fully_qualified_name()
    heard: set[str] = set()
    sub = node.create_subscription(String, READY_TOPIC, lambda m: heard.add(m.data), READY_QOS)
    next_log = time.monotonic() + READY_LOG_EVERY
    try:
        while (len(heard - {me}) < nodes - 1
               or clock.pub.get_subscription_count() < nodes - 1):
            if time.monotonic() >= next_log:
                node.get_logger().info(
                    f"the clock waits for the system's nodes: {len(heard - {me})} of "
                    f"{nodes - 1} ready ({', '.join(sorted(heard - {me})) or 'none yet'}), "
                    f"{clock.pub.get_subscription_count()} reading {CLOCK_TOPIC}")
                next_log = time.monotonic() + READY_LOG_EVERY
            spin(0.05)
    finally:
        node.destroy_subscription(sub)


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
