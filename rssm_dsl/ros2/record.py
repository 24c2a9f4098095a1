"""Record what a Cartesian tracking experiment does on ROS 2, from its topics alone: the set
points a control subsystem sends (a record with ``position`` and ``velocity``, e.g.
``/a1/c/cmd``), the states a device measures (a record with ``position``, e.g.
``/a1/E_lwr/state``), each paired with its ``SampleInfo`` (sequence number and the producer's
stamp, on simulated time when the system runs with ``use_sim_time``), and the behaviour
switches of the control subsystem from its diagnostics topic. Written as JSON lines
(rssm_dsl/ros2/tracking.py reads them). Stops after ``--switches`` switches, or ``--timeout``
wall-clock seconds.

Runs with the ROS venv's Python in the environment of the built workspace (it imports the
workspace's interfaces package and the runtime's ``digest``, which pairs an info with its data
message, so rssmc must be importable, as for the standard library's devices):

    python -m rssm_dsl.ros2.record --interfaces S_interfaces \\
        --setpoint /a1/c/cmd=S_interfaces/msg/CartesianSetpoint \\
        --state /a1/E_lwr/state=S_interfaces/msg/LwrState \\
        --status /a1/c/rssm/diagnostics --switches 2 --out run.jsonl
"""

from __future__ import annotations

import argparse
import importlib
import json
import sys
import time
from collections.abc import Callable
from typing import IO, Any


def _qos() -> tuple[Any, Any]:
    from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy

    data = QoSProfile(history=HistoryPolicy.KEEP_ALL, reliability=ReliabilityPolicy.RELIABLE,
                      durability=DurabilityPolicy.VOLATILE)
    status = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=100,
                        reliability=ReliabilityPolicy.RELIABLE,
                        durability=DurabilityPolicy.TRANSIENT_LOCAL)
    return data, status


def _vector(msg: Any, name: str) -> list[float] | None:
    value = getattr(msg, name, None)
    return None if value is None else [float(x) for x in value]


class Paired:
    """Data messages of one topic paired with their infos by digest (as a consumer does)."""

    def __init__(self, kind: str, write: Callable[[dict[str, Any]], None],
                 digest: Callable[[Any], int]) -> None:
        self.kind, self.write, self.digest = kind, write, digest
        self.data: dict[int, Any] = {}
        self.infos: dict[int, Any] = {}

    def on_data(self, msg: Any) -> None:
        key = self.digest(msg)
        info = self.infos.pop(key, None)
        if info is None:
            self.data[key] = msg
        else:
            self._emit(msg, info)

    def on_info(self, info: Any) -> None:
        msg = self.data.pop(info.digest, None)
        if msg is None:
            self.infos[info.digest] = info
        else:
            self._emit(msg, info)

    def _emit(self, msg: Any, info: Any) -> None:
        self.write({"kind": self.kind, "seq": int(info.seq),
                    "t": info.stamp.sec + info.stamp.nanosec * 1e-9,
                    "position": _vector(msg, "position"), "velocity": _vector(msg, "velocity")})


def _topic(item: str) -> tuple[str, Any]:
    """TOPIC=pkg/msg/Name: the topic and its message class."""
    topic, _, type_name = item.partition("=")
    package, _, name = type_name.replace("/msg/", "/").partition("/")
    if not topic or not package or not name:
        raise SystemExit(f"record: {item}: write TOPIC=PACKAGE/msg/MESSAGE")
    return topic, getattr(importlib.import_module(f"{package}.msg"), name)


def record(args: argparse.Namespace, out: IO[str]) -> int:
    import rclpy
    from rclpy.executors import SingleThreadedExecutor
    from rclpy.node import Node

    from rssm_dsl.ros2.runtime.channels import digest

    msg = importlib.import_module(f"{args.interfaces}.msg")
    data_qos, status_qos = _qos()
    rclpy.init()
    node = Node("rssm_recorder")
    executor = SingleThreadedExecutor()
    executor.add_node(node)
    switches = 0

    def write(row: dict[str, Any]) -> None:
        out.write(json.dumps(row) + "\n")

    def on_status(m: Any) -> None:
        nonlocal switches
        if m.event in ("switch", "end"):
            switches += 1
            write({"kind": "switch", "t": m.stamp.sec + m.stamp.nanosec * 1e-9,
                   "from": m.previous_behaviour, "to": m.behaviour, "switches": switches})

    for kind, item in (("setpoint", args.setpoint), ("state", args.state)):
        topic, cls = _topic(item)
        paired = Paired(kind, write, digest)
        node.create_subscription(cls, topic, paired.on_data, data_qos)
        node.create_subscription(msg.SampleInfo, topic + "/info", paired.on_info, data_qos)
    node.create_subscription(msg.SubsystemStatus, args.status, on_status, status_qos)
    print("ready", flush=True)
    end = time.monotonic() + args.timeout
    try:
        while switches < args.switches and time.monotonic() < end:
            executor.spin_once(timeout_sec=0.05)
        stop = time.monotonic() + 0.5          # the samples up to the last switch
        while time.monotonic() < stop:
            executor.spin_once(timeout_sec=0.05)
    finally:
        node.destroy_node()
        rclpy.try_shutdown()
    return 0 if switches >= args.switches else 1


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(prog="python -m rssm_dsl.ros2.record",
                                 description=__doc__.split("\n\n")[0])
    ap.add_argument("--interfaces", required=True, help="the workspace's interfaces package")
    ap.add_argument("--setpoint", required=True, metavar="TOPIC=PKG/msg/NAME")
    ap.add_argument("--state", required=True, metavar="TOPIC=PKG/msg/NAME")
    ap.add_argument("--status", required=True, help="the control subsystem's diagnostics")
    ap.add_argument("--switches", type=int, default=2)
    ap.add_argument("--timeout", type=float, default=300.0)
    ap.add_argument("--out", required=True)
    args = ap.parse_args(argv)
    with open(args.out, "w", encoding="utf-8") as out:
        return record(args, out)


if __name__ == "__main__":
    sys.exit(main())
