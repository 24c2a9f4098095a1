"""The paper's Fig. 19 for a run: (a) the end-effector positions in the horizontal plane
forming the circle, with the desired circle; (b) the coordinates over time; (c) the tracking
error. Drawn with matplotlib's Agg backend (no display), returned as PNG bytes."""

from __future__ import annotations

import io
from typing import TYPE_CHECKING, Any

import numpy as np

if TYPE_CHECKING:
    from rssm_dsl.run.experiment import Experiment

COLOURS = ("#1f77b4", "#d62728", "#2ca02c", "#9467bd", "#8c564b", "#e377c2")


def finish_path_axes(ax: Any) -> None:
    """Labels, equal scales, grid and legend of a path in the horizontal plane (mm)."""
    ax.set_xlabel("x [mm]")
    ax.set_ylabel("y [mm]")
    ax.set_aspect("equal", adjustable="datalim")
    ax.grid(True, alpha=0.3)
    ax.legend(fontsize=8, loc="upper right")


def figure_png(exp: Experiment, dpi: int = 120) -> bytes:
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    s = exp.samples
    mm = 1e3
    fig = Figure(figsize=(13.5, 4.6), layout="constrained")
    FigureCanvasAgg(fig)
    ax_xy, ax_t, ax_e = fig.subplots(1, 3, width_ratios=(1.0, 1.25, 1.25))
    fig.suptitle(f"{exp.system}: {exp.rig.control} cw/ccw circles tracked by {exp.rig.effector} "
                 f"on the simulated LWR4+ ({exp.rig.device})", fontsize=11)

    # (a) the path in the horizontal plane, coloured by the behaviour of c
    names = list(dict.fromkeys(b for b in s.behaviour if b))
    colour = {b: COLOURS[i % len(COLOURS)] for i, b in enumerate(names)}
    ax_xy.plot(s.desired[:, 0] * mm, s.desired[:, 1] * mm, "--", color="0.55", lw=1.0,
               label="desired (c)")
    behaviour = np.array(s.behaviour)
    for i, b in enumerate(names):       # the first behaviour wide underneath, later ones on top
        pts = np.where(behaviour == b, 1.0, np.nan)[:, None] * s.actual
        ax_xy.plot(pts[:, 0] * mm, pts[:, 1] * mm, color=colour[b], lw=max(1.2, 3.6 - 1.6 * i),
                   alpha=0.55 if i == 0 and len(names) > 1 else 1.0, label=f"actual, {b}")
    if len(s.t):
        ax_xy.plot(s.actual[0, 0] * mm, s.actual[0, 1] * mm, "ko", ms=5, label="start")
    fit = exp.metrics.actual_circle
    if fit is not None:
        ax_xy.plot(fit.centre[0] * mm, fit.centre[1] * mm, "k+", ms=8)
        ax_xy.set_title(f"(a) end-effector path: r = {fit.radius * mm:.2f} mm "
                        f"(fit), z = {fit.height * mm:.1f} mm", fontsize=10)
    else:
        ax_xy.set_title("(a) end-effector path", fontsize=10)
    finish_path_axes(ax_xy)

    # (b) coordinates over time, relative to the start
    origin = s.actual[0] if len(s.t) else np.zeros(3)
    for k, axis in enumerate("xyz"):
        line = ax_t.plot(s.t, (s.actual[:, k] - origin[k]) * mm, lw=1.3, label=axis)[0]
        ax_t.plot(s.t, (s.desired[:, k] - origin[k]) * mm, "--", lw=0.9,
                  color=line.get_color())
    ax_t.set_title("(b) position relative to the start (dashed: desired)", fontsize=10)
    ax_t.set_xlabel("t [s]")
    ax_t.set_ylabel("[mm]")
    ax_t.grid(True, alpha=0.3)
    ax_t.legend(fontsize=8, loc="upper right")

    # (c) tracking error
    err = np.linalg.norm(s.desired - s.actual, axis=1) * mm
    m = exp.metrics
    ax_e.plot(s.t, err, color="0.2", lw=1.0)
    ax_e.axhline(m.rms_error * mm, color="#2ca02c", lw=1.0, ls="--",
                 label=f"RMS {m.rms_error * mm:.2f} mm")
    ax_e.set_title(f"(c) tracking error |P_des - P|: max {m.max_error * mm:.2f} mm", fontsize=10)
    ax_e.set_xlabel("t [s]")
    ax_e.set_ylabel("[mm]")
    ax_e.grid(True, alpha=0.3)
    for ax in (ax_t, ax_e):
        for sw in exp.switches:
            ax.axvline(sw.time, color="0.5", lw=0.8, ls=":")
            ax.annotate(f"{sw.source} → {sw.target}", (sw.time, 1.0),
                        xycoords=("data", "axes fraction"), fontsize=7, rotation=90,
                        ha="right", va="top", color="0.35")
    ax_e.legend(fontsize=8, loc="center left")

    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=dpi)
    return buf.getvalue()
