"""The series of a run for the explorer's charts: a series file of `rssmc simulate --series`
(read by the one reader, :func:`rssm_core.series.read_series`), the series chosen by
`--select` (the patterns of `rssmc plot`, :func:`rssm_core.series.select_series`), grouped in
the rows `rssmc plot` draws (:func:`rssm_dsl.run.series_plot.rows_of`: the components of a
vector or record together, a row per behaviour or enum), and decimated so the page stays
bounded: at most :data:`MAX_POINTS` points a series and :data:`MAX_SERIES` series.

Decimation (:func:`decimate`) first keeps only the first sample of each run of equal values
(and the last sample), which loses nothing of a series drawn as steps; if more samples remain
than allowed, they are cut into buckets of consecutive samples and each bucket keeps the
samples of its smallest and of its largest value, so spikes survive.

Bad input is a diagnostic at the file, never an exception: E856 the file cannot be read as a
series file, E857 a `--select` pattern chooses no series, W858 the series were recorded from
another system, W859 more series than the explorer draws.
"""

from __future__ import annotations

import math
from itertools import pairwise
from pathlib import Path
from typing import Any

import numpy as np

from rssm_core.records import dataclass
from rssm_core.series import Series, SeriesFormatError, read_series, select_series
from rssm_dsl.diagnostics import DiagnosticBag
from rssm_dsl.run.series_plot import rows_of
from rssm_dsl.source import Span

MAX_POINTS = 2000          # points a series at most
MIN_POINTS = 200           # ... and at least, when many series share the budget
TOTAL_POINTS = 200_000     # the points of all series, when there are many
MAX_SERIES = 500           # series drawn at most (the most `rssmc simulate` records)
_T_DIGITS, _V_DIGITS = 9, 7  # significant digits embedded (times, values)


@dataclass(frozen=True, slots=True)
class Line:
    """One series as drawn: its decimated samples (None: a non-finite value, a gap)."""

    name: str
    t: tuple[float, ...]
    v: tuple[float | None, ...]
    samples: int               # samples in the file
    bucketed: bool             # cut down to the extremes of buckets (not only runs dropped)


@dataclass(frozen=True, slots=True)
class Chart:
    title: str                 # the variable (its components are the lines) or the series
    kind: str                  # "number" or "category"
    labels: tuple[str, ...]    # a category's values: v indexes them
    lines: tuple[Line, ...]


@dataclass(frozen=True, slots=True)
class SeriesPanel:
    source: str                # the file as given on the command line
    system: str
    charts: tuple[Chart, ...]
    series: int                # series drawn
    in_file: int               # series in the file


def _at(source: str) -> Span:
    return Span(source, 1, 1, 1, 1)


# ------------------------------------------------------------------ decimation


def bucket_edges(n: int, buckets: int) -> np.ndarray:
    """The first index of each of `buckets` runs of consecutive samples of n, and n."""
    return np.linspace(0, n, buckets + 1).round().astype(np.int64)


def _runs(v: np.ndarray) -> np.ndarray:
    """The index of the first sample of each run of equal values, and of the last sample."""
    if len(v) <= 2:
        return np.arange(len(v))
    same = (v[1:] == v[:-1]) | (np.isnan(v[1:]) & np.isnan(v[:-1]))
    keep = np.concatenate(([0], np.flatnonzero(~same) + 1, [len(v) - 1]))
    return np.unique(keep)


def _extremes(v: np.ndarray, edges: np.ndarray) -> np.ndarray:
    """Per bucket, the index of its smallest and of its largest finite value, and of its first
    non-finite value if it has one."""
    keep: list[int] = []
    finite = np.isfinite(v)
    for a, b in pairwise(edges.tolist()):
        if a == b:
            continue
        ok = finite[a:b]
        if ok.any():
            chunk = v[a:b]
            keep.append(a + int(np.argmin(np.where(ok, chunk, np.inf))))
            keep.append(a + int(np.argmax(np.where(ok, chunk, -np.inf))))
        if not ok.all():
            keep.append(a + int(np.argmin(ok)))
    return np.unique(np.asarray(keep, dtype=np.int64))


