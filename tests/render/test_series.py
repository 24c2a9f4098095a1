"""The series panel of the explorer: decimation keeps each bucket's extremes, the rows are
those of `rssmc plot`, --select is the plot's selection, bad input is a coded diagnostic, and
a hostile series name stays data."""

from __future__ import annotations

import json
import math
import zipfile
from itertools import pairwise
from pathlib import Path

import numpy as np
import pytest

from rssm_core.series import Series, write_series
from rssm_dsl.diagnostics import DiagnosticBag
from rssm_dsl.render.html import render_explorer
from rssm_dsl.render.series import (
    MAX_POINTS,
    MAX_SERIES,
    bucket_count,
    bucket_edges,
    decimate,
    load_series,
    points_per_series,
)
from rssm_dsl.run.series_plot import rows_of
from tests.render.browser import rssmc
from tests.render.support import LWR4, lwr4, lwr4_net
from tests.render.test_html import EVIL, _parse

SYSTEM = "lwr4_circle"


def _series(name: str, v: list[float] | np.ndarray, kind: str = "number",
            labels: list[str] | None = None, dt: float = 0.001) -> Series:
    v = np.asarray(v, dtype=np.float64)
    return Series(name, name.rsplit(".", 1)[0], kind, labels or [],
                  np.arange(len(v)) * dt, v)


def _file(tmp_path: Path, series: list[Series], system: str = SYSTEM) -> Path:
    path = tmp_path / "s.npz"
    write_series(path, system, series)
    return path


# ------------------------------------------------------------------ decimation


def test_decimation_keeps_the_smallest_and_largest_of_every_bucket() -> None:
    rnd = np.random.default_rng(1)
    v = np.cumsum(rnd.normal(size=200_000))
    keep = decimate(v, 1000)
    assert len(keep) <= 1000 and list(keep) == sorted(set(keep.tolist()))
    assert keep[0] == 0 and keep[-1] == len(v) - 1
    edges = bucket_edges(len(v), bucket_count(1000, True))
    kept = set(keep.tolist())
    for a, b in pairwise(edges.tolist()):
        mine = [k for k in kept if a <= k < b]
        assert v[a:b].min() in v[mine] and v[a:b].max() in v[mine]
    assert v.min() in v[keep] and v.max() in v[keep]


def test_a_spike_survives_decimation() -> None:
    v = np.sin(np.linspace(0, 50, 1_000_000))
    v[654_321] = 40.0
    v[123_456] = -40.0
    keep = decimate(v, MAX_POINTS)
    assert 654_321 in keep and 123_456 in keep and len(keep) <= MAX_POINTS


def test_runs_of_equal_values_lose_nothing_drawn_as_steps() -> None:
    rnd = np.random.default_rng(2)
    v = np.repeat(rnd.integers(0, 5, size=300).astype(float), rnd.integers(1, 400, size=300))
    keep = decimate(v, 10_000)
    # holding each kept sample until the next one gives back every sample
    held = np.repeat(v[keep], np.diff(np.append(keep, len(v))))
    assert np.array_equal(held, v)
    assert keep[-1] == len(v) - 1


def test_gaps_are_kept_and_the_bound_holds() -> None:
    v = np.cos(np.linspace(0, 30, 100_000))
    v[50_000:50_010] = np.nan
    v[70_000] = np.inf
    keep = decimate(v, 999)
    assert len(keep) <= 999
    assert not np.isfinite(v[keep]).all()
    assert any(50_000 <= k < 50_010 for k in keep) and 70_000 in keep


def test_many_series_share_a_bounded_budget() -> None:
    assert points_per_series(1) == MAX_POINTS
    assert points_per_series(MAX_SERIES) * MAX_SERIES <= 200_000


# ------------------------------------------------------------------ reading


