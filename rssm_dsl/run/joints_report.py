"""What ``rssmc run`` writes and prints for a joint-space run (joints.py): one arm as
``trajectory.csv``, ``joints.png``, ``summary.json``; several arms as one
``trajectory_<device>.csv`` per arm, ``joints.png`` with each arm's joints and errors and the
behaviours of their control subsystems, and ``summary.json`` with an entry per arm."""

from __future__ import annotations

import io
import json
from collections.abc import Sequence
from typing import Any

import numpy as np

from rssm_dsl.run.joints import JointTracking


def _us_per_step(r: JointTracking, arms: int) -> float:
    """Wall-clock time per step of one arm's device (every arm steps as often)."""
    steps = r.device_steps * arms
    return r.wall / steps * 1e6 if steps else float("nan")


def _run_dict(r: JointTracking, arms: int = 1) -> dict[str, Any]:
    """The run's figures, shared by its ``arms`` arms (``device_steps``: per arm)."""
    return {
        "reason": r.reason, "message": r.message,
        "simulated_s": r.simulated, "wall_s": r.wall, "cpu_s": r.cpu,
        "real_time_factor": r.simulated / r.wall if r.wall > 0 else None,
        "us_per_device_step": _us_per_step(r, arms), "device_steps": r.device_steps,
        "firings": r.firings,
    }


def _arm_dict(r: JointTracking) -> dict[str, Any]:
    return {
        "system_rig": {"control": r.rig.control, "effector": r.rig.effector,
                       "device": r.rig.device, "robot": r.robot},
        "samples": len(r.t),
        "rms_error_rad": r.rms if len(r.t) else None,
        "max_error_rad": r.max_abs if len(r.t) else None,
        "rms_error_per_joint_rad": [float(x) for x in r.rms_per_joint] if len(r.t) else [],
        "switches": [{"time": t, "from": a, "to": b} for t, a, b in r.switches],
    }


def joint_summary_dict(r: JointTracking) -> dict[str, Any]:
    """summary.json of a one-arm run."""
    return _run_dict(r) | _arm_dict(r)


def arms_summary_dict(runs: Sequence[JointTracking]) -> dict[str, Any]:
    """summary.json: a one-arm run's, or the run's figures and ``arms``, one entry each."""
    if len(runs) == 1:
        return joint_summary_dict(runs[0])
    return _run_dict(runs[0], len(runs)) | {"arms": [_arm_dict(r) for r in runs]}


def joint_trajectory_csv(r: JointTracking) -> str:
    dof = r.actual.shape[1] if r.actual.ndim == 2 else 0
    head = (["t"] + [f"q{i + 1}_des" for i in range(dof)] + [f"q{i + 1}" for i in range(dof)]
            + ["error", "behaviour"])
    rows = [",".join(head)]
    err = np.sqrt(np.sum(r.error ** 2, axis=1)) if len(r.t) else np.zeros(0)
    for k in range(len(r.t)):
        values = [r.t[k], *r.desired[k], *r.actual[k], err[k]]
        rows.append(",".join(f"{v:.9g}" for v in values) + f",{r.behaviour[k]}")
    return "\n".join(rows) + "\n"


def trajectory_name(r: JointTracking) -> str:
    """The CSV of one arm of several: ``trajectory_giver_E_arm.csv`` for ``giver.E.arm``."""
    return f"trajectory_{r.rig.device.replace('.', '_')}.csv"


def _draw_arm(top: Any, bottom: Any, r: JointTracking, first: str, second: str) -> None:
    """(first) each joint and its desired position over time; (second) each joint's error."""
    for j in range(r.actual.shape[1] if len(r.t) else 0):
        line = top.plot(r.t, r.actual[:, j], lw=1.2, label=f"q{j + 1}")[0]
        top.plot(r.t, r.desired[:, j], ls="--", lw=0.9, color=line.get_color())
        bottom.plot(r.t, r.error[:, j] * 1e3, lw=1.0, color=line.get_color())
    for t, _, _ in r.switches:
        for ax in (top, bottom):
            ax.axvline(t, color="0.6", lw=0.8, ls=":")
    top.set_ylabel("joint position (rad); desired dashed")
    top.set_title(f"({first}) joints of {r.rig.device} ({r.robot})", loc="left")
    top.legend(ncols=7, fontsize=8, loc="upper right")
    bottom.set_ylabel("error q - q_des (mrad)")
    bottom.set_title(f"({second}) tracking error: RMS {r.rms * 1e3:.3f} mrad" if len(r.t) else
                     f"({second}) tracking error", loc="left")
    for ax in (top, bottom):
        ax.grid(True, lw=0.4, alpha=0.5)


