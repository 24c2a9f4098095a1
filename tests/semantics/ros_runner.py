"""Build the semantic tests' ROS 2 workspace (every agent of systems.ros_system(), one colcon
build per session) and run some of its agents over real DDS with the launch runner, on a
DDS domain of their own, with node rates set by parameters; read back the nodes' JSON-lines
traces ($RSSM_TRACE_DIR: one file per subsystem) and exit codes."""

from __future__ import annotations

import json
import re
import subprocess
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import pytest

from rssm_dsl.ros2 import toolchain
from tests.ros2.conftest import Built, Processes, build_spec, launch_cmd, node_env
from tests.semantics import systems

Event = dict[str, Any]
_EXITED = re.compile(r"\[launch_runner\] (\S+) \(\S+\) exited (-?\d+)")


def build(venv: toolchain.RosVenv, where: Path) -> Built:
    spec = systems.write(where / "spec", "sem", systems.ros_system())
    return build_spec(spec, venv, where)


@dataclass
class Launch:
    code: int                       # the launch runner's (124: stopped at the end of RUN)
    exits: dict[str, int]           # node (fully qualified) -> exit code
    traces: dict[str, list[Event]]  # subsystem id -> its trace's events
    log: str

    def of(self, subsystem: str, kind: str) -> list[Event]:
        return [e for e in self.traces.get(subsystem, []) if e.get("event") == kind]


def launch(built: Built, domain: int, tmp: Path, processes: Processes, agents: list[str],
           duration: float, params: tuple[str, ...] = ()) -> Launch:
    tmp.mkdir(parents=True, exist_ok=True)
    env = node_env(built, domain, tmp)
    files = [built.launch_file(f"sem_{a}", a) for a in agents]
    proc = processes.start(launch_cmd(files, duration, tmp / "logs", list(params)), env,
                           tmp / "launch.log")
    try:
        code = proc.wait(timeout=duration + 90)
    except subprocess.TimeoutExpired:
        pytest.fail("the launch runner did not stop the nodes")
    log = (tmp / "launch.log").read_text(errors="replace")
    exits = {m.group(1): int(m.group(2)) for m in _EXITED.finditer(log)}
    traces: dict[str, list[Event]] = {}
    for f in sorted((tmp / "trace").glob("*.jsonl")):
        traces[f.stem] = [json.loads(x) for x in f.read_text().splitlines() if x.strip()]
    return Launch(code, exits, traces, log)
