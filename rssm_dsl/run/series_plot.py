"""Draw series of a run (rssm_core/series.py) against time: one row per variable (the
components of a vector or record together, with a legend), one row per behaviour or enum
(its values as labelled steps). matplotlib's Agg backend (no display); PNG or SVG by the
file's suffix."""

from __future__ import annotations

import re
from pathlib import Path

from rssm_core.series import Series

MAX_ROWS = 24
_COMPONENT = re.compile(r"(\[\d+\]|\.[A-Za-z_][A-Za-z0-9_]*)+$")


class PlotError(Exception):
    """Nothing to draw, too much, or a format matplotlib cannot write."""


def _variable(s: Series) -> str:
    """The variable a component series belongs to (``a1.c.q[2]`` -> ``a1.c.q``)."""
    rest = s.name[len(s.subsystem) + 1:]
    head = re.match(r"[A-Za-z_][A-Za-z0-9_]*", rest)
    return f"{s.subsystem}.{head.group()}" if head else s.name


def rows_of(series: list[Series]) -> list[tuple[str, list[Series]]]:
    """The rows of the figure: (title, series drawn in it), in the order given."""
    rows: dict[str, list[Series]] = {}
    for s in series:
        key = s.name if s.kind == "category" else _variable(s)
        rows.setdefault(key, []).append(s)
    return list(rows.items())


def draw(system: str, series: list[Series], out: Path, dpi: int = 110) -> None:
    """Write the figure to ``out`` (.png or .svg); whole or not at all."""
    from rssm_dsl.emit.write import write_outputs

    write_outputs(out.parent, {out.name: figure(system, series, out.suffix, dpi)})


def figure(system: str, series: list[Series], suffix: str, dpi: int = 110) -> bytes:
    """The figure of ``series`` as a .png or .svg file's bytes."""
    import io

    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    if suffix.lower() not in (".png", ".svg"):
        raise PlotError(f"a figure is written as .png or .svg, not {suffix or 'no suffix'}")
    rows = rows_of([s for s in series if len(s.t)])
    if not rows:
        raise PlotError("no samples to draw: the selected subsystems completed no iteration")
    if len(rows) > MAX_ROWS:
        raise PlotError(f"{len(rows)} variables selected; a figure shows at most {MAX_ROWS}: "
                        "narrow --select")
    fig = Figure(figsize=(10.0, 1.0 + 1.7 * len(rows)), layout="constrained")
    FigureCanvasAgg(fig)
    axes = fig.subplots(len(rows), 1, sharex=True, squeeze=False)[:, 0]
    fig.suptitle(f"system {system}", fontsize=11)
    for ax, (title, group) in zip(axes, rows, strict=True):
        ax.set_title(title, fontsize=9, loc="left")
        ax.grid(True, lw=0.4, alpha=0.5)
        for s in group:
            if s.kind == "category":
                ax.step(s.t, s.v, where="post", lw=1.2)
                ax.set_yticks(range(len(s.labels)), s.labels, fontsize=8)
                ax.set_ylim(-0.5, len(s.labels) - 0.5)
            else:
                label = s.name[len(title):] or None
                ax.step(s.t, s.v, where="post", lw=1.0, label=label)
        if len(group) > 1 and len(group) <= 12:
            ax.legend(fontsize=7, loc="upper right", ncol=min(len(group), 6))
    axes[-1].set_xlabel("time (s)")
    data = io.BytesIO()
    fig.savefig(data, format=suffix.lower()[1:], dpi=dpi)
    return data.getvalue()