def test_the_charts_are_the_rows_of_rssmc_plot(tmp_path: Path) -> None:
    series = [_series("a1.c.behaviour", [0, 0, 1, 1, 0], "category", ["cw", "ccw"]),
              _series("a1.c.q[0]", np.linspace(0, 1, 5000)),
              _series("a1.c.q[1]", np.linspace(1, 0, 5000)),
              _series("a1.c.phase", [0.5] * 10)]
    bag = DiagnosticBag()
    panel = load_series(_file(tmp_path, series), SYSTEM, bag)
    assert panel is not None and not bag.items
    assert [(c.title, [ln.name for ln in c.lines]) for c in panel.charts] == [
        (title, [s.name for s in group]) for title, group in rows_of(series)]
    behaviour = panel.charts[0]
    assert behaviour.kind == "category" and behaviour.labels == ("cw", "ccw")
    assert behaviour.lines[0].t == (0.0, 0.002, 0.004) and behaviour.lines[0].v == (0, 1, 0)
    q0 = panel.charts[1].lines[0]
    assert q0.samples == 5000 and len(q0.t) <= MAX_POINTS and q0.bucketed
    assert panel.charts[2].lines[0].t == (0.0, 0.009) and not panel.charts[2].lines[0].bucketed


def test_select_uses_the_plot_patterns(tmp_path: Path) -> None:
    series = [_series("a1.c.behaviour", [0], "category", ["cw"]), _series("a1.c.x", [1.0]),
              _series("a1.e.lwr.behaviour", [0], "category", ["move"])]
    bag = DiagnosticBag()
    panel = load_series(_file(tmp_path, series), SYSTEM, bag, ["*.behaviour"])
    assert panel is not None and not bag.items
    assert [c.title for c in panel.charts] == ["a1.c.behaviour", "a1.e.lwr.behaviour"]
    assert (panel.series, panel.in_file) == (2, 3)


def _codes(bag: DiagnosticBag) -> list[tuple[str, str]]:
    return [(d.code, d.span.file) for d in bag.items]


def test_a_pattern_that_chooses_nothing_is_E857(tmp_path: Path) -> None:
    path = _file(tmp_path, [_series("a1.c.x", [1.0]), _series("a1.c.y", [2.0])])
    bag = DiagnosticBag()
    assert load_series(path, SYSTEM, bag, ["a1.c.x", "a9.*"]) is None
    assert _codes(bag) == [("E857", str(path))]
    d = bag.items[0]
    assert "a9.*" in d.message and d.hint is not None and "a1.c.x, a1.c.y" in d.hint


@pytest.mark.parametrize("what", ["missing", "text", "zip", "no meta", "bad shapes", "empty",
                                  "format", "nan time"])
def test_bad_series_files_are_E856(tmp_path: Path, what: str) -> None:
    path = tmp_path / "s.npz"
    if what == "text":
        path.write_text("a1.c.x,1\n")
    elif what == "zip":
        with zipfile.ZipFile(path, "w") as z:
            z.writestr("readme.txt", "hello")
    elif what == "no meta":
        np.savez(path, t0=np.zeros(3), v0=np.zeros(3))
    elif what == "bad shapes":
        meta = {"format": 1, "system": SYSTEM, "series": [
            {"name": "a1.c.x", "subsystem": "a1.c", "kind": "number", "labels": []}]}
        np.savez(path, meta=np.array(json.dumps(meta)), t0=np.zeros(3), v0=np.zeros(4))
    elif what == "nan time":
        write_series(path, SYSTEM, [Series("a1.c.x", "a1.c", "number", [], [0.0, math.nan],
                                           [1.0, 2.0])])
    elif what == "empty":
        write_series(path, SYSTEM, [])
    elif what == "format":
        np.savez(path, meta=np.array(json.dumps({"format": 9, "system": "x", "series": []})))
    bag = DiagnosticBag()
    assert load_series(path, SYSTEM, bag) is None
    assert _codes(bag) == [("E856", str(path))]
    assert bag.items[0].hint is not None and "--series" in bag.items[0].hint


