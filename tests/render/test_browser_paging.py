"""The explorer in real headless Chromium: seeking anywhere in a long trace (the step box, the
time box, the slider's neighbours across marking checkpoints) shows the marking that
rssm_dsl/render/playback.py computes for that step, a window of the trace is numbered and
announced as such, and the series panel draws the series of a simulated run with a cursor at
the time of the current step."""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest

from rssm_dsl.diagnostics import DiagnosticBag
from rssm_dsl.render import CHECKPOINT_EVERY
from rssm_dsl.render.playback import Playback, Window, load_playback
from rssm_dsl.render.series import Line, load_series
from tests.conftest import EXAMPLES
from tests.render.browser import (
    chromium,
    needs_chromium,
    open_explorer,
    render_explorer_file,
    rssmc,
    severe_console_errors,
)
from tests.render.support import LWR4, lwr4_net, markings, random_run, write_trace
from tests.render.test_browser import _check_marking, _hpn
from tests.render.test_html import EVIL
from tests.render.test_series import _hostile

pytestmark = [needs_chromium, pytest.mark.external, pytest.mark.slow]

RUN = 2600
PAGE = "P^B[1,lwr,move]"


@pytest.fixture(scope="module")
def driver() -> Iterator[Any]:
    with chromium() as d:
        yield d


@pytest.fixture(scope="module")
def run() -> list[str]:
    return random_run(lwr4_net(), RUN, seed=31)


@pytest.fixture(scope="module")
def trace(tmp_path_factory: pytest.TempPathFactory, run: list[str]) -> Path:
    return write_trace(tmp_path_factory.mktemp("paging") / "t.jsonl", run)


def _playback(trace: Path, window: Window | None = None) -> Playback:
    pb = load_playback(trace, lwr4_net(), DiagnosticBag(), window)
    assert pb is not None and pb.every == CHECKPOINT_EVERY
    return pb


def _info(driver: Any) -> Any:
    return driver.find_element("css selector", "#stepinfo")


def _shown(driver: Any) -> tuple[int, tuple[int, ...]]:
    """The run's step shown and its whole marking (flat place indices)."""
    info = _info(driver)
    marking = info.get_attribute("data-marking") or ""
    return int(info.get_attribute("data-step")), tuple(int(p) for p in marking.split())


def _type(driver: Any, box: str, value: str) -> None:
    field = driver.find_element("css selector", f"#{box}")
    field.clear()
    field.send_keys(f"{value}\n")


def _expect(driver: Any, pb: Playback, run: list[str], n: int) -> None:
    """Step n of the run is shown with the marking playback.py computes (and an independent
    replay agrees)."""
    step, marking = _shown(driver)
    assert step == n
    assert marking == pb.marking_at(n - pb.first)
    after = markings(lwr4_net(), run)
    assert frozenset(marking) == (after[n - 1] if n else frozenset(lwr4_net().initial))


def test_seeking_anywhere_shows_the_marking_of_that_step(driver: Any, trace: Path,
                                                         run: list[str], tmp_path: Path) -> None:
    html = render_explorer_file(LWR4, tmp_path / "out", "--trace", str(trace))
    pb = _playback(trace)
    open_explorer(driver, html)
    driver.find_element("css selector", f'#pagetree button[data-page="{PAGE}"]').click()
    hpn, net = _hpn(), lwr4_net()
    every = CHECKPOINT_EVERY
    # far jumps in both directions, onto, before and after checkpoints, and the ends
    for n in (1234, 0, every - 1, every, every + 1, 2 * every, 3, RUN, 2 * every + 7, 1):
        _type(driver, "stepbox", str(n))
        _expect(driver, pb, run, n)
        _check_marking(driver, hpn, net, PAGE, frozenset(pb.marking_at(n)))
    # stepping over a checkpoint, forward and back
    _type(driver, "stepbox", str(every - 2))
    for n in (every - 1, every, every + 1):
        driver.find_element("css selector", "#next").click()
        _expect(driver, pb, run, n)
    for n in (every, every - 1):
        driver.find_element("css selector", "#prev").click()
        _expect(driver, pb, run, n)
    fired = driver.find_elements("css selector", "#canvas g.transition.fired")
    assert [e.get_attribute("data-id") for e in fired] == (
        [run[every - 2]] if hpn.transitions[run[every - 2]].page == PAGE else [])
    # the time box: firing k is at (k - 1) ms, so t = 1.0005 s is step 1001
    _type(driver, "timebox", "1.0005")
    _expect(driver, pb, run, 1001)
    assert float(_info(driver).get_attribute("data-time")) == pytest.approx(1.0)
    assert driver.find_element("css selector", "#window").get_attribute("hidden") is not None
    assert not severe_console_errors(driver)


