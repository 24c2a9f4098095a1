"""ROS 2 backend figures.

1. Generation: `rssmc ros2` on the 100-agent ring (rssm_dsl.synth.ring_system(100)): time
   to generate the workspace from a compiled specification and to write it, as the best of
   a few runs, with the compile time of the same file measured in the same run as baseline.
2. On ROS 2 (the PyPI ros-jazzy wheels; the ROS venv of the tests is created if needed):
   two generated nodes (agent lat: c -> e.sink blocking/blocking; agent rate: the same with
   nonblocking/nonblocking), run free (rssm.rate_hz 0), against hand-written rclpy
   baselines with the same QoS (bench/ros2_baseline.py):
   * blocking channel: time of one producer iteration (publish, wait until the consumer
     took the sample and its acknowledgement is back) vs. a plain publish/echo round trip;
   * non-blocking channel: samples the producer publishes per second and the consumer
     takes per second vs. a plain publishing loop and subscriber.

    python bench/ros2.py [--repeat 3] [--seconds 8] [--no-ros]
"""

from __future__ import annotations

import argparse
import itertools
import json
import os
import signal
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

from rssm_dsl.pipeline import compile_file
from rssm_dsl.ros2 import toolchain
from rssm_dsl.ros2.generator import generate, write_workspace
from rssm_dsl.synth import ring_system

ROOT = Path(__file__).resolve().parent.parent
BASELINE = Path(__file__).resolve().parent / "ros2_baseline.py"

SPEC = """// bench/ros2.py: one blocking and one non-blocking channel between two generated nodes.
system bench {
%s}
"""
AGENT = """  agent %(name)s {
    control c {
      memory n: int = 0
      output data: int to e.sink %(mode)s
      behaviour count {
        update data { data := n }
        update memory { n := n + 1 }
        terminal never when n < 0
        send data
      }
      initial count
      switch count -> end when never
    }
    effector sink {
      input data: int from c %(mode)s
      memory last: int = 0
      behaviour take {
        update memory {
          case new(data):
            last := data
          otherwise:
            skip
        }
        terminal never when last < -1
        receive data
      }
      initial take
      switch take -> end when never
    }
  }
"""


def bench_generation(repeat: int) -> None:
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "ring100.rssm"
        text = ring_system(100)
        path.write_text(text)
        compile_s, gen_s, write_s = [], [], []
        files = 0
        for _ in range(repeat):
            t0 = time.perf_counter()
            comp = compile_file(path)
            t1 = time.perf_counter()
            ws = generate(comp)
            t2 = time.perf_counter()
            assert not isinstance(ws, list)
            out = Path(tmp) / "ws" / "src"
            write_workspace(ws, out)
            t3 = time.perf_counter()
            compile_s.append(t1 - t0)
            gen_s.append(t2 - t1)
            write_s.append(t3 - t2)
            files = len(ws.files)
        size = sum(len(t) for t in ws.files.values())
        print(f"generation, ring_system(100): {text.count(chr(10))} lines, {len(ws.packages)} "
              f"packages, {files} files, {size / 1e6:.1f} MB")
        print(f"  compile (baseline) {min(compile_s):.3f} s   generate {min(gen_s):.3f} s   "
              f"write {min(write_s):.3f} s   generate/compile = {min(gen_s) / min(compile_s):.2f}")


def _events(path: Path) -> list[dict[str, Any]]:
    return [json.loads(x) for x in path.read_text().splitlines() if x.strip()]


def _run(cmd: list[str], env: dict[str, str], timeout: float) -> str:
    return subprocess.run(cmd, env=env, capture_output=True, text=True, timeout=timeout,
                          check=False).stdout


