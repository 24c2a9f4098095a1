"""The four communication modes on the wire (specs/wire.rssm: one agent per pair of modes,
c counting 0, 1, 2, ... into its effector sink), and a device node (agent gadget).

With a fast producer and a slow consumer, a blocking producer never runs ahead of its
consumer (it publishes a sample only once the previous one was taken), while a non-blocking
one does and the samples nobody took are overwritten: the consumer sees gaps, newest first.
With a slow producer and a fast consumer, a blocking consumer waits for each fresh sample
(never a stale one), while a non-blocking one goes on without and finds nothing new most of
the time. What the data topics carried is counted by an independent subscriber."""

from __future__ import annotations

import json
import subprocess
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import pytest

from rssm_dsl.ros2 import toolchain
from tests.ros2.conftest import (
    SPECS,
    Built,
    Processes,
    build_spec,
    launch_cmd,
    monitor_cmd,
    node_env,
    wait_ready,
)

pytestmark = [pytest.mark.ros2, pytest.mark.slow]

WIRE = SPECS / "wire.rssm"
PAIRS = {"bb": (True, True), "bn": (True, False), "nb": (False, True), "nn": (False, False)}
RUN = 12.0     # seconds the nodes run (their start-up included)


@dataclass
class Pair:
    produced: int                # iterations of the producer c (one sample each)
    consumed: int                # iterations of the consumer sink
    taken: list[int]             # seq of every sample the sink took, in order
    new: list[bool]              # new(data) of every sink iteration
    on_wire: set[int]            # seqs the info topic carried (an independent subscriber)
    data_heard: int              # plain std_msgs/Int64 messages the data topic carried


def _events(path: Path) -> list[dict[str, Any]]:
    return [json.loads(x) for x in path.read_text().splitlines() if x.strip()]


def run_pairs(built: Built, venv: toolchain.RosVenv, domain: int, tmp: Path,
              processes: Processes, producer_hz: float, consumer_hz: float) -> dict[str, Pair]:
    env = node_env(built, domain, tmp)
    monitor = processes.start(
        monitor_cmd(venv, "wire_interfaces", RUN + 30, tmp / "dds.jsonl",
                    info=[f"/{a}/c/data" for a in PAIRS],
                    data=[f"/{a}/c/data=std_msgs/msg/Int64" for a in PAIRS]),
        env, tmp / "monitor.log")
    wait_ready(monitor, tmp / "monitor.log")
    params = [p for a in PAIRS for p in (f"/{a}/c:rssm.rate_hz:={producer_hz}",
                                         f"/{a}/e_sink:rssm.rate_hz:={consumer_hz}")]
    launch = processes.start(
        launch_cmd([built.launch_file(f"wire_{a}", a) for a in PAIRS], RUN, tmp / "logs",
                   params), env, tmp / "launch.log")
    try:
        code = launch.wait(timeout=RUN + 60)
    except subprocess.TimeoutExpired:
        pytest.fail("the launch runner did not stop the nodes")
    assert code == 124, (tmp / "launch.log").read_text()     # stopped at the end of RUN
    assert "exited 0" in (tmp / "launch.log").read_text()
    monitor.send_signal(2)
    monitor.wait(timeout=30)
    heard = _events(tmp / "dds.jsonl")
    out: dict[str, Pair] = {}
    for a in PAIRS:
        prod = [e for e in _events(tmp / "trace" / f"{a}.c.jsonl") if e["event"] == "iteration"]
        cons = [e for e in _events(tmp / "trace" / f"{a}.e.sink.jsonl")
                if e["event"] == "iteration"]
        out[a] = Pair(len(prod), len(cons),
                      [e["received"]["data"]["seq"] for e in cons if e["received"]],
                      [e["new"][0] for e in cons],
                      {h["seq"] for h in heard if h["topic"] == f"/{a}/c/data" and "seq" in h},
                      sum(1 for h in heard if h["topic"] == f"/{a}/c/data" and "data" in h))
        # the data topic carries plain std_msgs/Int64, one message with every info
        assert out[a].data_heard >= 0.9 * len(out[a].on_wire) > 0, (a, out[a].data_heard)
        # the value taken is the count the producer sent with that sample
        for e in cons:
            if e["received"]:
                assert e["received"]["data"]["value"] == e["received"]["data"]["seq"] - 1
    return out


