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

import os
import subprocess
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
    # the device node is the clock: its state k is stamped k periods of 1 ms; a recorder that
    # fell behind may miss a sample (depth 1, as every channel), hardly ever
    seqs = np.array([r["seq"] for r in rec.states])
    assert np.all(np.diff(seqs) > 0)
    assert np.allclose([r["t"] for r in rec.states], seqs * 1e-3, atol=1e-9)
    # c's set points from its first (it waits for the recorder), each stamped with its tick:
    # 10 ms of simulated time apart
    sp = np.array([(r["seq"], r["t"]) for r in rec.setpoints])
    assert sp[0, 0] == 1
    assert np.allclose(sp[:, 1] - sp[0, 1], 0.01 * (sp[:, 0] - 1), atol=1e-9)
    # the circles took as long as in the interpreter: switches 2 s apart, from c's start
    assert [s.target for s in rec.switches] == [s.target for s in interp.switches]
    assert np.allclose([s.time - sp[0, 1] for s in rec.switches],
                       [s.time for s in interp.switches], atol=1e-9)
    # the same run: one sample per device step from c's first set point (a few missed at most)
    assert abs(ros.metrics.samples - interp.metrics.samples) <= interp.metrics.samples // 100

    ratio = ros.metrics.rms_error / interp.metrics.rms_error
    print(f"lwr4_circle: interpreter RMS {interp.metrics.rms_error * 1e3:.3f} mm, ROS 2 RMS "
          f"{ros.metrics.rms_error * 1e3:.3f} mm (ratio {ratio:.3f}); nodes {t_ros:.1f} s "
          f"wall at real-time factor {REAL_TIME_FACTOR}")
    # within 10 % above; below, the nodes' regular interleaving tracks better than the
    # interpreter's seeded ones (docs/ros2.md, "The LWR4+ on ROS 2"): 0.90 to 0.99 seen, the
    # lower the quieter the machine, so the floor leaves room under 0.9 (a node that slept
    # through the start gave 1.6 to 4)
    assert 0.85 <= ratio <= 1.1, (ros.metrics, interp.metrics)


@pytest.mark.parametrize("missing", ["mujoco", "pinocchio"])
def test_a_missing_physics_package_is_one_line_naming_what_to_install(
        missing: str, ros_physics_venv: toolchain.RosVenv, build_dir: Path, domain: int,
        tmp_path: Path) -> None:
    """The device node (MuJoCo) and the effector node (Pinocchio externs) of the built
    workspace, started where the module cannot be imported (a package of that name that
    raises ModuleNotFoundError, first on PYTHONPATH): exit code 2 and one line."""
    built = build_spec(SPEC, ros_physics_venv, build_dir)
    env = with_rssmc(node_env(built, domain, tmp_path), tmp_path)
    hide = tmp_path / "hide" / missing
    hide.mkdir(parents=True)
    (hide / "__init__.py").write_text(
        f"raise ModuleNotFoundError(\"No module named '{missing}'\", name={missing!r})\n")
    env["PYTHONPATH"] = f"{hide.parent}{os.pathsep}{env['PYTHONPATH']}"
    node = "E_lwr" if missing == "mujoco" else "e_lwr"
    exe = built.root / "install" / "lwr4_circle_a1" / "lib" / "lwr4_circle_a1" / node
    done = subprocess.run([str(exe)], env=env, capture_output=True, text=True, timeout=60,
                          check=False)
    lines = (done.stdout + done.stderr).strip().splitlines()
    assert done.returncode == 2, lines
    assert len(lines) == 1, lines
    assert "[FATAL]" in lines[0] and f"needs '{missing}'" in lines[0], lines
    assert "pip install -r rssm_dsl/ros2/requirements-physics.txt" in lines[0], lines
    print(lines[0])
