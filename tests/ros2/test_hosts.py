"""Several hosts (issue 20, item 4): every node of a specification's agents runs as an OS
process of its own, in a process group (session) of its own, the nodes sharing nothing but one
DDS domain, as agents on separate machines would; what they did (their trace files) is
compared with what the interpreter does on the same specification, for every part of the run
that the semantics determine (tests/ros2/differential.py states the rule).

Specifications: the ROS 2 test specifications and every example whose devices can run in a
ROS node. Building a workspace costs about 20 s (2 cores), so by default the run covers the
specifications the other ROS 2 tests build anyway (the session shares their workspaces) and a
few cheap examples that exercise the rule's cases; ``RSSM_ROS2_ALL_SPECS=1`` runs every one.
"""

from __future__ import annotations

import contextlib
import json
import os
import signal
import subprocess
import sys
import time
from dataclasses import dataclass
from pathlib import Path

import pytest

from rssm_dsl.ros2 import toolchain
from tests.conftest import ROOT, example_specs
from tests.ros2 import differential
from tests.ros2.conftest import SPECS, Built, Processes, build_spec, node_env, with_rssmc

pytestmark = [pytest.mark.ros2, pytest.mark.slow]

START_SECONDS = 20.0       # at most, until every subsystem node wrote its trace's header
RUN_SECONDS = 6.0          # then a system that does not end is stopped after this
INTERP_UNTIL = 30.0        # simulated seconds of the interpreter's run: beyond the nodes'

# relay, wire, deploy, finite: built by the other ROS 2 tests of the session (no extra build);
# (mode_bn and lockstep, two builds more, ~50 s, run with RSSM_ROS2_ALL_SPECS=1: the mode pairs
# are the semantic table's rows in tests/semantics/test_ros2.py.) Between them: deterministic
# subsystems that end
# and that never do, inputs from deterministic producers that block and that do not (either
# consumer mode), devices, non-deterministic subsystems.
# lwr4_circle (30 s, with RSSM_ROS2_ALL_SPECS=1): built by test_lwr4.py, which runs the same
# nodes under one launch; here a device node stepping MuJoCo and an effector node calling
# Pinocchio, on the wall clock (the ROS venv gets requirements-physics.txt for them).
DEFAULT = {"relay", "wire", "deploy", "finite"}
# The Pandas' URDF and meshes come from example-robot-data (requirements-robots.txt, about
# 400 MB): installed for RSSM_ROS2_ALL_SPECS=1 only.
PHYSICS = {"lwr4_circle", "panda_joints", "panda_handover"}
ROBOTS = {"panda_joints", "panda_handover"}


def _specs() -> list[object]:
    out: list[object] = []
    for spec in [*sorted(SPECS.glob("*.rssm")), *example_specs()]:
        name = str(spec.relative_to(ROOT))
        if spec.stem not in DEFAULT and not os.environ.get("RSSM_ROS2_ALL_SPECS"):
            out.append(pytest.param(spec, id=name, marks=pytest.mark.skip(
                reason=f"{name}: a build of its own (~20 s); RSSM_ROS2_ALL_SPECS=1 runs it")))
        else:
            out.append(pytest.param(spec, id=name))
    return out


@dataclass
class Node:
    fqn: str
    proc: subprocess.Popen[bytes]
    log: Path


def _node_commands(built: Built, launch_file: Path,
                   env: dict[str, str]) -> list[tuple[str, list[str], dict[str, str]]]:
    """The nodes of one agent's launch file, as the launch runner would start them."""
    done = subprocess.run([sys.executable, "-m", "rssm_dsl.ros2.launch_runner", "--dry-run",
                           str(launch_file)], env=env, capture_output=True, text=True,
                          timeout=60, check=False)
    assert done.returncode == 0, done.stderr
    out = []
    for line in done.stdout.splitlines():
        item = json.loads(line)
        out.append((item["node"], item["command"], item["env"]))
    return out


