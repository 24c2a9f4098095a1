"""Fixtures of the ROS 2 tests: the ROS venv (PyPI ros-jazzy wheels + colcon, created once
per test session under <repo>/.cache/ros2-venv and reused while the pinned requirements do
not change), generated and built workspaces (once per session each), a DDS domain of its
own per test, and the processes a test starts (always killed)."""

from __future__ import annotations

import contextlib
import fcntl
import os
import subprocess
import sys
import tempfile
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import IO

import pytest

from rssm_dsl.pipeline import compile_file
from rssm_dsl.ros2 import toolchain
from rssm_dsl.ros2.generator import generate, write_workspace
from tests.conftest import ROOT

SPECS = Path(__file__).resolve().parent / "specs"
MONITOR = Path(__file__).resolve().parent / "monitor.py"
VENV = ROOT / ".cache" / "ros2-venv"


@dataclass(frozen=True)
class Built:
    root: Path                 # the colcon workspace (src/, install/)
    env: dict[str, str]        # install/setup.bash sourced (no domain yet)
    venv: toolchain.RosVenv

    def launch_file(self, package: str, agent: str) -> Path:
        return self.root / "install" / package / "share" / package / "launch" / f"{agent}.launch.py"

    def system_launch_file(self, system: str) -> Path:
        return self.launch_file(f"{system}_bringup", "system")


@pytest.fixture(scope="session")
def ros_venv() -> toolchain.RosVenv:
    why = toolchain.unsupported_reason()
    if why is not None:
        pytest.skip(f"ROS 2 wheels cannot be installed here: {why}")
    return toolchain.ensure_venv(VENV, timeout=900)


@pytest.fixture(scope="session")
def ros_physics_venv(ros_venv: toolchain.RosVenv) -> toolchain.RosVenv:
    """The ROS venv with MuJoCo and Pinocchio (requirements-physics.txt), for the nodes of the
    MuJoCo-bound devices and their controllers (installed once, about 15 s from pip's cache)."""
    return toolchain.ensure_extra(ros_venv, timeout=900)


_built: dict[str, Built] = {}


@pytest.fixture(scope="session")
def build_dir() -> Iterator[Path]:
    """The folder of the session's built workspaces. Removed at the end by a process of its
    own that outlives the session: deleting the colcon trees (tens of thousands of files)
    took 38 s of the suite's wall time as the last test's teardown."""
    d = tempfile.mkdtemp(prefix="rssm-ros2-")
    try:
        yield Path(d)
    finally:
        try:
            subprocess.Popen(["rm", "-rf", "--", d], start_new_session=True,
                             stdin=subprocess.DEVNULL, stdout=subprocess.DEVNULL,
                             stderr=subprocess.DEVNULL)
        except OSError:                   # no `rm`: remove it here
            import shutil

            shutil.rmtree(d, ignore_errors=True)


def build_spec(spec: Path, venv: toolchain.RosVenv, where: Path) -> Built:
    """Generate the workspace of ``spec`` and colcon-build it (once per session)."""
    key = str(spec)
    if key in _built:
        return _built[key]
    comp = compile_file(spec.relative_to(ROOT) if spec.is_relative_to(ROOT) else spec)
    assert comp.ok, comp.diagnostics
    ws = generate(comp)
    assert not isinstance(ws, list), ws
    root = where / spec.stem
    write_workspace(ws, root / "src")
    env = toolchain.ros_env(venv, 1, root / "log")
    toolchain.colcon_build(root, env, timeout=900)
    built = Built(root, toolchain.workspace_env(root, env), venv)
    _built[key] = built
    return built