def bench_ros(seconds: float) -> None:
    why = toolchain.unsupported_reason()
    if why is not None:
        print(f"ROS 2 figures skipped: {why}")
        return
    venv = toolchain.ensure_venv(ROOT / ".cache" / "ros2-venv")
    with tempfile.TemporaryDirectory() as tmp_s:
        tmp = Path(tmp_s)
        spec = tmp / "bench.rssm"
        spec.write_text(SPEC % (AGENT % {"name": "lat", "mode": "blocking"}
                                + AGENT % {"name": "rate", "mode": "nonblocking"}))
        ws = generate(compile_file(spec))
        assert not isinstance(ws, list)
        write_workspace(ws, tmp / "ws" / "src")
        env = toolchain.ros_env(venv, 90 + os.getpid() % 10, tmp / "log")
        t0 = time.perf_counter()
        toolchain.colcon_build(tmp / "ws", env)
        print(f"colcon build of the bench workspace: {time.perf_counter() - t0:.1f} s")
        env = toolchain.workspace_env(tmp / "ws", env)
        env["RSSM_TRACE_DIR"] = str(tmp / "trace")
        for agent in ("lat", "rate"):
            launch = tmp / "ws" / "install" / f"bench_{agent}" / "share" / f"bench_{agent}" / \
                "launch" / f"{agent}.launch.py"
            subprocess.run([sys.executable, "-m", "rssm_dsl.ros2.launch_runner", "--duration",
                            str(seconds), "-p", "*:rssm.rate_hz:=0.0", "-p",
                            "*:rssm.diagnostics_period:=1.0", str(launch)], env=env,
                           capture_output=True, timeout=seconds + 60, check=False)
        py = str(venv.python)
        # blocking: producer iteration intervals in the steady part of the run
        prod = [e["t"] for e in _events(tmp / "trace" / "lat.c.jsonl")
                if e["event"] == "iteration"]
        steady = prod[len(prod) // 5:]
        gaps = [b - a for a, b in itertools.pairwise(steady)]
        echo = subprocess.Popen([py, str(BASELINE), "echoer"], env=env,
                                stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
        try:
            base = json.loads(_run([py, str(BASELINE), "pinger", "2000"], env, 120) or "{}")
        finally:
            echo.send_signal(signal.SIGINT)
            echo.wait(timeout=20)
        med = 1e3 * statistics.median(gaps)
        p90 = 1e3 * statistics.quantiles(gaps, n=10)[-1]
        print(f"blocking channel (generated nodes): {len(prod)} sends, one send + ack "
              f"median {med:.3f} ms, p90 {p90:.3f} ms")
        if base:
            print(f"  baseline rclpy publish/echo round trip: median "
                  f"{base['rtt_median_ms']:.3f} ms, p90 {base['rtt_p90_ms']:.3f} ms; "
                  f"generated/baseline = {med / base['rtt_median_ms']:.2f}")
        # non-blocking: producer publications and consumer takes per second
        prod_ev = [e for e in _events(tmp / "trace" / "rate.c.jsonl")
                   if e["event"] == "iteration"]
        cons_ev = [e for e in _events(tmp / "trace" / "rate.e.sink.jsonl")
                   if e["event"] == "iteration"]
        p = prod_ev[len(prod_ev) // 5:]
        c = [e for e in cons_ev[len(cons_ev) // 5:] if e["received"]]
        prod_rate = (len(p) - 1) / (p[-1]["t"] - p[0]["t"])
        cons_rate = (len(c) - 1) / (c[-1]["t"] - c[0]["t"])
        sink = subprocess.Popen([py, str(BASELINE), "sink", str(seconds / 2)], env=env,
                                stdout=subprocess.PIPE, stderr=subprocess.DEVNULL, text=True)
        flood = json.loads(_run([py, str(BASELINE), "flood", str(seconds / 2)], env, 120)
                           or "{}")
        taken = json.loads(sink.communicate(timeout=120)[0] or "{}")
        print(f"non-blocking channel (generated nodes): producer {prod_rate:,.0f} samples/s, "
              f"consumer takes {cons_rate:,.0f}/s (the rest overwritten)")
        if flood and taken:
            print(f"  baseline rclpy: publish loop {flood['published_per_s']:,.0f}/s, "
                  f"subscriber {taken['taken_per_s']:,.0f}/s; generated/baseline = "
                  f"{prod_rate / flood['published_per_s']:.3f} (producer), "
                  f"{cons_rate / taken['taken_per_s']:.2f} (consumer)")


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--seconds", type=float, default=8.0)
    ap.add_argument("--no-ros", action="store_true")
    args = ap.parse_args()
    bench_generation(args.repeat)
    if not args.no_ros:
        bench_ros(args.seconds)


if __name__ == "__main__":
    main()
