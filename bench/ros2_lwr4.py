"""The LWR4+ on ROS 2 against the interpreter (issue 20, item 3): examples/lwr4_circle.rssm
generated and built with colcon (the PyPI ros-jazzy wheels; the ROS venv of the tests, with
requirements-physics.txt), launched from its system.launch.py, the topics recorded
(rssm_dsl/ros2/record.py) until c switched behaviours twice (cw, then ccw: 4 s simulated),
and the tracking RMS compared with `rssmc run`'s on the same specification, run here too.

* simulated time (the default): use_sim_time, the MuJoCo device node is the clock, paced at
  each --rtf real-time factor (simulated s per wall-clock s);
* --wall: also on the wall clock (no use_sim_time), as on a robot: the device integrates the
  time that passed between its iterations, every node paces itself at its frequency.

    python bench/ros2_lwr4.py [--rtf 0.2 [0.1 ...]] [--wall] [--plot docs/ros2_lwr4.png]

Prints per run: interpreter RMS, ROS 2 RMS, their ratio, wall-clock seconds of the nodes; with
--plot, the first run's paths and tracking errors beside the interpreter's (PNG).
"""

from __future__ import annotations

import argparse
import os
import tempfile
import time
from pathlib import Path

import numpy as np

from rssm_dsl.pipeline import compile_file
from rssm_dsl.ros2 import simrun, toolchain
from rssm_dsl.ros2.generator import generate, write_workspace
from rssm_dsl.run.experiment import Experiment, RunOptions, run_experiment
from rssm_dsl.run.metrics import errors
from rssm_dsl.run.rig import Rig, find_rig

ROOT = Path(__file__).resolve().parent.parent
SPEC = Path("examples/lwr4_circle.rssm")


def plot(path: Path, interp: Experiment, ros: simrun.RosRun, label: str) -> None:
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    from rssm_dsl.ros2.tracking import samples
    from rssm_dsl.run.plot import finish_path_axes

    mm = 1e3
    s_i, s_r = interp.samples, samples(ros.recording)
    t0 = s_r.t[0] if len(s_r.t) else 0.0        # c's first set point on ROS 2
    fig = Figure(figsize=(12.5, 4.6), layout="constrained")
    FigureCanvasAgg(fig)
    ax_xy, ax_e = fig.subplots(1, 2, width_ratios=(1.0, 1.6))
    fig.suptitle("examples/lwr4_circle.rssm: cw and ccw circles on the simulated LWR4+, "
                 f"interpreter (rssmc run) and ROS 2 nodes ({label})", fontsize=11)
    ax_xy.plot(s_i.desired[:, 0] * mm, s_i.desired[:, 1] * mm, "--", color="0.55", lw=1.0,
               label="desired (c)")
    ax_xy.plot(s_i.actual[:, 0] * mm, s_i.actual[:, 1] * mm, color="#1f77b4", lw=2.6,
               alpha=0.6, label="interpreter")
    ax_xy.plot(s_r.actual[:, 0] * mm, s_r.actual[:, 1] * mm, color="#d62728", lw=1.0,
               label="ROS 2")
    ax_xy.set_title("(a) end-effector path", fontsize=10)
    finish_path_axes(ax_xy)
    ri, rr = interp.metrics.rms_error * mm, ros.metrics.rms_error * mm
    ax_e.plot(s_i.t, errors(s_i) * mm, color="#1f77b4", lw=1.6, alpha=0.7,
              label=f"interpreter, RMS {ri:.3f} mm")
    ax_e.plot(s_r.t - t0, errors(s_r) * mm, color="#d62728", lw=0.9,
              label=f"ROS 2, RMS {rr:.3f} mm (ratio {rr / ri:.3f})")
    ax_e.set_title("(b) tracking error |P_des - P| from c's first set point", fontsize=10)
    ax_e.set_xlabel("t [s]")
    ax_e.set_ylabel("[mm]")
    ax_e.grid(True, alpha=0.3)
    ax_e.legend(fontsize=8, loc="upper right")
    fig.savefig(path, format="png", dpi=110)


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--rtf", type=float, nargs="+", default=[0.2],
                    help="real-time factors of the simulated-time runs")
    ap.add_argument("--wall", action="store_true", help="also a run on the wall clock")
    ap.add_argument("--plot", type=Path, help="PNG of the first run against the interpreter")
    args = ap.parse_args()
    why = toolchain.unsupported_reason()
    if why is not None:
        print(f"skipped: {why}")
        return 0
    os.chdir(ROOT)
    comp = compile_file(SPEC)
    assert comp.system is not None
    rig = find_rig(comp.system)
    assert isinstance(rig, Rig), rig
    ws = generate(comp)
    assert not isinstance(ws, list)
    interp = run_experiment(comp, RunOptions(switches=2))
    ri = interp.metrics.rms_error * 1e3
    print(f"interpreter (rssmc run): tracking RMS {ri:.3f} mm over {interp.metrics.samples} "
          f"samples, {interp.simulated:.3f} s simulated")
    venv = toolchain.ensure_extra(toolchain.ensure_venv(ROOT / ".cache" / "ros2-venv"))
    runs: list[tuple[str, float | None]] = [(f"simulated time, real-time factor {r:g}", r)
                                            for r in args.rtf]
    if args.wall:
        runs.append(("wall clock", None))
    with tempfile.TemporaryDirectory(prefix="rssm-lwr4-") as tmp_s:
        tmp = Path(tmp_s)
        write_workspace(ws, tmp / "ws" / "src")
        env = toolchain.ros_env(venv, 80 + os.getpid() % 10, tmp / "log")
        t0 = time.perf_counter()
        toolchain.colcon_build(tmp / "ws", env, timeout=900)
        print(f"colcon build: {time.perf_counter() - t0:.1f} s")
        env = toolchain.with_rssmc(toolchain.workspace_env(tmp / "ws", env), tmp / "overlay")
        launch = (tmp / "ws" / "install" / "lwr4_circle_bringup" / "share" /
                  "lwr4_circle_bringup" / "launch" / "system.launch.py")
        names = simrun.topics(ws, comp.system, rig)
        for k, (label, rtf) in enumerate(runs):
            ros = simrun.run(env, launch, names, tmp / f"run{k}", rtf, 2, timeout=300)
            rr = ros.metrics.rms_error * 1e3
            steps = np.array([r["seq"] for r in ros.recording.states])
            print(f"ROS 2, {label}: tracking RMS {rr:.3f} mm over {ros.metrics.samples} samples "
                  f"(ratio to the interpreter {rr / ri:.3f}); nodes {ros.wall:.1f} s wall, "
                  f"device steps {steps[-1] - steps[0] + 1 if len(steps) else 0}"
                  + ("" if ros.ok else "; c did NOT switch twice"))
            if args.plot is not None and k == 0:
                plot(args.plot, interp, ros, label)
                print(f"plot: {args.plot}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
