"""Bad robot parameters are diagnostics (E801 at the device, exit code 1), never tracebacks."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

from tests.conftest import ROOT
from tests.robots.conftest import TABLE, write_robots, write_spec


def _simulate(spec: Path) -> subprocess.CompletedProcess[str]:
    return subprocess.run([sys.executable, "-m", "rssm_dsl", "simulate", str(spec),
                           "--until", "0.01"], cwd=ROOT, capture_output=True, text=True,
                          timeout=120)


@pytest.mark.parametrize(("old", "new", "message"), [
    ('model = "models/long.xml"', 'model = "models/missing.xml"',
     "robot long: model file 'models/missing.xml' not found (looked for "),
    ('joints = ["shoulder", "elbow"]\nee = "tip"\nq0 = [-0.2, 0.1]',
     'joints = ["shoulder", "wrist"]\nee = "tip"\nq0 = [-0.2, 0.1]',
     "long.xml: no joint 'wrist' (joints: shoulder, elbow)"),
    ('ee = "tip"\nq0 = [-0.2, 0.1]', 'ee = "nose"\nq0 = [-0.2, 0.1]',
     "long.xml: no site, body or link 'nose'"),
    ('q0 = [-0.2, 0.1]', 'q0 = [-0.2, 0.1, 0.0]', "q0 must be a number or a list of 2 numbers"),
    ('[long]', '[lang]', "robot long: no robot 'long' in "),
    ('torque_limits = [5.0, 3.0]', 'torque_limits = [5.0, 3.0]\ncollisions = "yes"',
     "collisions must be true or false"),
])
def test_bad_robot_is_E801(tmp_path: Path, old: str, new: str, message: str) -> None:
    assert old in TABLE
    spec = write_spec(write_robots(tmp_path, TABLE.replace(old, new, 1)))
    proc = _simulate(spec)
    assert proc.returncode == 1, proc.stdout + proc.stderr
    out = proc.stdout + proc.stderr
    assert "Traceback" not in out
    assert "error[E801]: device a1.E.right (rssm_stdlib.robots.device:MujocoArmDevice): " in out
    assert message in out
    assert "real effector right: Arm2(robot = Bot.long)" in out     # the device's line


def test_wrong_buffer_size_is_E801(tmp_path: Path) -> None:
    write_robots(tmp_path)
    spec = write_spec(tmp_path)
    # a three-joint torque for a two-joint robot
    text = spec.read_text(encoding="utf-8").replace(
        "input torque: JointVec2 nonblocking", "input torque: Vec3 nonblocking")
    text = text.replace("output left: JointVec2 to E.left", "output left: Vec3 to E.left")
    text = text.replace("output right: JointVec2 to E.right", "output right: Vec3 to E.right")
    text = text.replace("param tau: JointVec2 = [0.0, 0.0]", "param tau: Vec3 = [0.0, 0.0, 0.0]")
    text = text.replace("left := tau + 0.0 * left_state.q * count",
                        "left := tau * count")
    text = text.replace("right := tau + 0.0 * right_state.q",
                        "right := tau + 0.0 * right_state.position")
    spec.write_text(text, encoding="utf-8")
    proc = _simulate(spec)
    out = proc.stdout + proc.stderr
    assert proc.returncode == 1 and "Traceback" not in out, out
    assert "Arm2 needs an input `torque: float[2]` for robot short, has float[3]" in out


def test_bad_q0_option_is_E801(tmp_path: Path) -> None:
    spec = write_spec(write_robots(tmp_path))
    proc = subprocess.run([sys.executable, "-m", "rssm_dsl", "simulate", str(spec), "--until",
                           "0.01", "--device-option", "a1.E.left:q0=1,x"], cwd=ROOT,
                          capture_output=True, text=True, timeout=120)
    out = proc.stdout + proc.stderr
    assert proc.returncode == 1 and "Traceback" not in out, out
    assert "error[E801]: device a1.E.left" in out and "option q0: could not convert" in out


def test_good_spec_runs(tmp_path: Path) -> None:
    proc = _simulate(write_spec(write_robots(tmp_path)))
    assert proc.returncode == 0, proc.stdout + proc.stderr


def test_panda_without_robot_data_is_E801_naming_the_extra() -> None:
    # a Python that cannot see example-robot-data (the package is hidden, not removed)
    code = ("import importlib.metadata as m, runpy, sys\n"
            "real = m.distribution\n"
            "def fake(name):\n"
            "    if name == 'example-robot-data': raise m.PackageNotFoundError(name)\n"
            "    return real(name)\n"
            "m.distribution = fake\n"
            "sys.argv = ['rssmc', 'simulate', 'examples/panda_joints.rssm', '--until', '0.1']\n"
            "runpy.run_module('rssm_dsl', run_name='__main__')\n")
    proc = subprocess.run([sys.executable, "-c", code], cwd=ROOT, capture_output=True,
                          text=True, timeout=120)
    out = proc.stdout + proc.stderr
    assert proc.returncode == 1 and "Traceback" not in out, out
    assert ("error[E801]: device a1.E.arm (rssm_stdlib.robots.device:MujocoArmDevice): robot "
            "panda: the package example-robot-data is not installed: "
            "pip install 'rssmc[robots]'") in out
