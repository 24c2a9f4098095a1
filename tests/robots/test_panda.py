"""The second robot end to end: examples/panda_joints.rssm (the Franka Panda of
example-robot-data) tracks its minimum-jerk joint moves, measured as bench/panda.py does."""

from __future__ import annotations

import subprocess
import sys

import numpy as np

from rssm_dsl.pipeline import compile_file
from rssm_dsl.run.joints import run_joint_tracking
from tests.conftest import EXAMPLES, ROOT
from tests.robots.conftest import needs_robot_data

SPEC = EXAMPLES / "panda_joints.rssm"
READY = np.array([0.0, -0.785398, 0.0, -2.356194, 0.0, 1.570796, 0.785398])
REACH = np.array([0.6, -0.2, -0.4, -1.9, 0.3, 1.9, 0.2])


@needs_robot_data
def test_panda_tracks_its_joint_moves() -> None:
    comp = compile_file(SPEC)
    assert comp.ok
    r = run_joint_tracking(comp, until=5.0)
    assert r.ok and r.reason == "until", r.diagnostics
    assert r.rig.device == "a1.E.arm" and r.device_steps == 5001
    assert len(r.t) >= 4990
    # the stated bound (docs/devices.md): joint RMS under 2 mrad, max under 5 mrad
    assert r.rms < 2e-3, r.rms
    assert r.max_abs < 5e-3, r.max_abs
    # the arm went there and back: at the end of the first move it is at `reach`, at the end
    # of the second at `ready`
    i_reach = int(np.searchsorted(r.t, 2.45))
    assert np.allclose(r.actual[i_reach], REACH, atol=5e-3)
    assert np.allclose(r.actual[-1], READY, atol=5e-3)
    # and it moved: not a trivially small error of an arm at rest
    assert np.abs(r.actual - READY).max(axis=0).max() > 0.5


@needs_robot_data
def test_bench_prints_the_figures() -> None:
    proc = subprocess.run([sys.executable, "bench/panda.py", "--until", "2.5"], cwd=ROOT,
                          capture_output=True, text=True, timeout=300)
    assert proc.returncode == 0, proc.stderr
    assert "tracking   joint RMS " in proc.stdout and "per joint  RMS " in proc.stdout


@needs_robot_data
def test_bench_prints_each_arm_of_the_handover() -> None:
    proc = subprocess.run([sys.executable, "bench/panda.py", "--spec",
                           "examples/panda_handover.rssm", "--switches", "1"], cwd=ROOT,
                          capture_output=True, text=True, timeout=300)
    assert proc.returncode == 0, proc.stderr
    lines = proc.stdout.splitlines()
    assert lines[0] == "panda_handover: 2 arms simulated by MuJoCo"
    assert "(switches)" in lines[3]       # stopped at the giver's first switch, at the offer
    for arm in ("giver.E.arm", "taker.E.arm"):
        assert any(x.startswith(f"  tracking   {arm} joint RMS ") for x in lines), lines
        assert any(x.startswith(f"  per joint  {arm} RMS ") for x in lines), lines


def test_without_robot_data_the_bench_says_what_to_install() -> None:
    # a Python that cannot see example-robot-data: the bench skips with a one-line message
    code = ("import importlib.metadata as m, runpy, sys\n"
            "real = m.distribution\n"
            "def fake(name):\n"
            "    if name == 'example-robot-data': raise m.PackageNotFoundError(name)\n"
            "    return real(name)\n"
            "m.distribution = fake\n"
            "sys.argv = ['bench/panda.py']\n"
            "runpy.run_path('bench/panda.py', run_name='__main__')\n")
    proc = subprocess.run([sys.executable, "-c", code], cwd=ROOT, capture_output=True,
                          text=True, timeout=120)
    assert proc.returncode == 0, proc.stderr
    assert proc.stdout.strip() == ("skipped: example-robot-data is not installed: "
                                   "pip install 'rssmc[robots]'")


def test_the_example_compiles_without_robot_data() -> None:
    # compiling needs no model file: only running does
    assert compile_file(SPEC).ok
