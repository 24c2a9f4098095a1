"""`rssmc run` on a system without the LWR4+ experiment but with an arm of stdlib/robots
tracking joint set points: examples/panda_joints.rssm (the Panda of example-robot-data)."""

from __future__ import annotations

import csv
import json
from pathlib import Path

import numpy as np

from tests.conftest import EXAMPLES
from tests.robots.conftest import needs_robot_data
from tests.run.conftest import rssmc

PANDA = EXAMPLES / "panda_joints.rssm"


@needs_robot_data
def test_rssmc_run_panda_writes_and_prints_the_joint_figures(tmp_path: Path) -> None:
    out = tmp_path / "out"
    proc = rssmc("run", PANDA, "-o", out, "--format", "json")
    assert proc.returncode == 0, proc.stderr
    summary = json.loads(proc.stdout)
    assert sorted(p.name for p in out.iterdir()) == ["joints.png", "summary.json",
                                                    "trajectory.csv"]
    assert json.loads((out / "summary.json").read_text()) == {
        k: v for k, v in summary.items() if k != "outputs"}
    assert summary["system_rig"] == {"control": "a1.c", "effector": "a1.e.arm",
                                     "device": "a1.E.arm", "robot": "panda"}
    # stopped by c's second switch (back -> out at 5 s), not by --until
    assert summary["reason"] == "switches"
    assert [(s["from"], s["to"]) for s in summary["switches"]] == [("out", "back"),
                                                                  ("back", "out")]
    assert [round(s["time"], 2) for s in summary["switches"]] == [2.5, 5.0]
    assert summary["rms_error_rad"] < 2e-3 and summary["max_error_rad"] < 5e-3
    # the CSV is the run: its errors give the summary's RMS
    with (out / "trajectory.csv").open(newline="") as f:
        rows = list(csv.DictReader(f))
    assert len(rows) == summary["samples"] >= 4990
    q = np.array([[float(r[f"q{i}"]) for i in range(1, 8)] for r in rows])
    qd = np.array([[float(r[f"q{i}_des"]) for i in range(1, 8)] for r in rows])
    assert abs(np.sqrt(np.mean((q - qd) ** 2)) - summary["rms_error_rad"]) < 1e-7
    assert {r["behaviour"] for r in rows} == {"out", "back"}
    assert (out / "joints.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


@needs_robot_data
def test_text_summary_and_lwr4_only_options(tmp_path: Path) -> None:
    proc = rssmc("run", PANDA, "-o", tmp_path / "o", "--until", "1", "--switches", "0")
    assert proc.returncode == 0, proc.stderr
    lines = proc.stdout.splitlines()
    assert lines[0] == ("panda_joints: a1.c -> a1.e.arm -> a1.E.arm (panda simulated by "
                        "MuJoCo, joint space)")
    assert "1001 device steps" in lines[1] and "reached t = 1 s" in lines[1]
    assert lines[3].startswith("  tracking   joint RMS ")
    for option in (["--damping", "paper"], ["--video", str(tmp_path / "v.mp4")]):
        bad = rssmc("run", PANDA, "-o", tmp_path / "x", *option)
        assert bad.returncode == 2
        assert "apply to the LWR4+ experiment only" in bad.stderr


def test_every_arm_needs_its_joint_set_points(tmp_path: Path) -> None:
    # two arms driven by one effector that receives no joint set points: E870 at the first
    from rssm_dsl.diagnostics import Diagnostic
    from rssm_dsl.pipeline import compile_file
    from rssm_dsl.run.joints import find_joint_rig, find_joint_rigs
    from tests.robots.conftest import write_robots, write_spec

    comp = compile_file(write_spec(write_robots(tmp_path)))
    assert comp.ok and comp.system is not None
    found = find_joint_rigs(comp.system)
    assert isinstance(found, Diagnostic) and found.code == "E870"
    assert found.message == ("a1.e.hold receives no joint set points (a record with "
                             "`q: float[n]`) from another subsystem")
    assert find_joint_rig(comp.system) == found
    # rssmc run says so, at the device, instead of looking for the LWR4+ experiment
    proc = rssmc("run", tmp_path / "arms.rssm", "-o", tmp_path / "out")
    assert proc.returncode == 1 and "Traceback" not in proc.stderr
    assert "arms.rssm:48:19: error[E870]: a1.e.hold receives no joint set points" in proc.stderr
    # the Panda example has one arm
    panda = compile_file(PANDA).system
    assert panda is not None
    rigs = find_joint_rigs(panda)
    assert not isinstance(rigs, Diagnostic)
    assert [r.device for r in rigs] == ["a1.E.arm"]
