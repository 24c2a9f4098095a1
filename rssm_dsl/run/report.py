"""What a run writes and prints: ``trajectory.csv`` (one row per device step), ``summary.json``
(the figures), ``fig19.png`` (rssm_dsl.run.plot) and the summary printed on the terminal."""

from __future__ import annotations

import json
import math
from typing import Any

import numpy as np

from rssm_dsl.run.experiment import Experiment
from rssm_dsl.run.metrics import Circle, errors

CSV_HEADER = "t,x_des,y_des,z_des,x,y,z,error,behaviour"


def trajectory_csv(exp: Experiment) -> str:
    """t (s), desired and actual end-effector positions (m), their distance (m), behaviour of c."""
    s = exp.samples
    err = errors(s)
    lines = [CSV_HEADER]
    for k in range(len(s.t)):
        d, a = s.desired[k], s.actual[k]
        lines.append(f"{s.t[k]:.6f},{d[0]:.9f},{d[1]:.9f},{d[2]:.9f},"
                     f"{a[0]:.9f},{a[1]:.9f},{a[2]:.9f},{err[k]:.9f},{s.behaviour[k]}")
    return "\n".join(lines) + "\n"


def _circle(c: Circle | None) -> dict[str, float] | None:
    if c is None:
        return None
    return {"centre_x_m": c.centre[0], "centre_y_m": c.centre[1], "radius_m": c.radius,
            "residual_m": c.residual, "z_m": c.height, "z_spread_m": c.height_spread}


def _finite(x: float) -> float | None:
    return x if math.isfinite(x) else None


def _json_value(v: Any) -> Any:
    if isinstance(v, np.ndarray):
        return v.tolist()
    if isinstance(v, dict):
        return {k: _json_value(x) for k, x in v.items()}
    return v


def summary_dict(exp: Experiment) -> dict[str, Any]:
    m = exp.metrics
    return {
        "spec": exp.spec,
        "system": exp.system,
        "device": exp.rig.device,
        "effector": exp.rig.effector,
        "control": exp.rig.control,
        "setpoint_channel": exp.rig.setpoint_channel,
        "reason": exp.reason,
        "message": exp.message,
        "simulated_s": exp.simulated,
        "wall_s": exp.wall,
        "cpu_s": exp.cpu,
        "real_time_factor": _finite(exp.real_time_factor),
        "cpu_real_time_factor": _finite(exp.cpu_real_time_factor),
        "us_per_device_step": _finite(exp.us_per_step),
        "device_steps": exp.device_steps,
        "firings": exp.firings,
        "samples": m.samples,
        "rms_error_m": _finite(m.rms_error),
        "max_error_m": _finite(m.max_error),
        "max_error_time_s": _finite(m.max_error_time),
        "switches": [{"time_s": sw.time, "from": sw.source, "to": sw.target}
                     for sw in exp.switches],
        "actual_circle": _circle(m.actual_circle),
        "desired_circle": _circle(m.desired_circle),
        "effector_params": {k: _json_value(v) for k, v in exp.params.items()},
        "diagnostics": [d.to_json() for d in exp.diagnostics],
    }


def output_files(exp: Experiment) -> dict[str, str | bytes]:
    """The files of the output folder, by name."""
    from rssm_dsl.run.plot import figure_png

    return {
        "trajectory.csv": trajectory_csv(exp),
        "summary.json": json.dumps(summary_dict(exp), indent=2) + "\n",
        "fig19.png": figure_png(exp),
    }


def _param(v: Any) -> str:
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, float):
        return f"{v:g}"
    return str(v)


def summary_text(exp: Experiment) -> str:
    m = exp.metrics
    mm = 1e3
    lines = [f"{exp.system}: {exp.rig.control} -> {exp.rig.effector} -> {exp.rig.device} "
             f"(LWR4+ simulated by MuJoCo)"]
    lines.append(f"  simulated  {exp.simulated:.3f} s: {exp.device_steps} device steps, "
                 f"{exp.firings:,} firings ({exp.message})")
    lines.append(f"  wall       {exp.wall:.3f} s: {exp.real_time_factor:.1f}x real time, "
                 f"{exp.us_per_step:.1f} us per device step (CPU {exp.cpu:.3f} s: "
                 f"{exp.cpu_real_time_factor:.1f}x)")
    if m.samples:
        lines.append(f"  tracking   RMS {m.rms_error * mm:.3f} mm, max {m.max_error * mm:.3f} mm "
                     f"(at t = {m.max_error_time:.3f} s), {m.samples} samples")
    else:
        lines.append("  tracking   no set point was received: nothing to compare")
    c, d = m.actual_circle, m.desired_circle
    if c is not None:
        want = f" (desired {d.radius * mm:.2f} mm)" if d is not None else ""
        lines.append(f"  circle     centre ({c.centre[0]:.4f}, {c.centre[1]:.4f}) m, radius "
                     f"{c.radius * mm:.2f} mm{want}, off-circle RMS {c.residual * mm:.3f} mm")
    if exp.switches:
        sw = "; ".join(f"{s.source} -> {s.target} at {s.time:.2f} s" for s in exp.switches)
        lines.append(f"  switches   {exp.rig.control}: {sw}")
    else:
        lines.append(f"  switches   {exp.rig.control}: none")
    params = ", ".join(f"{k} = {_param(v)}" for k, v in exp.params.items())
    if params:
        lines.append(f"  params     {exp.rig.effector}: {params}")
    return "\n".join(lines)