def _draw_behaviours(ax: Any, runs: Sequence[JointTracking], label: str) -> None:
    """Each control subsystem's behaviour over time, one band per subsystem."""
    ticks: list[float] = []
    names: list[str] = []
    for k, r in enumerate(runs):
        order = list(dict.fromkeys(r.behaviour))
        base = 1.5 * k * max(len(order), 1)
        level = {b: base + i for i, b in enumerate(order)}
        ax.step(r.t, [level[b] for b in r.behaviour], where="post", lw=1.4,
                label=r.rig.control)
        ticks += list(level.values())
        names += [f"{r.rig.control} {b}" for b in order]
    ax.set_yticks(ticks, names, fontsize=8)
    ax.set_xlabel("t (s)")
    ax.set_title(f"({label}) behaviours of the control subsystems", loc="left")
    ax.grid(True, lw=0.4, alpha=0.5)


def joint_figure_png(r: JointTracking, dpi: int = 110) -> bytes:
    """(a) each joint and its desired position over time; (b) each joint's error (mrad)."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    fig = Figure(figsize=(11.0, 6.5), layout="constrained")
    FigureCanvasAgg(fig)
    top, bottom = fig.subplots(2, 1, sharex=True)
    _draw_arm(top, bottom, r, "a", "b")
    bottom.set_xlabel("t (s)")
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=dpi)
    return buf.getvalue()


def arms_figure_png(runs: Sequence[JointTracking], dpi: int = 110) -> bytes:
    """One arm's figure, or each arm's joints and errors and the control subsystems'
    behaviours on one time axis."""
    if len(runs) == 1:
        return joint_figure_png(runs[0], dpi)
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    rows = 2 * len(runs) + 1
    fig = Figure(figsize=(11.0, 3.0 * rows), layout="constrained")
    FigureCanvasAgg(fig)
    axes = fig.subplots(rows, 1, sharex=True)
    letters = "abcdefghijklmnopqrstuvwxyz"
    for k, r in enumerate(runs):
        _draw_arm(axes[2 * k], axes[2 * k + 1], r, letters[2 * k], letters[2 * k + 1])
    _draw_behaviours(axes[-1], runs, letters[rows - 1])
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=dpi)
    return buf.getvalue()


def arms_output_files(runs: Sequence[JointTracking]) -> dict[str, str | bytes]:
    """The files of the run's folder."""
    files: dict[str, str | bytes] = {}
    if len(runs) == 1:
        files["trajectory.csv"] = joint_trajectory_csv(runs[0])
    else:
        files |= {trajectory_name(r): joint_trajectory_csv(r) for r in runs}
    files["summary.json"] = json.dumps(arms_summary_dict(runs), indent=2) + "\n"
    files["joints.png"] = arms_figure_png(runs)
    return files


def _tracking_lines(r: JointTracking, who: str) -> list[str]:
    if not len(r.t):
        return [f"  tracking   {who}no set point arrived"]
    return [f"  tracking   {who}joint RMS {r.rms * 1e3:.3f} mrad, max {r.max_abs * 1e3:.3f} "
            f"mrad, {len(r.t)} samples",
            f"  per joint  {who}RMS " + " ".join(f"{x * 1e3:.3f}" for x in r.rms_per_joint)
            + " mrad"]


def _switch_line(r: JointTracking) -> list[str]:
    if not r.switches:
        return []
    return [f"  switches   {r.rig.control}: " + "; ".join(
        f"{a} -> {b} at {t:.2f} s" for t, a, b in r.switches)]


def arms_summary_text(runs: Sequence[JointTracking], system: str) -> str:
    """What ``rssmc run`` prints: the rig(s), the run, each arm's tracking, the switches."""
    r = runs[0]
    several = len(runs) > 1
    if several:
        lines = [f"{system}: {len(runs)} arms simulated by MuJoCo, joint space"]
        lines += [f"  arm        {x.rig.control} -> {x.rig.effector} -> {x.rig.device} "
                  f"({x.robot})" for x in runs]
    else:
        lines = [f"{system}: {r.rig.control} -> {r.rig.effector} -> {r.rig.device} "
                 f"({r.robot} simulated by MuJoCo, joint space)"]
    per_arm = " per arm" if several else ""
    lines.append(f"  simulated  {r.simulated:.3f} s: {r.device_steps} device steps{per_arm}, "
                 f"{r.firings:,} firings ({r.message})")
    rtf = r.simulated / r.wall if r.wall > 0 else float("inf")
    lines.append(f"  wall       {r.wall:.3f} s: {rtf:.1f}x real time, "
                 f"{_us_per_step(r, len(runs)):.1f} us per device step")
    for x in runs:
        lines += _tracking_lines(x, f"{x.rig.device} " if several else "")
    for x in runs:
        lines += _switch_line(x)
    return "\n".join(lines)