@pytest.fixture
def domain() -> Iterator[int]:
    """A DDS domain id no other test on this machine holds (a lock file per id)."""
    lock_dir = Path(tempfile.gettempdir()) / "rssm-ros-domains"
    lock_dir.mkdir(exist_ok=True)
    start = os.getpid() % 90
    for k in range(100):
        did = (start + k) % 100 + 1
        f: IO[str] = open(lock_dir / f"{did}.lock", "w")  # noqa: SIM115
        try:
            fcntl.flock(f, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except OSError:
            f.close()
            continue
        try:
            yield did
        finally:
            fcntl.flock(f, fcntl.LOCK_UN)
            f.close()
        return
    pytest.fail("no free ROS_DOMAIN_ID")


def node_env(built: Built, domain: int, tmp: Path) -> dict[str, str]:
    env = dict(built.env)
    env.update({"ROS_DOMAIN_ID": str(domain), "ROS_LOG_DIR": str(tmp / "roslog"),
                "ROS_AUTOMATIC_DISCOVERY_RANGE": "LOCALHOST",
                "RSSM_TRACE_DIR": str(tmp / "trace")})
    return env


def with_rssmc(env: dict[str, str], tmp: Path) -> dict[str, str]:
    """``env`` in which the nodes can import rssmc (toolchain.with_rssmc)."""
    return toolchain.with_rssmc(env, tmp / "rssmc-path")


class Processes:
    """Processes started by a test; every one still running at the end is killed."""

    def __init__(self) -> None:
        self.procs: list[subprocess.Popen[bytes]] = []

    def start(self, cmd: list[str], env: dict[str, str], log: Path,
              cwd: Path | None = None) -> subprocess.Popen[bytes]:
        out = open(log, "wb")  # noqa: SIM115
        p = subprocess.Popen(cmd, env=env, stdout=out, stderr=subprocess.STDOUT,
                             start_new_session=True, cwd=cwd)
        out.close()
        self.procs.append(p)
        return p

    def kill_all(self) -> None:
        for p in self.procs:
            if p.poll() is None:
                with contextlib.suppress(ProcessLookupError):
                    os.killpg(p.pid, 9)
                p.wait()


@pytest.fixture
def processes() -> Iterator[Processes]:
    procs = Processes()
    try:
        yield procs
    finally:
        procs.kill_all()


def wait_ready(proc: subprocess.Popen[bytes], log: Path, timeout: float = 60.0) -> None:
    """Wait until a monitor printed "ready" (its subscriptions exist), then give discovery a
    moment so that it hears the nodes from their first message."""
    import time

    end = time.monotonic() + timeout
    while time.monotonic() < end:
        if log.exists() and b"ready" in log.read_bytes():
            time.sleep(1.0)
            return
        if proc.poll() is not None:
            raise AssertionError(f"the monitor failed: {log.read_text()}")
        time.sleep(0.1)
    raise AssertionError(f"the monitor did not start in {timeout} s")


def launch_cmd(files: list[Path], duration: float, log_dir: Path,
               params: list[str] = (),  # type: ignore[assignment]
               arguments: dict[str, str] | None = None) -> list[str]:
    """The launch runner, run by this (the test) interpreter as `python -m` (from any folder:
    rssmc is installed in it); ``arguments`` are launch arguments (NAME:=VALUE)."""
    cmd = [sys.executable, "-m", "rssm_dsl.ros2.launch_runner", "--duration", str(duration),
           "--grace", "10", "--log-dir", str(log_dir)]
    for p in params:
        cmd += ["-p", p]
    return cmd + [str(f) for f in files] + [f"{k}:={v}" for k, v in (arguments or {}).items()]


def monitor_cmd(venv: toolchain.RosVenv, interfaces: str, duration: float, out: Path,
                diagnostics: list[str] = (), data: list[str] = (),  # type: ignore[assignment]
                until_ended: int = 0, info: list[str] = ()) -> list[str]:  # type: ignore[assignment]
    cmd = [str(venv.python), str(MONITOR), "--interfaces", interfaces, "--duration",
           str(duration), "--out", str(out), "--until-ended", str(until_ended)]
    for t in diagnostics:
        cmd += ["--diagnostics", t]
    for t in data:
        cmd += ["--data", t]
    for t in info:
        cmd += ["--info", t]
    return cmd
