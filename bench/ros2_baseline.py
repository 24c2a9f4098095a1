"""Hand-written rclpy baselines for bench/ros2.py, run with the ROS venv's Python: the same
QoS as the generated nodes (reliable, keep last 1, volatile), std_msgs/Int64 payloads.

    python ros2_baseline.py pinger N     # publish n, wait for the echo of n; print RTTs
    python ros2_baseline.py echoer       # echo every sample back
    python ros2_baseline.py flood S      # publish as fast as possible for S s
    python ros2_baseline.py sink S       # count samples taken in S s (newest wins)
Each prints one JSON line with its figures."""

from __future__ import annotations

import contextlib
import json
import statistics
import sys
import time

import rclpy
from rclpy.node import Node
from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy
from std_msgs.msg import Int64

QOS = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=1,
                 reliability=ReliabilityPolicy.RELIABLE, durability=DurabilityPolicy.VOLATILE)


def spin_until(node: Node, pred, timeout: float) -> bool:  # type: ignore[no-untyped-def]
    end = time.monotonic() + timeout
    while not pred():
        if time.monotonic() > end:
            return False
        rclpy.spin_once(node, timeout_sec=0.05)
    return True


def main() -> int:
    role = sys.argv[1]
    rclpy.init()
    node = Node(f"baseline_{role}")
    got: list[int] = []
    if role == "echoer":
        pub = node.create_publisher(Int64, "bench_ack", QOS)
        node.create_subscription(Int64, "bench_req", lambda m: pub.publish(m), QOS)
        with contextlib.suppress(KeyboardInterrupt, rclpy.executors.ExternalShutdownException):
            rclpy.spin(node)
        return 0
    if role == "pinger":
        n = int(sys.argv[2])
        pub = node.create_publisher(Int64, "bench_req", QOS)
        node.create_subscription(Int64, "bench_ack", lambda m: got.append(m.data), QOS)
        spin_until(node, lambda: pub.get_subscription_count() > 0 and
                   node.count_publishers("bench_ack") > 0, 60)
        rtts = []
        for k in range(n):
            t0 = time.perf_counter()
            pub.publish(Int64(data=k))
            if not spin_until(node, lambda k=k: bool(got) and got[-1] == k, 5):
                continue
            rtts.append(time.perf_counter() - t0)
        print(json.dumps({"rtt_median_ms": 1e3 * statistics.median(rtts[10:]),
                          "rtt_p90_ms": 1e3 * statistics.quantiles(rtts[10:], n=10)[-1],
                          "round_trips": len(rtts)}), flush=True)
        return 0
    seconds = float(sys.argv[2])
    if role == "flood":
        pub = node.create_publisher(Int64, "bench_flood", QOS)
        spin_until(node, lambda: pub.get_subscription_count() > 0, 60)
        t0, k = time.perf_counter(), 0
        while time.perf_counter() - t0 < seconds:
            pub.publish(Int64(data=k))
            k += 1
        print(json.dumps({"published_per_s": k / seconds}), flush=True)
        return 0
    node.create_subscription(Int64, "bench_flood", lambda m: got.append(m.data), QOS)
    spin_until(node, lambda: bool(got), 60)
    t0, start = time.perf_counter(), len(got)
    while time.perf_counter() - t0 < seconds:
        rclpy.spin_once(node, timeout_sec=0.05)
    print(json.dumps({"taken_per_s": (len(got) - start) / seconds}), flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