def test_a_window_is_numbered_as_the_run_and_says_so(driver: Any, trace: Path, run: list[str],
                                                     tmp_path: Path) -> None:
    html = render_explorer_file(LWR4, tmp_path / "out", "--trace", str(trace),
                                "--from-step", "1000", "--max-steps", "1200")
    pb = _playback(trace, Window(from_step=1000, max_steps=1200))
    open_explorer(driver, html)
    _expect(driver, pb, run, 1000)
    note = driver.find_element("css selector", "#window").text
    assert "holds steps 1000 to 2200" in note and f"of the {RUN} firings" in note
    assert "--from-step" in note and "--from-time" in note
    for n in (2200, 1700, 1501, 1000, 1999):
        _type(driver, "stepbox", str(n))
        _expect(driver, pb, run, n)
    _type(driver, "stepbox", "500")     # not in this file: says so, stays in the window
    assert "Step 500 is not in this file (steps 1000 to 2200)" in driver.find_element(
        "css selector", "#window").text
    _expect(driver, pb, run, 1000)
    assert driver.find_element("css selector", "#stepslider").get_attribute("max") == "1200"
    assert not severe_console_errors(driver)


# ------------------------------------------------------------------ the series panel


@pytest.fixture(scope="module")
def relay(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, Path]:
    out = tmp_path_factory.mktemp("relay")
    trace, series = out / "relay.jsonl", out / "relay.npz"
    done = rssmc("simulate", str(EXAMPLES / "relay_blocking.rssm"), "--until", "2",
                 "--no-live", "-q", "--trace", str(trace), "--series", str(series))
    assert done.returncode == 0, done.stderr
    return trace, series


def _path_points(d: str) -> list[tuple[float, float]]:
    """The vertices of a step path drawn by explorer.js (M x,y then H x [V y] ...): one per
    sample."""
    import re

    points: list[tuple[float, float]] = []
    for cmd, args in re.findall(r"([MHV])([-\d.,]+)", d):
        if cmd == "M":
            x, y = (float(a) for a in args.split(","))
            points.append((x, y))
        elif cmd == "H":
            points.append((float(args), points[-1][1]))
        else:
            points[-1] = (points[-1][0], float(args))
    return points


def _check_line(svg: Any, line: Line, path: Any) -> None:
    """The path of a line goes through its samples, mapped by the chart's axes."""
    t0, t1, y0, y1, left, top, width, height = (
        float(svg.get_attribute(f"data-{k}"))
        for k in ("t0", "t1", "y0", "y1", "left", "top", "width", "height"))
    points = _path_points(path.get_attribute("d"))
    finite = [(t, v) for t, v in zip(line.t, line.v, strict=True) if v is not None]
    assert len(points) == len(finite) == int(path.get_attribute("data-points"))
    for (px, py), (t, v) in zip(points, finite, strict=True):
        assert px == pytest.approx(left + (t - t0) / (t1 - t0) * width, abs=0.06)
        assert py == pytest.approx(top + (y1 - v) / (y1 - y0) * height, abs=0.06)


