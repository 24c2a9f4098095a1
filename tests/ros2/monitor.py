"""A DDS observer for the ROS 2 tests, run with the ROS venv's Python: it subscribes to the
diagnostics topics of subsystem nodes (SubsystemStatus, reliable, transient local, as the
nodes publish them), to data topics (--data TOPIC=pkg/msg/Type: any message type, e.g.
std_msgs/msg/Int64) and to the sample-info topics of channels (--info TOPIC: SampleInfo on
TOPIC/info), all reliable, keep all, and writes what it hears as JSON lines. It prints
"ready" once subscribed and exits after --duration
seconds, or once --until-ended diagnostics topics reported the end of their subsystem."""

from __future__ import annotations

import argparse
import importlib
import json
import sys
import time
from typing import Any

import rclpy
from rclpy.executors import SingleThreadedExecutor
from rclpy.node import Node
from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy

STATUS_QOS = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=100,
                        reliability=ReliabilityPolicy.RELIABLE,
                        durability=DurabilityPolicy.TRANSIENT_LOCAL)
DATA_QOS = QoSProfile(history=HistoryPolicy.KEEP_ALL, reliability=ReliabilityPolicy.RELIABLE,
                      durability=DurabilityPolicy.VOLATILE)


def main() -> int:
    ap = argparse.ArgumentParser()
    ap.add_argument("--interfaces", required=True)
    ap.add_argument("--duration", type=float, required=True)
    ap.add_argument("--out", required=True)
    ap.add_argument("--diagnostics", action="append", default=[])
    ap.add_argument("--data", action="append", default=[])
    ap.add_argument("--info", action="append", default=[])
    ap.add_argument("--until-ended", type=int, default=0)
    args = ap.parse_args()
    msg = importlib.import_module(f"{args.interfaces}.msg")
    rclpy.init()
    node = Node("rssm_test_monitor")
    executor = SingleThreadedExecutor()
    executor.add_node(node)
    out = open(args.out, "w", encoding="utf-8")  # noqa: SIM115
    ended: set[str] = set()
    start = time.monotonic()

    def write(record: dict[str, Any]) -> None:
        record["t"] = round(time.monotonic() - start, 6)
        out.write(json.dumps(record) + "\n")

    def on_status(topic: str) -> Any:
        def cb(m: Any) -> None:
            write({"topic": topic, "subsystem": m.subsystem, "event": m.event,
                   "behaviour": m.behaviour, "previous": m.previous_behaviour,
                   "iteration": m.iteration, "switches": m.switches,
                   "new_data": list(m.new_data), "data_cases": list(m.data_cases)})
            if m.event == "end":
                ended.add(topic)
        return cb

    def on_info(topic: str) -> Any:
        def cb(m: Any) -> None:
            write({"topic": topic, "epoch": m.epoch, "seq": m.seq})
        return cb

    def on_data(topic: str) -> Any:
        def cb(m: Any) -> None:
            write({"topic": topic, "data": str(m)})
        return cb

    for topic in args.diagnostics:
        node.create_subscription(msg.SubsystemStatus, topic, on_status(topic), STATUS_QOS)
    for topic in args.info:
        node.create_subscription(msg.SampleInfo, topic + "/info", on_info(topic), DATA_QOS)
    for item in args.data:
        topic, _, type_name = item.partition("=")
        package, _, name = type_name.split("/")
        cls = getattr(importlib.import_module(f"{package}.msg"), name)
        node.create_subscription(cls, topic, on_data(topic), DATA_QOS)
    print("ready", flush=True)
    try:
        while time.monotonic() - start < args.duration:
            if args.until_ended and len(ended) >= args.until_ended:
                break
            executor.spin_once(timeout_sec=0.05)
    finally:
        nodes = sorted(f"{ns.rstrip('/')}/{n}" for n, ns in node.get_node_names_and_namespaces())
        print("discovered:", " ".join(nodes), flush=True)
        out.close()
        node.destroy_node()
        rclpy.try_shutdown()
    return 0


if __name__ == "__main__":
    sys.exit(main())
