"""A long trace is embedded as a window of it: the steps chosen by --from-step / --from-time and
--max-steps, kept as transition indices and marking checkpoints; the warning W855 says which
window is shown and how to see another; the page stays bounded for any trace length."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from rssm_dsl.diagnostics import DiagnosticBag
from rssm_dsl.render import MAX_STEPS_LIMIT
from rssm_dsl.render.html import render_explorer
from rssm_dsl.render.playback import Playback, Window, WindowError, load_playback
from tests.render.browser import rssmc
from tests.render.support import LWR4, lwr4, lwr4_net, markings, random_run, write_trace

RUN = 1200


@pytest.fixture(scope="module")
def run() -> list[str]:
    return random_run(lwr4_net(), RUN, seed=21)


@pytest.fixture(scope="module")
def trace(tmp_path_factory: pytest.TempPathFactory, run: list[str]) -> Path:
    # firing k (1-based) is at time (k - 1) * 0.001 s
    return write_trace(tmp_path_factory.mktemp("window") / "t.jsonl", run)


def _load(trace: Path, window: Window, every: int = 100) -> tuple[Playback, DiagnosticBag]:
    bag = DiagnosticBag()
    pb = load_playback(trace, lwr4_net(), bag, window, every)
    assert pb is not None and not bag.has_errors, bag.items
    return pb, bag


def _names(pb: Playback) -> list[str]:
    return [lwr4_net().transitions[t].name for t in pb.fired]


def test_the_whole_trace_fits_and_no_warning(trace: Path, run: list[str]) -> None:
    pb, bag = _load(trace, Window())
    assert not bag.items
    assert pb.whole and pb.first == 0 and pb.total == RUN and _names(pb) == run
    assert pb.span == (0.0, (RUN - 1) * 0.001)


@pytest.mark.parametrize(("start", "length"), [(0, 300), (250, 400), (1000, 500), (1199, 10)])
def test_from_step_embeds_the_chosen_steps(trace: Path, run: list[str], start: int,
                                           length: int) -> None:
    pb, bag = _load(trace, Window(from_step=start, max_steps=length))
    after = markings(lwr4_net(), run)
    end = min(start + length, RUN)
    assert (pb.first, pb.last, pb.total) == (start, end, RUN)
    assert _names(pb) == run[start:end]
    assert frozenset(pb.initial) == (after[start - 1] if start else frozenset(lwr4_net().initial))
    assert [frozenset(s.marking) for s in pb.steps] == after[start:end]
    assert [s.time for s in pb.steps] == [k * 0.001 for k in range(start, end)]
    (w,) = bag.items
    assert w.code == "W855"
    assert f"the trace has {RUN:,} firings" in w.message
    assert f"the explorer shows steps {start:,} to {end:,}" in w.message
    assert w.hint is not None and "--from-step" in w.hint and "--from-time" in w.hint
    lines = trace.read_text().splitlines()
    if end < RUN:   # at the first firing left out
        assert json.loads(lines[w.span.line - 1])["transition"] == run[end]


def test_from_time_starts_at_the_first_firing_at_or_after_it(trace: Path, run: list[str]) -> None:
    pb, bag = _load(trace, Window(from_time=0.4005, max_steps=100))
    # firings at 0.400 s and before (401 of them) are before the window
    assert pb.first == 401 and _names(pb) == run[401:501]
    assert pb.start_time == pytest.approx(0.4) and pb.times[0] == pytest.approx(0.401)
    assert frozenset(pb.initial) == markings(lwr4_net(), run)[400]
    assert "(t = 0.4 s to 0.5 s)" in bag.items[0].message


def test_a_window_past_the_end_shows_the_last_marking(trace: Path, run: list[str]) -> None:
    for window in (Window(from_step=5000), Window(from_time=99.0)):
        pb, bag = _load(trace, window)
        assert pb.first == RUN and pb.fired == ()
        assert frozenset(pb.initial) == markings(lwr4_net(), run)[-1]
        (w,) = bag.items
        assert w.code == "W855" and "is past its end" in w.message


def test_from_time_needs_times(tmp_path: Path, run: list[str]) -> None:
    cex = tmp_path / "cex.json"
    cex.write_text(json.dumps(run[:20]))
    with pytest.raises(WindowError, match="--from-step"):
        load_playback(cex, lwr4_net(), DiagnosticBag(), Window(from_time=0.1))
    pb, _ = _load(cex, Window(from_step=5))          # a counterexample has steps
    assert _names(pb) == run[5:20]


def test_errors_after_the_window_are_still_found(tmp_path: Path, run: list[str]) -> None:
    path = write_trace(tmp_path / "t.jsonl", [*run[:50], "t[9,nope]"])
    bag = DiagnosticBag()
    assert load_playback(path, lwr4_net(), bag, Window(max_steps=10)) is None
    assert [d.code for d in bag.items] == ["E853"]


@pytest.mark.parametrize("every", [1, 7, 100, 500])
def test_checkpoints_give_the_marking_of_every_step(trace: Path, run: list[str],
                                                    every: int) -> None:
    pb, _ = _load(trace, Window(from_step=100, max_steps=700), every)
    after = markings(lwr4_net(), run)
    assert len(pb.checkpoints) == (700 - 1) // every + 1
    for j, c in enumerate(pb.checkpoints):
        assert frozenset(c) == after[100 + j * every - 1]
    for k in (0, 1, every - 1, every, every + 1, 350, 699, 700):
        if 0 <= k <= 700:
            assert frozenset(pb.marking_at(k)) == after[100 + k - 1]


def test_the_page_embeds_indices_and_checkpoints_not_markings(trace: Path, run: list[str]) -> None:
    comp = lwr4()
    assert comp.hpn is not None
    pb, _ = _load(trace, Window(from_step=200, max_steps=600), every=250)
    html = render_explorer(comp.hpn, lwr4_net(), comp.program, "x.rssm", {}, pb)
    block = html.split('<script type="application/json" id="rssm-data">')[1].split("</script>")[0]
    data = json.loads(block)
    play = data["playback"]
    assert (play["first"], play["total"], play["every"], play["whole"]) == (200, RUN, 250, False)
    assert [data["flat"]["names"][t] for t in play["fired"]] == run[200:800]
    assert len(play["checkpoints"]) == 3
    assert "--from-step" in play["hint"]
    # the times, as change points: every firing is 1 ms after the one before
    assert play["times"]["k"] == list(range(0, 601))
    assert play["times"]["t"][:2] == [pytest.approx(0.199), pytest.approx(0.2)]
    assert "marking" not in json.dumps(play)


def test_the_page_stays_bounded_as_the_trace_grows(tmp_path: Path) -> None:
    comp = lwr4()
    assert comp.hpn is not None
    net = lwr4_net()
    sizes = []
    for n in (2000, 20000):
        path = write_trace(tmp_path / f"t{n}.jsonl", random_run(net, n, seed=n))
        pb, _ = _load(path, Window(from_step=n // 2, max_steps=1000))
        sizes.append(len(render_explorer(comp.hpn, net, comp.program, "x.rssm", {}, pb)))
    assert abs(sizes[1] - sizes[0]) < 0.05 * sizes[0]


def test_cli_window_options(trace: Path, tmp_path: Path) -> None:
    out = tmp_path / "out"
    done = rssmc("render", str(LWR4), "--no-svg", "-o", str(out), "--trace", str(trace),
                 "--from-step", "300", "--max-steps", "200", "-f", "json")
    assert done.returncode == 0, done.stderr
    (w,) = json.loads(done.stdout)
    assert w["code"] == "W855" and "steps 300 to 500" in w["message"]
    assert "--from-time" in w["hint"]
    done = rssmc("render", str(LWR4), "--no-svg", "-o", str(out), "--trace", str(trace),
                 "--from-time", "0.1", "--max-steps", "50")
    assert done.returncode == 0, done.stderr
    assert "playback: steps 100 to 150 of 1200 firings" in done.stderr
    assert "warning[W855]" in done.stderr


@pytest.mark.parametrize("args", [
    ["--from-step", "3", "--from-time", "1"],
    ["--max-steps", str(MAX_STEPS_LIMIT + 1)],
    ["--select", "a1.*"],
])
def test_cli_window_usage_errors(trace: Path, tmp_path: Path, args: list[str]) -> None:
    done = rssmc("render", str(LWR4), "--no-svg", "-o", str(tmp_path / "o"), "--trace",
                 str(trace), *args)
    assert done.returncode == 2, done.stderr
    assert "Traceback" not in done.stderr
    assert not (tmp_path / "o").exists()


def test_cli_window_needs_a_trace(tmp_path: Path) -> None:
    done = rssmc("render", str(LWR4), "--no-svg", "-o", str(tmp_path / "o"), "--from-step", "3")
    assert done.returncode == 2 and "--trace" in done.stderr


def test_cli_from_time_on_a_counterexample_is_a_usage_error(tmp_path: Path,
                                                             run: list[str]) -> None:
    cex = tmp_path / "cex.json"
    cex.write_text(json.dumps(run[:20]))
    done = rssmc("render", str(LWR4), "--no-svg", "-o", str(tmp_path / "o"), "--trace",
                 str(cex), "--from-time", "1")
    assert done.returncode == 2 and "use --from-step" in done.stderr
    assert "Traceback" not in done.stderr and not (tmp_path / "o").exists()


def _no_constants(name: str) -> None:
    raise AssertionError(f"{name} is not JSON a browser parses")


def test_non_finite_times_do_not_break_the_page(tmp_path: Path, run: list[str]) -> None:
    path = tmp_path / "t.jsonl"
    times = ["NaN", "0.5", "Infinity"]
    path.write_text("\n".join(f'{{"event": "fire", "transition": "{n}", "time": {t}}}'
                              for n, t in zip(run[:3], times, strict=True)) + "\n")
    pb, _ = _load(path, Window())
    comp = lwr4()
    assert comp.hpn is not None
    html = render_explorer(comp.hpn, lwr4_net(), comp.program, "x.rssm", {}, pb)
    block = html.split('<script type="application/json" id="rssm-data">')[1].split("</script>")[0]
    play = json.loads(block, parse_constant=_no_constants)["playback"]
    assert play["times"]["t"] == [0.0, None, 0.5, None]
