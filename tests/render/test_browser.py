"""The explorer of the LWR4+ example in real headless Chromium: descend to the virtual
effector's behaviour page, read its places and transitions from the DOM, step the playback,
fire a transition, search, take a screenshot, and prove that nothing touched the network."""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest

from rssm_dsl.hpn.flat import FlatNet
from rssm_dsl.hpn.ir import HPN
from tests.conftest import ROOT
from tests.render.browser import NETWORK_SCHEMES, chromium, needs_chromium, requests
from tests.render.support import LWR4, lwr4, lwr4_net, markings, random_run, write_trace

pytestmark = [needs_chromium, pytest.mark.external, pytest.mark.slow]

TARGET = "P^B[1,lwr,move]"
PATH_DOWN = ["P[1]", "P[1,lwr]", TARGET]


def _render(spec: Path, out: Path, *extra: str) -> Path:
    done = subprocess.run([sys.executable, "-m", "rssm_dsl", "render", str(spec), "-o", str(out),
                           "--html", *extra], capture_output=True, text=True, cwd=ROOT,
                          timeout=300, check=False)
    assert done.returncode == 0, done.stderr
    html = out / f"{spec.stem if spec.stem != 'evil' else 'lwr4_circle'}.html"
    assert html.is_file()
    return html


@pytest.fixture(scope="module")
def run() -> list[str]:
    return random_run(lwr4_net(), 300, seed=11)


@pytest.fixture(scope="module")
def explorer(tmp_path_factory: pytest.TempPathFactory, run: list[str]) -> Path:
    out = tmp_path_factory.mktemp("explorer")
    trace = write_trace(out / "trace.jsonl", run)
    return _render(LWR4, out / "html", "--trace", str(trace))


@pytest.fixture(scope="module")
def driver() -> Iterator[Any]:
    with chromium() as d:
        yield d


def _open(driver: Any, html: Path) -> None:
    from selenium.webdriver.support.ui import WebDriverWait

    driver.get(html.as_uri())
    WebDriverWait(driver, 20).until(
        lambda d: d.execute_script("return document.body.getAttribute('data-ready')") == "true")


def _drawn(driver: Any, kind: str) -> set[str]:
    return {e.get_attribute("data-id")
            for e in driver.find_elements("css selector", f"#canvas g.node.{kind}")}


def _node(driver: Any, node_id: str) -> Any:
    return driver.find_element("css selector", f'#canvas g.node[data-id="{node_id}"]')


def _click(driver: Any, node_id: str) -> None:
    _node(driver, node_id).find_element("css selector", ".shape").click()


def _current(driver: Any) -> str:
    return str(driver.find_element("css selector", "#pagehead .title").text)


def _hpn() -> HPN:
    hpn = lwr4().hpn
    assert hpn is not None
    return hpn


def _page_places_marked(hpn: HPN, net: FlatNet, page: str, marking: frozenset[int]) -> set[str]:
    flat = {o: p.index for p in net.places for o in p.origin}
    return {p.id for p in hpn.contents(page)[0] if flat[p.id] in marking}


def _tokens_inside(hpn: HPN, net: FlatNet, page: str, marking: frozenset[int]) -> int:
    flat = {o: p.index for p in net.places for o in p.origin}
    under: set[int] = set()
    stack = [page]
    while stack:
        pg = stack.pop()
        under |= {flat[p.id] for p in hpn.contents(pg)[0]}
        stack.extend(c.id for c in hpn.children(pg))
    return len(under & marking)


def _check_marking(driver: Any, hpn: HPN, net: FlatNet, page: str,
                   marking: frozenset[int]) -> None:
    marked = {e.get_attribute("data-id")
              for e in driver.find_elements("css selector", "#canvas g.place.marked")}
    assert marked == _page_places_marked(hpn, net, page, marking)
    tokens = {e.get_attribute("data-id"): int(e.get_attribute("data-tokens") or 0)
              for e in driver.find_elements("css selector", "#canvas g.node.page")}
    assert tokens == {sp.id: _tokens_inside(hpn, net, sp.id, marking)
                      for sp in hpn.contents(page)[2]}