def test_series_of_another_system_is_W858(tmp_path: Path) -> None:
    bag = DiagnosticBag()
    panel = load_series(_file(tmp_path, [_series("a1.c.x", [1.0])], "relay"), SYSTEM, bag)
    assert panel is not None and _codes(bag) == [("W858", str(tmp_path / "s.npz"))]
    assert "relay" in bag.items[0].message


def test_more_series_than_drawn_is_W859(tmp_path: Path) -> None:
    series = [_series(f"a1.c.x{k}", [float(k)]) for k in range(MAX_SERIES + 3)]
    bag = DiagnosticBag()
    panel = load_series(_file(tmp_path, series), SYSTEM, bag)
    assert panel is not None and panel.series == MAX_SERIES and panel.in_file == MAX_SERIES + 3
    assert [d.code for d in bag.items] == ["W859"]


# ------------------------------------------------------------------ escaping, end to end


def _hostile(tmp_path: Path) -> Path:
    return _file(tmp_path, [
        _series(f"a1.c.{EVIL}", [1.0, 2.0, math.nan, 3.0]),
        _series("a1.c.behaviour", [0, 1], "category", [EVIL, "</SCRIPT >\u2028x"]),
    ])


def test_hostile_series_names_stay_data(tmp_path: Path) -> None:
    comp = lwr4()
    assert comp.hpn is not None
    panel = load_series(_hostile(tmp_path), SYSTEM, DiagnosticBag())
    assert panel is not None
    html = render_explorer(comp.hpn, lwr4_net(), comp.program, "x.rssm", {}, None, panel)
    assert EVIL not in html and "<img" not in html and "</SCRIPT" not in html
    parsed = _parse(html)
    assert [a.get("type") for a, _ in parsed.scripts] == ["application/json", None, None]
    data = json.loads(parsed.scripts[0][1])
    names = [ln["name"] for c in data["series"]["charts"] for ln in c["lines"]]
    assert names == [f"a1.c.{EVIL}", "a1.c.behaviour"]
    assert data["series"]["charts"][1]["labels"] == [EVIL, "</SCRIPT >\u2028x"]
    assert data["series"]["charts"][0]["lines"][0]["v"] == [1.0, 2.0, None, 3.0]


def test_cli_bad_series_writes_nothing(tmp_path: Path) -> None:
    bad = tmp_path / "bad.npz"
    bad.write_text("nope")
    out = tmp_path / "out"
    done = rssmc("render", str(LWR4), "--no-svg", "-o", str(out), "--series", str(bad),
                 "-f", "json")
    assert done.returncode == 1 and "Traceback" not in done.stderr
    assert [(d["code"], d["span"]["file"]) for d in json.loads(done.stdout)] == [
        ("E856", str(bad))]
    assert not out.exists()
    done = rssmc("render", str(LWR4), "--no-svg", "-o", str(out), "--series",
                 str(tmp_path / "absent.npz"))
    assert done.returncode == 1 and "error[E856]" in done.stderr and "no such file" in done.stderr


def test_cli_series_alone_writes_the_explorer(tmp_path: Path) -> None:
    path = _file(tmp_path, [_series("a1.c.x", [1.0, 2.0]), _series("a1.c.y", [3.0])])
    out = tmp_path / "out"
    done = rssmc("render", str(LWR4), "--no-svg", "-o", str(out), "--series", str(path),
                 "--select", "*.y")
    assert done.returncode == 0, done.stderr
    assert "(1 series in 1 charts)" in done.stderr
    html = (out / "lwr4_circle.html").read_text()
    data = json.loads(_parse(html).scripts[0][1])
    assert [c["title"] for c in data["series"]["charts"]] == ["a1.c.y"]
    assert data["playback"] is None
    done = rssmc("render", str(LWR4), "--no-svg", "-o", str(out), "--series", str(path),
                 "--select", "*.z", "--select", "*.x")
    assert done.returncode == 1 and "error[E857]" in done.stderr and "*.z" in done.stderr