def test_producer_modes_with_a_slow_consumer(ros_venv: toolchain.RosVenv, build_dir: Path,
                                             domain: int, tmp_path: Path,
                                             processes: Processes) -> None:
    built = build_spec(WIRE, ros_venv, build_dir)
    pairs = run_pairs(built, ros_venv, domain, tmp_path, processes, 200.0, 10.0)
    for name, (producer_blocking, _) in PAIRS.items():
        p = pairs[name]
        assert len(p.taken) >= 10, (name, p)
        increasing = all(a < b for a, b in zip(p.taken, p.taken[1:], strict=False))
        assert increasing, (name, p.taken)           # never a sample taken twice, nor an old one
        if producer_blocking:
            # never ahead: one sample per take, none skipped, and no more on the wire
            assert p.produced <= len(p.taken) + 1, (name, p.produced, len(p.taken))
            assert p.taken == list(range(1, len(p.taken) + 1)), (name, p.taken)
            assert max(p.on_wire) <= len(p.taken) + 1, (name, max(p.on_wire))
        else:
            # runs ahead: many more samples than takes, the ones never taken overwritten
            assert p.produced >= 4 * len(p.taken), (name, p.produced, len(p.taken))
            skipped = p.taken[-1] - len(p.taken)
            assert skipped >= 3 * len(p.taken), (name, p.taken)
            assert max(p.on_wire) >= 4 * len(p.taken), (name, max(p.on_wire))


def test_consumer_modes_with_a_slow_producer(ros_venv: toolchain.RosVenv, build_dir: Path,
                                             domain: int, tmp_path: Path,
                                             processes: Processes) -> None:
    built = build_spec(WIRE, ros_venv, build_dir)
    pairs = run_pairs(built, ros_venv, domain, tmp_path, processes, 10.0, 200.0)
    for name, (_, consumer_blocking) in PAIRS.items():
        p = pairs[name]
        assert len(p.taken) >= 10, (name, p)
        assert len(set(p.taken)) == len(p.taken), name         # a sample is taken once only
        if consumer_blocking:
            # waits for every fresh sample: one iteration per sample, each with new data
            assert p.consumed <= p.produced + 1, (name, p.consumed, p.produced)
            assert all(p.new[1:]), (name, p.new.count(False))
        else:
            # goes on without: most iterations find nothing new and keep the old value
            assert p.consumed >= 4 * p.produced, (name, p.consumed, p.produced)
            assert p.new.count(False) >= 3 * p.new.count(True), name
            # new(x) of an iteration is what the previous iteration's receive found
            assert len(p.taken) - 1 <= p.new.count(True) <= len(p.taken), name
            assert len(p.taken) <= p.produced + 1, name


def test_device_node_and_shipped_modules(ros_venv: toolchain.RosVenv, build_dir: Path,
                                         domain: int, tmp_path: Path,
                                         processes: Processes) -> None:
    """gadget: the device node runs the Thermometer class shipped from next to the spec,
    the receptor forwards its readings, c averages them with the shipped extern smooth()
    and switches behaviours as the average crosses its parameters' thresholds."""
    built = build_spec(WIRE, ros_venv, build_dir)
    env = node_env(built, domain, tmp_path)
    monitor = processes.start(
        monitor_cmd(ros_venv, "wire_interfaces", RUN + 30, tmp_path / "dds.jsonl",
                    diagnostics=["/gadget/c/rssm/diagnostics",
                                 "/gadget/r_thermo/rssm/diagnostics"]),
        env, tmp_path / "monitor.log")
    wait_ready(monitor, tmp_path / "monitor.log")
    launch = processes.start(
        launch_cmd([built.launch_file("wire_gadget", "gadget")], RUN, tmp_path / "logs"),
        env, tmp_path / "launch.log")
    assert launch.wait(timeout=RUN + 60) == 124
    log = (tmp_path / "launch.log").read_text()
    for node in ("/gadget/c", "/gadget/r_thermo", "/gadget/R_thermo"):
        assert f"{node} " in log and "exited 0" in log.split(f"{node} ")[1].split("\n")[0], log
    monitor.send_signal(2)
    monitor.wait(timeout=30)
    receptor = [e for e in _events(tmp_path / "trace" / "gadget.r.thermo.jsonl")
                if e["event"] == "iteration"]
    readings = [e["received"]["raw"]["value"] for e in receptor if e["received"]]
    assert len(readings) >= 10 and set(readings) <= {float(t) for t in range(20, 41)}
    heard = _events(tmp_path / "dds.jsonl")
    switches = [(h["previous"], h["behaviour"]) for h in heard
                if h["topic"] == "/gadget/c/rssm/diagnostics" and h["event"] == "switch"]
    assert ("watch", "cool") in switches and ("cool", "watch") in switches, switches
    assert any(h["new_data"] == [True] for h in heard
               if h["topic"] == "/gadget/r_thermo/rssm/diagnostics"), heard