def test_descend_to_the_virtual_effector_and_play(explorer: Path, driver: Any, run: list[str],
                                                  tmp_path: Path) -> None:
    hpn, net = _hpn(), lwr4_net()
    _open(driver, explorer)
    assert driver.title == "lwr4_circle: HPN explorer"
    assert _current(driver) == "H"
    assert _drawn(driver, "page") == {"P[1]"}
    assert _drawn(driver, "place") == {"p[in]", "p[out]"}

    # click down the hierarchy: system -> agent -> virtual effector -> its behaviour page
    for page in PATH_DOWN:
        _click(driver, page)
        assert _current(driver) == page
    crumbs = [b.text for b in driver.find_elements("css selector", "#crumbs button")]
    assert crumbs == ["H", *PATH_DOWN]
    places, transitions, subpages, _ = hpn.contents(TARGET)
    assert _drawn(driver, "place") == {p.id for p in places}
    assert _drawn(driver, "transition") == {t.id for t in transitions}
    assert _drawn(driver, "page") == {p.id for p in subpages}
    assert {"P^f[1,lwr,move]", "P^B[1,lwr,move,snd]", "P^B[1,lwr,move,rcv]"} <= _drawn(
        driver, "page")
    assert len(driver.find_elements("css selector", "#canvas path.arc")) == len(
        hpn.contents(TARGET)[3])

    # a transition's condition and a place's operation, with the spec line
    _click(driver, "t[1,lwr,move,4]")
    details = driver.find_element("css selector", "#details")
    assert "[not (never)]" in details.text
    span = hpn.transitions["t[1,lwr,move,4]"].span
    assert driver.find_element("css selector", "#details .speclink").text == (
        f"{span.file}:{span.line}")
    assert driver.find_element("css selector", "#details .specline").text == (
        lwr4().program.line(span.file, span.line))
    _click(driver, "p[1,lwr,move,2]")
    op = hpn.places["p[1,lwr,move,2]"].operation
    assert op is not None
    assert driver.find_element("css selector", "#details .op").text == op.text
    driver.find_element("css selector", "#details .speclink").click()
    hit = driver.find_element("css selector", "#srclines div.hit")
    span = hpn.places["p[1,lwr,move,2]"].span
    assert hit.text.endswith(lwr4().program.line(span.file, span.line))

    # step through the trace until something fires on this page; tokens follow the firings
    after = markings(net, run)
    first = next(k for k, t in enumerate(run) if hpn.transitions[t].page == TARGET) + 1
    _check_marking(driver, hpn, net, TARGET, frozenset(net.initial))
    nxt = driver.find_element("css selector", "#next")
    for k in range(1, first + 2):
        nxt.click()
        info = driver.find_element("css selector", "#stepinfo")
        assert info.get_attribute("data-step") == str(k)
        assert _current(driver) == TARGET  # "follow" is off
        _check_marking(driver, hpn, net, TARGET, after[k - 1])
        if k == first:
            fired = driver.find_elements("css selector", "#canvas g.transition.fired")
            assert [e.get_attribute("data-id") for e in fired] == [run[k - 1]]
            shot = tmp_path / "lwr4-explorer-move.png"
            assert driver.save_screenshot(str(shot))
            assert shot.stat().st_size > 20_000
            if os.environ.get("RSSMC_SCREENSHOTS"):
                shutil.copy(shot, Path(os.environ["RSSMC_SCREENSHOTS"]) / shot.name)

    # up, and back down through the browser history
    driver.find_element("css selector", "#up").click()
    assert _current(driver) == "P[1,lwr]"
    driver.back()
    assert _current(driver) == TARGET

    # search by name, open the hit
    box = driver.find_element("css selector", "#search")
    box.send_keys("move,rcv,2,op")
    hits = driver.find_elements("css selector", "#results li[data-id]")
    assert [h.get_attribute("data-id") for h in hits] == ["p[1,lwr,move,rcv,2,op]"]
    hits[0].find_element("css selector", "button").click()
    assert _current(driver) == "P^B[1,lwr,move,rcv,2]"
    assert "selected" in (_node(driver, "p[1,lwr,move,rcv,2,op]").get_attribute("class") or "")
    assert "receive" in driver.find_element("css selector", "#details").text

    # the token game by hand: back to the initial marking on H and fire t[in]
    driver.find_element("css selector", '#crumbs button[data-page="H"]').click()
    driver.find_element("css selector", "#first").click()
    assert "enabled" in (_node(driver, "t[in]").get_attribute("class") or "")
    _click(driver, "t[in]")
    driver.find_element("css selector", "#fire").click()
    assert driver.find_element("css selector", "#stepinfo").get_attribute("data-step") == "1"
    assert "step 1 / 1" in driver.find_element("css selector", "#stepinfo").text
    _check_marking(driver, hpn, net, "H", markings(net, ["t[in]"])[0])

    # nothing but the file itself was requested, and the console stayed clean
    asked = requests(driver)
    assert not [u for u, _ in asked if u.startswith(NETWORK_SCHEMES)], asked
    assert [u for u, doc in asked if doc.startswith("file:")] == [explorer.as_uri()]
    assert driver.execute_script("return performance.getEntriesByType('resource').length") == 0
    errors = [e for e in driver.get_log("browser") if e["level"] == "SEVERE"]
    assert not errors, errors


def test_markup_in_the_spec_is_shown_as_text(driver: Any, tmp_path: Path) -> None:
    evil = '</script><script>window.__pwned = 1</script><img src=x onerror="window.__pwned=2">'
    spec = tmp_path / "evil.rssm"
    spec.write_text(f"// {evil}\n" + LWR4.read_text(), encoding="utf-8")
    html = _render(spec, tmp_path / "out", "--no-svg")
    _open(driver, html)
    assert driver.execute_script("return window.__pwned === undefined")
    assert not driver.find_elements("css selector", "img")
    _click(driver, "p[in]")
    driver.find_element("css selector", "#details .speclink").click()
    first = driver.find_element("css selector", "#srclines div")
    assert first.text == f"1// {evil}"
    errors = [e for e in driver.get_log("browser") if e["level"] == "SEVERE"]
    assert not errors, errors
