"""Series of a run (rssm_dsl/interp/sampler.py, rssm_core/series.py) and `rssmc plot`: the
chosen variables sampled once per iteration of their subsystem, by the user's names, one
series per component; what is sampled is what the run computed (the active behaviour
changes exactly where the trace says the subsystem switched)."""

from __future__ import annotations

import itertools
import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from rssm_core.series import Series, SeriesFormatError, read_series, write_series
from rssm_dsl.interp import SimOptions, Simulator, build_runtime
from rssm_dsl.interp.sampler import Sampler, SelectionError
from rssm_dsl.interp.trace import TraceWriter, read_trace
from rssm_dsl.pipeline import compile_file
from tests.interp.conftest import EXAMPLES, ROOT

RELAY = EXAMPLES / "relay_blocking.rssm"


def _run(spec: Path, select: list[str] | None, until: float,
         trace: Path | None = None) -> tuple[list[Series], object]:
    from rssm_dsl.interp import RunConfig

    comp = compile_file(spec)
    rt = build_runtime(comp, RunConfig(base_dir=spec.parent))
    sampler = Sampler(rt, select)
    sampler.attach()
    if trace is not None:
        rt.tracer = TraceWriter(trace)
    result = Simulator(rt, SimOptions(until=until)).run()
    if rt.tracer is not None:
        rt.tracer.close()
    return sampler.series(), result


def test_the_default_series_and_one_sample_per_iteration() -> None:
    series, result = _run(RELAY, None, 1.0)
    names = [s.name for s in series]
    assert names == ["a1.c.behaviour", "a1.c.count", "a2.c.behaviour"]
    summary = result.summary  # type: ignore[attr-defined]
    for s in series:
        assert len(s.t) == summary.subsystem(s.subsystem).i
        assert list(s.t) == sorted(s.t) and s.t[-1] <= 1.0


def test_the_behaviour_series_changes_where_the_subsystem_switched(tmp_path: Path) -> None:
    trace = tmp_path / "t.jsonl"
    [beh], _ = _run(RELAY, ["a1.c.behaviour"], 1.0, trace)
    switches = [(e["time"], e["to"]) for e in read_trace(trace)
                if e["event"] == "switch" and e["subsystem"] == "a1.c"]
    assert switches
    labels = [beh.labels[int(v)] for v in beh.v]
    for t, to in switches:
        after = [lab for tt, lab in zip(beh.t, labels, strict=True) if tt > t]
        if after:
            assert after[0] == to, (t, to)
    changes = sum(1 for a, b in itertools.pairwise(labels) if a != b)
    assert changes == len([s for s in switches if s[0] < beh.t[-1]])


def test_records_and_patterns_give_one_series_per_component() -> None:
    spec = EXAMPLES / "camera_tracker.rssm"
    series, _ = _run(spec, ["a1.c.target*", "a1.c.gain"], 0.5)
    assert [s.name for s in series] == ["a1.c.gain", "a1.c.target.visible", "a1.c.target.x",
                                        "a1.c.target.size"]
    assert all(s.kind == "number" for s in series)
    with pytest.raises(SelectionError, match="names no series"):
        _run(spec, ["a1.c.nothing"], 0.1)


def test_a_series_file_reads_back_exactly(tmp_path: Path) -> None:
    path = tmp_path / "s.npz"
    made = [Series("a1.c.q[0]", "a1.c", "number", [], [0.0, 0.01], [1.5, -2.0]),
            Series("a1.c.behaviour", "a1.c", "category", ["cw", "ccw"], [0.0, 0.5], [0.0, 1.0])]
    write_series(path, "arm", made)
    system, back = read_series(path)
    assert system == "arm"
    for a, b in zip(made, back, strict=True):
        assert (a.name, a.subsystem, a.kind, a.labels) == (b.name, b.subsystem, b.kind, b.labels)
        assert np.array_equal(np.asarray(a.t), b.t) and np.array_equal(np.asarray(a.v), b.v)
    bad = tmp_path / "bad.npz"
    bad.write_bytes(b"not a zip")
    with pytest.raises(SeriesFormatError):
        read_series(bad)