def bucket_count(max_points: int, finite: bool) -> int:
    """The buckets of a series cut down to `max_points`: the first and last sample, and two
    points a bucket (three when the series has non-finite values)."""
    return max(1, (max_points - 2) // (2 if finite else 3))


def decimate(v: np.ndarray, max_points: int) -> np.ndarray:
    """The indices (ascending) of at most `max_points` (>= 5) samples of `v` that keep its
    drawing as steps: the first of each run of equal values and the last sample; beyond
    `max_points`, the first and last of those and per bucket of consecutive ones
    (:func:`bucket_edges`, :func:`bucket_count`) the smallest and largest value (and the first
    non-finite one, a gap)."""
    runs = _runs(v)
    if len(runs) <= max_points:
        return runs
    kept = v[runs]
    buckets = bucket_count(max_points, bool(np.isfinite(kept).all()))
    picked: np.ndarray = np.union1d(_extremes(kept, bucket_edges(len(runs), buckets)),
                                    [0, len(runs) - 1])
    out: np.ndarray = runs[picked]
    return out


def _round(x: float, digits: int) -> float | None:
    return float(f"{x:.{digits}g}") if math.isfinite(x) else None


def _line(s: Series, max_points: int) -> Line:
    t = np.asarray(s.t, dtype=np.float64)
    v = np.asarray(s.v, dtype=np.float64)
    keep = decimate(v, max_points)
    return Line(s.name, tuple(float(f"{x:.{_T_DIGITS}g}") for x in t[keep]),
                tuple(_round(float(x), _V_DIGITS) for x in v[keep]), len(v),
                len(_runs(v)) > max_points)


def points_per_series(n: int) -> int:
    """The points each of n series may keep: MAX_POINTS, less when many share TOTAL_POINTS."""
    return max(MIN_POINTS, min(MAX_POINTS, TOTAL_POINTS // max(n, 1)))


def charts(series: list[Series]) -> tuple[Chart, ...]:
    """The rows of `rssmc plot` as charts, each series decimated."""
    budget = points_per_series(len(series))
    out: list[Chart] = []
    for title, group in rows_of(series):
        kind = "category" if any(s.kind == "category" for s in group) else "number"
        labels = tuple(group[0].labels) if kind == "category" else ()
        out.append(Chart(title, kind, labels, tuple(_line(s, budget) for s in group)))
    return tuple(out)


# ------------------------------------------------------------------ reading


def _read(path: Path, bag: DiagnosticBag) -> tuple[str, list[Series]] | None:
    source = str(path)
    hint = "give a series file written by `rssmc simulate SPEC --series FILE.npz`"
    if not path.is_file():
        bag.error("E856", f"cannot read '{path}': no such file", _at(source), hint)
        return None
    try:
        system, series = read_series(path)      # each series checked (rssm_core/series.py)
    except SeriesFormatError as e:
        bag.error("E856", f"'{path}' is not a series file: {e}", _at(source), hint)
        return None
    if not series:
        bag.error("E856", f"'{path}' holds no series", _at(source), hint)
        return None
    return system, series


def _select(path: Path, series: list[Series], select: list[str] | None,
            bag: DiagnosticBag) -> list[Series] | None:
    if not select:
        return series
    chosen, unmatched = select_series(series, select)
    names = ", ".join(s.name for s in series[:12]) + (", ..." if len(series) > 12 else "")
    for p in unmatched:
        bag.error("E857", f"--select {p} names no series of '{path}'", _at(str(path)),
                  f"a pattern is a series name or a shell pattern such as 'a1.c.*'; the file "
                  f"has: {names}")
    return None if unmatched else chosen


def load_series(path: Path, system: str, bag: DiagnosticBag,
                select: list[str] | None = None) -> SeriesPanel | None:
    """The charts of the series file at `path` (those chosen by `select`); None (with a
    diagnostic) if it cannot be read or a pattern chooses nothing."""
    read = _read(path, bag)
    if read is None:
        return None
    recorded, series = read
    chosen = _select(path, series, select, bag)
    if chosen is None:
        return None
    if recorded != system:
        bag.warn("W858", f"'{path}' holds the series of system {recorded}, not of {system}",
                 _at(str(path)), "record the series of this specification with `rssmc "
                 "simulate SPEC --series FILE.npz`")
    if len(chosen) > MAX_SERIES:
        bag.warn("W859", f"{len(chosen)} series chosen; the explorer draws the first "
                 f"{MAX_SERIES}", _at(str(path)), "choose fewer with --select PATTERN")
        chosen = chosen[:MAX_SERIES]
    return SeriesPanel(str(path), recorded, charts(chosen), len(chosen), len(series))


def panel_json(panel: SeriesPanel | None) -> dict[str, Any] | None:
    if panel is None:
        return None
    return {"source": panel.source, "system": panel.system, "series": panel.series,
            "in_file": panel.in_file,
            "charts": [{"title": c.title, "kind": c.kind, "labels": list(c.labels),
                        "lines": [{"name": ln.name, "samples": ln.samples,
                                   "decimated": ln.bucketed, "t": list(ln.t), "v": list(ln.v)}
                                  for ln in c.lines]}
                       for c in panel.charts]}