def test_the_series_panel_draws_the_run(driver: Any, relay: tuple[Path, Path],
                                        tmp_path: Path) -> None:
    trace, series = relay
    spec = EXAMPLES / "relay_blocking.rssm"
    html = render_explorer_file(spec, tmp_path / "out", "--trace", str(trace),
                                "--series", str(series))
    bag = DiagnosticBag()
    panel = load_series(series, "relay", bag)
    assert panel is not None and not bag.items
    open_explorer(driver, html)
    assert driver.find_element("css selector", "#series").is_displayed()
    charts = driver.find_elements("css selector", "#charts .chart")
    assert [c.get_attribute("data-title") for c in charts] == [c.title for c in panel.charts]
    assert [c.find_element("css selector", ".title").text for c in charts] == [
        c.title for c in panel.charts]
    for chart, drawn in zip(panel.charts, charts, strict=True):
        svg = drawn.find_element("css selector", "svg")
        paths = svg.find_elements("css selector", "path.series")
        assert [p.get_attribute("data-name") for p in paths] == [ln.name for ln in chart.lines]
        for line, path in zip(chart.lines, paths, strict=True):
            _check_line(svg, line, path)
        if chart.kind == "category":   # steps labelled with the behaviours' names
            ticks = [t.text for t in svg.find_elements("css selector", "text.tick")]
            assert set(chart.labels) <= set(ticks)
    assert {"up", "down"} <= set(panel.charts[0].labels)

    # the cursor follows the time of the current step
    pb = load_playback(trace, _relay_net(spec), DiagnosticBag())
    assert pb is not None
    for n in (1, 3000, len(pb.fired)):
        _type(driver, "stepbox", str(n))
        want = pb.times[n - 1]
        assert want is not None
        for cur in driver.find_elements("css selector", "#charts line.cursor"):
            assert cur.get_attribute("visibility") == "visible"
            assert float(cur.get_attribute("data-time")) == pytest.approx(want)
    # a click in the middle of a chart goes to the last step at or before that time
    from selenium.webdriver.common.action_chains import ActionChains

    svg = charts[1].find_element("css selector", "svg")
    driver.execute_script("arguments[0].scrollIntoView({block: 'center'})", svg)
    ActionChains(driver).move_to_element(svg).click().perform()
    t0, t1, left, width = (float(svg.get_attribute(k)) for k in
                           ("data-t0", "data-t1", "data-left", "data-width"))
    clicked = t0 + (t1 - t0) * (float(svg.get_attribute("width")) / 2 - left) / width
    step = int(_info(driver).get_attribute("data-step"))
    at, after = pb.times[step - 1], pb.times[step] if step < len(pb.fired) else None
    assert at is not None and at <= clicked + 1e-6
    assert after is None or after > clicked - 1e-6
    assert not severe_console_errors(driver)


def _relay_net(spec: Path) -> Any:
    from rssm_dsl.hpn.flatten import flatten
    from rssm_dsl.pipeline import compile_file

    comp = compile_file(spec)
    assert comp.ok and comp.hpn is not None
    return flatten(comp.hpn)


def test_hostile_series_names_are_shown_as_text(driver: Any, tmp_path: Path) -> None:
    series = _hostile(tmp_path)
    html = render_explorer_file(LWR4, tmp_path / "out", "--series", str(series))
    panel = load_series(series, "lwr4_circle", DiagnosticBag())
    assert panel is not None
    open_explorer(driver, html)
    assert driver.execute_script("return window.__pwned === undefined")
    assert not driver.find_elements("css selector", "img")
    titles = [t.get_attribute("textContent")
              for t in driver.find_elements("css selector", "#charts .chart .title")]
    assert titles == [c.title for c in panel.charts] and EVIL.split(".")[0] in titles[0]
    names = [p.get_attribute("data-name")
             for p in driver.find_elements("css selector", "#charts path.series")]
    assert names == [f"a1.c.{EVIL}", "a1.c.behaviour"]
    ticks = [t.get_attribute("textContent")
             for t in driver.find_elements("css selector", "#charts text.tick")]
    assert EVIL in ticks
    assert not severe_console_errors(driver)