def _rssmc(*args: str | Path) -> subprocess.CompletedProcess[str]:
    return subprocess.run([sys.executable, "-m", "rssm_dsl", *map(str, args)], cwd=ROOT,
                          capture_output=True, text=True, timeout=120)


def test_simulate_plots_and_plot_draws_a_saved_run(tmp_path: Path) -> None:
    png, npz, svg = tmp_path / "r.png", tmp_path / "r.npz", tmp_path / "r.svg"
    r = _rssmc("simulate", RELAY, "--until", "1", "--no-live", "--plot", png, "--series", npz)
    assert r.returncode == 0, r.stderr
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    r = _rssmc("plot", npz, "-o", svg, "--select", "a1.c.*")
    assert r.returncode == 0, r.stderr
    assert svg.read_text().lstrip().startswith("<?xml") and "a1.c.count" in svg.read_text()
    r = _rssmc("plot", npz, "-o", svg, "--select", "a9.*")
    assert r.returncode == 2 and "names no series" in r.stderr
    r = _rssmc("simulate", RELAY, "--until", "1", "--plot", tmp_path / "r.pdf")
    assert r.returncode == 2 and ".png or .svg" in r.stderr
    r = _rssmc("simulate", RELAY, "--until", "1", "--series", npz, "--select", "a1.c.nope")
    assert r.returncode == 2 and "names no series" in r.stderr
    r = _rssmc("plot", tmp_path / "r.png")
    assert r.returncode == 2 and "not a series file" in r.stderr


def test_a_series_file_grows_with_samples_not_firings(tmp_path: Path) -> None:
    """The trace of a run grows with its firings; its series file with the series times
    their samples (bench/trace_size.py prints bytes per simulated second of both)."""
    trace, npz = tmp_path / "t.jsonl", tmp_path / "s.npz"
    r = _rssmc("simulate", RELAY, "--until", "5", "--no-live", "-q", "--trace", trace,
               "--series", npz, "--select", "a1.c.count")
    assert r.returncode == 0, r.stderr
    [count] = read_series(npz)[1]
    assert len(count.t) == 501
    assert npz.stat().st_size < trace.stat().st_size / 50
    events = [json.loads(x) for x in trace.read_text().splitlines()]
    assert len(events) > 10 * len(count.t)


def _npz(path: Path, meta: str, arrays: dict[str, list[float]]) -> Path:
    np.savez(path, meta=np.array(meta), **{k: np.asarray(v) for k, v in arrays.items()})
    return path


@pytest.mark.parametrize("kind", ["deep-meta", "meta-list", "lengths", "kind", "nan-time"])
def test_a_bad_series_file_is_E856_in_plot_and_render(tmp_path: Path, kind: str) -> None:
    """One reading (rssm_core/series.py) for both commands: a meta nested too deeply, one
    that is no object, times and values of different lengths, a kind that is neither, a
    time that is not finite: E856 (plot exit 2, render exit 1), never E900."""
    one = {"name": "a1.c.count", "subsystem": "a1.c", "kind": "number", "labels": []}
    t: list[float] = [0.0, 0.1, 0.2]
    if kind == "deep-meta":
        meta = "[" * 100_000 + "]" * 100_000
    elif kind == "meta-list":
        meta = "[1, 2]"
    else:
        if kind == "kind":
            one["kind"] = "weird"
        if kind == "nan-time":
            t = [0.0, float("nan"), 0.2]
        meta = json.dumps({"format": 1, "system": "relay", "series": [one]})
    path = _npz(tmp_path / "s.npz", meta,
                {"t0": t, "v0": [1.0, 2.0] if kind == "lengths" else [1.0, 2.0, 3.0]})
    with pytest.raises(SeriesFormatError):
        read_series(path)
    r = _rssmc("plot", path, "-o", tmp_path / "p.svg")
    assert r.returncode == 2 and "E856" in r.stderr and "Traceback" not in r.stderr, r.stderr
    r = _rssmc("render", RELAY, "--series", path, "-o", tmp_path / "out")
    assert r.returncode == 1 and "E856" in r.stderr and "Traceback" not in r.stderr, r.stderr
