"""The generated nodes behave like the model: build the workspace of specs/relay.rssm (every
channel blocking on both sides, so nothing depends on timing), start its nodes the way the
launch files say, and compare what they did with what the interpreter does on the same
specification: every iteration's behaviour, new(x) flags and data-availability cases, the
values received, the behaviour switches, and the switches as the nodes published them over
DDS on their diagnostics topics."""

from __future__ import annotations

import json
import subprocess
from pathlib import Path

import pytest

from rssm_dsl.ros2 import toolchain
from tests.ros2 import differential
from tests.ros2.conftest import (
    SPECS,
    Processes,
    build_spec,
    launch_cmd,
    monitor_cmd,
    node_env,
    wait_ready,
)

pytestmark = [pytest.mark.ros2, pytest.mark.slow]

RELAY = SPECS / "relay.rssm"
SUBSYSTEMS = {"src.c": "/src/c", "dst.c": "/dst/c", "dst.e.arm": "/dst/e_arm"}


def test_nodes_do_what_the_interpreter_does(ros_venv: toolchain.RosVenv, build_dir: Path,
                                            domain: int, tmp_path: Path,
                                            processes: Processes) -> None:
    built = build_spec(RELAY, ros_venv, build_dir)
    interp = differential.interpreter_records(RELAY, tmp_path / "interp.jsonl")
    assert interp.reason == "finished"
    expected = interp.records
    # every subsystem is deterministic: the whole run is determined
    system = differential.compile_spec(RELAY).system
    assert system is not None
    assert differential.deterministic_subsystems(system) == set(SUBSYSTEMS)
    env = node_env(built, domain, tmp_path)
    monitor = processes.start(
        monitor_cmd(ros_venv, "relay_interfaces", 120, tmp_path / "dds.jsonl",
                    diagnostics=[f"{n}/rssm/diagnostics" for n in SUBSYSTEMS.values()],
                    until_ended=len(SUBSYSTEMS)), env, tmp_path / "monitor.log")
    wait_ready(monitor, tmp_path / "monitor.log")
    launch = processes.start(
        launch_cmd([built.launch_file("relay_src", "src"), built.launch_file("relay_dst", "dst")],
                   duration=90, log_dir=tmp_path / "logs", params=["*:rssm.linger:=5.0"]),
        env, tmp_path / "launch.log")
    try:
        code = launch.wait(timeout=150)
        monitor.wait(timeout=150)
    except subprocess.TimeoutExpired:
        pytest.fail("the relay nodes did not finish: " + (tmp_path / "launch.log").read_text())
    log = (tmp_path / "launch.log").read_text()
    assert code == 0, log           # every node ended by itself (124: still running at 90 s)
    nodes = {sid: differential.node_record(tmp_path / "trace" / f"{sid}.jsonl")
             for sid in SUBSYSTEMS}
    for sid, got in nodes.items():
        want = expected[sid]
        assert got.ended and want.ended, sid
        assert got.switches == want.switches, sid
        assert got.iterations == want.iterations, sid
        assert got.received == want.received, sid
        assert len(got.iterations) >= 12
    comparison = differential.compare(system, interp, nodes)
    assert not comparison.mismatches, comparison.mismatches
    # the switches as published on the diagnostics topics, heard over DDS
    heard = [json.loads(x) for x in (tmp_path / "dds.jsonl").read_text().splitlines()]
    for sid, node in SUBSYSTEMS.items():
        events = [(h["previous"] or None, h["behaviour"] or None) for h in heard
                  if h["topic"] == f"{node}/rssm/diagnostics"
                  and h["event"] in ("enter", "switch", "end")]
        assert events == expected[sid].switches, sid
    # some data went over the wire into a data case that needs it
    assert any(new == [True] for _, new, _ in expected["dst.e.arm"].iterations)
