"""The LWR4+ on ROS 2 (issue 20, item 3): examples/lwr4_circle.rssm generated, built and
launched from its system.launch.py with use_sim_time (the MuJoCo device node, the very class
``rssmc run`` steps, is the clock at a real-time factor the nodes keep up with; the effector's
Pinocchio externs run in their node), its topics recorded (rssm_dsl/ros2/record.py), and the
tracking RMS over the cw and ccw circles compared with the interpreter's on the same
specification, run in this test: within 10 %.

About 30 s of nodes at real-time factor 0.2 (4 s simulated) after the build, which
test_hosts.py shares. bench/ros2_lwr4.py prints the same figures (and plots them).
"""

from __future__ import annotations

import time
from pathlib import Path

import numpy as np
import pytest

from rssm_dsl.pipeline import compile_file
from rssm_dsl.ros2 import simrun, toolchain
from rssm_dsl.ros2.generator import generate
from rssm_dsl.run.experiment import RunOptions, run_experiment
from rssm_dsl.run.rig import Rig, find_rig
from tests.conftest import ROOT
from tests.ros2.conftest import build_spec, node_env, with_rssmc

pytestmark = [pytest.mark.ros2, pytest.mark.slow]

SPEC = ROOT / "examples" / "lwr4_circle.rssm"
REAL_TIME_FACTOR = 0.2
SWITCHES = 2                    # cw -> ccw -> cw, as `rssmc run` does: 4 s simulated


def test_lwr4_circle_on_ros2_tracks_as_the_interpreter_does(
        ros_physics_venv: toolchain.RosVenv, build_dir: Path, domain: int,
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.chdir(ROOT)
    comp = compile_file(SPEC.relative_to(ROOT))
    assert comp.system is not None
    rig = find_rig(comp.system)
    assert isinstance(rig, Rig)
    ws = generate(comp)
    assert not isinstance(ws, list)
    built = build_spec(SPEC, ros_physics_venv, build_dir)
    env = with_rssmc(node_env(built, domain, tmp_path), tmp_path)
    t0 = time.monotonic()
    ros = simrun.run(env, built.system_launch_file("lwr4_circle"),
                     simrun.topics(ws, comp.system, rig), tmp_path / "ros",
                     REAL_TIME_FACTOR, SWITCHES, timeout=120)
    t_ros = time.monotonic() - t0
    interp = run_experiment(comp, RunOptions(switches=SWITCHES))
    logs = "\n".join(f"{p.name}: {p.read_text()[-1500:]}" for p in sorted(ros.log_dir.iterdir()))
    assert ros.ok, f"the control subsystem did not switch {SWITCHES} times:\n{logs}"

    rec = ros.recording
    # the device node is the clock: its state k is stamped k periods of 1 ms, none missing
    seqs = np.array([r["seq"] for r in rec.states])
    stamps = np.array([r["t"] for r in rec.states])
    assert np.array_equal(seqs, np.arange(seqs[0], seqs[0] + len(seqs)))
    assert np.allclose(stamps, seqs * 1e-3, atol=1e-9)
    # every set point of c from its first (it waits for the recorder), one per 10 ms of
    # simulated time: the k-th sent at its tick, or a few ms after it when c's node woke late
    # (its stamp is the clock when it published)
    sp = np.array([r["t"] for r in rec.setpoints])
    assert [r["seq"] for r in rec.setpoints] == list(range(1, len(sp) + 1))
    late = sp - sp[0] - 0.01 * np.arange(len(sp))
    assert late.min() > -1e-6 and late.max() < 0.005, late
    # the circles took as long as in the interpreter: switches 2 s apart, from c's start
    assert [s.target for s in rec.switches] == [s.target for s in interp.switches]
    assert np.allclose([s.time - sp[0] for s in rec.switches],
                       [s.time for s in interp.switches], atol=1e-6)
    # the same run, sample for sample: one per device step from c's first set point
    assert abs(ros.metrics.samples - interp.metrics.samples) <= 1

    ratio = ros.metrics.rms_error / interp.metrics.rms_error
    print(f"lwr4_circle: interpreter RMS {interp.metrics.rms_error * 1e3:.3f} mm, ROS 2 RMS "
          f"{ros.metrics.rms_error * 1e3:.3f} mm (ratio {ratio:.3f}); nodes {t_ros:.1f} s "
          f"wall at real-time factor {REAL_TIME_FACTOR}")
    assert 0.9 <= ratio <= 1.1, (ros.metrics, interp.metrics)