def _stop(nodes: list[Node], grace: float = 10.0) -> None:
    for n in nodes:
        if n.proc.poll() is None:
            with contextlib.suppress(ProcessLookupError):
                os.killpg(n.proc.pid, signal.SIGINT)
    end = time.monotonic() + grace
    for n in nodes:
        try:
            n.proc.wait(timeout=max(0.1, end - time.monotonic()))
        except subprocess.TimeoutExpired:
            with contextlib.suppress(ProcessLookupError):
                os.killpg(n.proc.pid, signal.SIGKILL)
            n.proc.wait()


def run_agents_apart(built: Built, system: str, agents: list[str], subsystems: set[str],
                     env: dict[str, str], tmp: Path, processes: Processes) -> dict[str, int | None]:
    """Start every node of every agent as its own process (own session), run until every
    subsystem node ended or RUN_SECONDS after they all started, then stop the rest. The exit
    codes of the nodes that ended by themselves (None: stopped)."""
    logs = tmp / "logs"
    logs.mkdir()
    nodes: list[Node] = []
    for agent in agents:
        package = f"{system}_{agent}".lower()
        for fqn, cmd, changed in _node_commands(built, built.launch_file(package, agent), env):
            log = logs / (fqn.strip("/").replace("/", ".") + ".log")
            nodes.append(Node(fqn, processes.start(cmd, {**env, **changed}, log), log))
    ids = {"/" + sid.split(".")[0] + "/" + ("c" if sid.endswith(".c") else
                                             "_".join(sid.split(".")[1:])) for sid in subsystems}
    watched = [n for n in nodes if n.fqn in ids]
    assert len(watched) == len(subsystems), ([n.fqn for n in nodes], subsystems)
    traces = [env["RSSM_TRACE_DIR"] + "/" + sid + ".jsonl" for sid in subsystems]

    def started() -> bool:                  # each node has matched its channels and begun
        return all(Path(t).exists() and Path(t).stat().st_size > 0 for t in traces)

    end = time.monotonic() + START_SECONDS
    while time.monotonic() < end and not started() and any(
            n.proc.poll() is None for n in watched):
        time.sleep(0.2)
    end = time.monotonic() + RUN_SECONDS
    while time.monotonic() < end and any(n.proc.poll() is None for n in watched):
        time.sleep(0.2)
    ended = {n.fqn: n.proc.poll() for n in nodes}
    _stop(nodes)
    return ended


@pytest.mark.parametrize("spec", _specs())
def test_agents_apart_do_what_the_interpreter_does(
        spec: Path, ros_venv: toolchain.RosVenv, build_dir: Path, domain: int, tmp_path: Path,
        processes: Processes) -> None:
    if spec.stem in PHYSICS:
        toolchain.ensure_extra(ros_venv)
    if spec.stem in ROBOTS:
        toolchain.ensure_extra(ros_venv, toolchain.ROBOTS)
    t0 = time.monotonic()
    built = build_spec(spec, ros_venv, build_dir)
    t_build = time.monotonic() - t0
    comp = differential.compile_spec(spec)
    assert comp.system is not None
    system = comp.system
    interp = differential.interpreter_records(spec, tmp_path / "interp.jsonl",
                                              until=INTERP_UNTIL, max_steps=200_000)
    sids = set(differential.subsystem_ids(system))
    env = with_rssmc(node_env(built, domain, tmp_path), tmp_path)
    t1 = time.monotonic()
    codes = run_agents_apart(built, system.name, [a.name for a in system.agents], sids, env,
                             tmp_path, processes)
    t_run = time.monotonic() - t1
    for fqn, code in codes.items():             # a node that ended by itself ended well
        assert code in (None, 0), (fqn, code, (tmp_path / "logs" / (
            fqn.strip("/").replace("/", ".") + ".log")).read_text()[-3000:])
    nodes = {sid: differential.node_record(tmp_path / "trace" / f"{sid}.jsonl") for sid in sids}
    result = differential.compare(system, interp, nodes)
    print(f"{spec.name}: build {t_build:.1f} s, run {t_run:.1f} s; interpreter "
          f"{interp.reason}; " + differential.describe([(spec.name, result)]))
    assert not result.mismatches, "\n".join(result.mismatches)
    for sid in result.full:                     # the deterministic nodes did run
        assert nodes[sid].switches, f"{sid} did not start"
