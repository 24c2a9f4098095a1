"""The generated nodes behave like the model: build the workspace of specs/relay.rssm (every
channel blocking on both sides, so nothing depends on timing), start its nodes the way the
launch files say, and compare what they did with what the interpreter does on the same
specification: every iteration's behaviour, new(x) flags and data-availability cases, the
values received, the behaviour switches, and the switches as the nodes published them over
DDS on their diagnostics topics."""

from __future__ import annotations

import json
import re
import subprocess
from pathlib import Path
from typing import Any

import pytest

from rssm_dsl.hpn.ir import CondKind
from rssm_dsl.interp import RunConfig, SimOptions, Simulator, build_runtime
from rssm_dsl.interp.trace import TraceWriter, read_trace
from rssm_dsl.pipeline import compile_file
from rssm_dsl.ros2 import toolchain
from tests.conftest import ROOT
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
_INDEX = re.compile(r"\[([^\]]*)\]$")


def _last_indices(name: str) -> list[str]:
    m = _INDEX.search(name)
    assert m is not None, name
    return m.group(1).split(",")


def interpreter_record(tmp: Path) -> dict[str, dict[str, list[Any]]]:
    """Per subsystem: iterations (behaviour, new, cases), received values, switches."""
    comp = compile_file(RELAY.relative_to(ROOT))
    assert comp.ok and comp.hpn is not None and comp.system is not None
    rt = build_runtime(comp, RunConfig(base_dir=RELAY.parent))
    rt.tracer = TraceWriter(tmp / "interp.jsonl")
    result = Simulator(rt, SimOptions(seed=0, max_steps=500_000)).run()
    assert result.reason == "finished", result.message
    hpn, system = comp.hpn, comp.system
    functions = {(s.id, b.name): len(b.functions) for s in system.subsystems()
                 for b in s.behaviours}
    pending: dict[str, list[tuple[int, int, tuple[bool, ...], str]]] = {}
    out: dict[str, dict[str, list[Any]]] = {
        s: {"iterations": [], "received": [], "switches": []} for s in SUBSYSTEMS}
    for e in read_trace(tmp / "interp.jsonl"):
        kind = e["event"]
        if kind == "fire":
            t = hpn.transitions[e["transition"]]
            c = t.condition
            if c is None or c.kind is not CondKind.CASE:
                continue
            assert c.behaviour is not None and c.new is not None
            psi, varpi = (int(x) for x in _last_indices(t.id)[-2:])
            group = pending.setdefault(c.subsystem, [])
            group.append((psi, varpi, c.new, c.behaviour))
            if len(group) == functions[c.subsystem, c.behaviour]:
                group.sort()
                out[c.subsystem]["iterations"].append(
                    (c.behaviour, list(c.new), [v for _, v, _, _ in group]))
                pending[c.subsystem] = []
        elif kind == "receive" and e["subsystem"] in out:
            out[e["subsystem"]]["received"].append((e["buffer"], e["value"]))
        elif kind == "enter":
            out[e["subsystem"]]["switches"].append((None, e["behaviour"]))
        elif kind == "switch":
            out[e["subsystem"]]["switches"].append((e["from"], e["to"]))
    return out


def node_record(trace: Path) -> dict[str, list[Any]]:
    events = [json.loads(x) for x in trace.read_text().splitlines() if x.strip()]
    rec: dict[str, list[Any]] = {"iterations": [], "received": [], "switches": []}
    for e in events:
        if e["event"] == "iteration":
            rec["iterations"].append((e["behaviour"], e["new"], e["cases"]))
            for buffer, got in e["received"].items():
                rec["received"].append((buffer, got["value"]))
        elif e["event"] in ("enter", "switch"):
            rec["switches"].append((e["from"], e["to"]))
    return rec


def test_nodes_do_what_the_interpreter_does(ros_venv: toolchain.RosVenv, build_dir: Path,
                                            domain: int, tmp_path: Path,
                                            processes: Processes) -> None:
    built = build_spec(RELAY, ros_venv, build_dir)
    expected = interpreter_record(tmp_path)
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
    for sid in SUBSYSTEMS:
        got = node_record(tmp_path / "trace" / f"{sid}.jsonl")
        want = expected[sid]
        assert got["switches"] == want["switches"], sid
        assert got["iterations"] == want["iterations"], sid
        assert got["received"] == want["received"], sid
        assert len(got["iterations"]) >= 12
    # the switches as published on the diagnostics topics, heard over DDS
    heard = [json.loads(x) for x in (tmp_path / "dds.jsonl").read_text().splitlines()]
    for sid, node in SUBSYSTEMS.items():
        events = [(h["previous"] or None, h["behaviour"] or None) for h in heard
                  if h["topic"] == f"{node}/rssm/diagnostics"
                  and h["event"] in ("enter", "switch", "end")]
        assert events == expected[sid]["switches"], sid
    # some data went over the wire into a data case that needs it
    assert any(new == [True] for _, new, _ in expected["dst.e.arm"]["iterations"])
