"""A plain ROS 2 node, written by hand as any ROS engineer would, that knows nothing of rssmc:
it subscribes to a std_msgs/msg/Float64 topic with the default QoS of `ros2 topic echo`
(reliable, depth 10), collects the values, and after --duration seconds (or once it has
--count values) prints one JSON line: the values, and the topic names and types the graph
shows (rclpy's get_topic_names_and_types, what `ros2 topic list -t` prints). Run with the
ROS venv's Python."""

from __future__ import annotations

import argparse
import json
import sys
import time

import rclpy
from rclpy.node import Node
from std_msgs.msg import Float64


def main() -> int:
    ap = argparse.ArgumentParser()
    ap.add_argument("--topic", required=True)
    ap.add_argument("--duration", type=float, required=True)
    ap.add_argument("--count", type=int, default=0)
    args = ap.parse_args()
    rclpy.init()
    node = Node("hand_written_listener")
    values: list[float] = []
    node.create_subscription(Float64, args.topic, lambda m: values.append(m.data), 10)
    print("ready", flush=True)
    end = time.monotonic() + args.duration
    while time.monotonic() < end and not (args.count and len(values) >= args.count):
        rclpy.spin_once(node, timeout_sec=0.05)
    types = {name: list(kinds) for name, kinds in node.get_topic_names_and_types()}
    print(json.dumps({"values": values, "types": types}), flush=True)
    node.destroy_node()
    rclpy.try_shutdown()
    return 0


if __name__ == "__main__":
    sys.exit(main())
