"""One SVG per page, drawn by Graphviz: the files exist and hold the page's net."""

from __future__ import annotations

import shutil
import xml.etree.ElementTree as ET
from collections.abc import Callable
from pathlib import Path

import pytest
from typer.testing import CliRunner

from rssm_dsl.cli import make_app
from rssm_dsl.commands.render import PAGE_PROBLEMS_SHOWN
from rssm_dsl.emit.dot import emit_dot
from rssm_dsl.hpn.ir import HPN
from rssm_dsl.render import svg as svg_module
from rssm_dsl.render.names import figure_files
from rssm_dsl.render.svg import GraphvizError, draw_figures, page_dot, render_svgs, run_dot
from tests.conftest import EXAMPLES
from tests.render.support import lwr4

LWR4 = EXAMPLES / "lwr4_circle.rssm"

NS = {"svg": "http://www.w3.org/2000/svg", "xlink": "http://www.w3.org/1999/xlink"}
needs_dot = pytest.mark.skipif(shutil.which("dot") is None, reason="Graphviz dot not installed")


def _hpn() -> HPN:
    hpn = lwr4().hpn
    assert hpn is not None
    return hpn


@pytest.fixture(scope="module")
def svgs() -> dict[str, str]:
    dot = shutil.which("dot")
    if dot is None:
        pytest.skip("Graphviz dot not installed")
    hpn = _hpn()
    return render_svgs(hpn, figure_files(hpn), dot)


def _nodes(svg: str) -> dict[str, tuple[set[str], ET.Element]]:
    root = ET.fromstring(svg)
    out: dict[str, tuple[set[str], ET.Element]] = {}
    for g in root.iter(f"{{{NS['svg']}}}g"):
        classes = set(g.get("class", "").split())
        if "node" in classes:
            title = g.find("svg:title", NS)
            assert title is not None and title.text is not None
            out[title.text] = (classes, g)
    return out


def _edges(svg: str) -> set[str]:
    root = ET.fromstring(svg)
    titles = set()
    for g in root.iter(f"{{{NS['svg']}}}g"):
        if g.get("class") == "edge":
            title = g.find("svg:title", NS)
            assert title is not None and title.text is not None
            titles.add(title.text)
    return titles


def _texts(el: ET.Element) -> list[str]:
    return [t.text or "" for t in el.iter(f"{{{NS['svg']}}}text")]


@pytest.mark.external
def test_one_svg_per_page(svgs: dict[str, str]) -> None:
    hpn = _hpn()
    files = figure_files(hpn)
    assert set(svgs) == set(files.values())
    for page_id, name in files.items():
        root = ET.fromstring(svgs[name])
        assert root.tag == f"{{{NS['svg']}}}svg"
        assert f"page {page_id};" in svgs[name]  # the generated-by note names the page


@pytest.mark.external
def test_each_svg_holds_exactly_its_pages_net(svgs: dict[str, str]) -> None:
    hpn = _hpn()
    files = figure_files(hpn)
    for page_id, name in files.items():
        places, transitions, subpages, arcs = hpn.contents(page_id)
        nodes = _nodes(svgs[name])
        assert {n for n, (c, _) in nodes.items() if "place" in c} == {p.id for p in places}
        assert {n for n, (c, _) in nodes.items() if "transition" in c} == {
            t.id for t in transitions}
        assert {n for n, (c, _) in nodes.items() if "page" in c} == {p.id for p in subpages}
        assert _edges(svgs[name]) == {f"{a.source}->{a.target}" for a in arcs}


@pytest.mark.external
def test_drawn_as_the_paper_draws(svgs: dict[str, str]) -> None:
    hpn = _hpn()
    files = figure_files(hpn)
    svg = svgs[files["P^B[1,lwr,move]"]]
    nodes = _nodes(svg)
    # transitions are boxes (polygons) with their condition in square brackets
    classes, t4 = nodes["t[1,lwr,move,4]"]
    assert t4.find(".//svg:polygon", NS) is not None
    assert "[not (never)]" in _texts(t4)
    # places are circles; pages double circles (two ellipses) linking to their figure
    assert nodes["p[1,lwr,move,2]"][1].find(".//svg:ellipse", NS) is not None
    _, rcv = nodes["P^B[1,lwr,move,rcv]"]
    assert len(rcv.findall(".//svg:ellipse", NS)) == 2
    link = rcv.find(".//svg:a", NS)
    assert link is not None
    assert link.get(f"{{{NS['xlink']}}}href") == files["P^B[1,lwr,move,rcv]"]
    # the operation is in the place's tooltip, user text escaped and read back intact
    op = hpn.places["p[1,lwr,move,2]"].operation
    assert op is not None
    tip = nodes["p[1,lwr,move,2]"][1].find(".//svg:a", NS)
    assert tip is not None and op.text in (tip.get(f"{{{NS['xlink']}}}title") or "")
    # fused places are dashed and initially marked ones hold a token
    fused = _nodes(svgs[files["P^B[1,lwr,move,rcv,1]"]])
    classes, el = fused["p[1,lwr,move,rcv,1,2]"]
    assert "fused" in classes
    ellipse = el.find(".//svg:ellipse", NS)
    assert ellipse is not None and ellipse.get("stroke-dasharray")
    assert "●" in _texts(el)
    assert "●" not in _texts(fused["p[1,lwr,move,rcv,1,1]"][1])


@pytest.mark.external
def test_user_text_with_markup_survives_as_text(svgs: dict[str, str]) -> None:
    hpn = _hpn()
    files = figure_files(hpn)
    svg = svgs[files["P^f[1,c,ccw,2]"]]
    nodes = _nodes(svg)
    op = hpn.places["p[1,c,ccw,2,1]"].operation
    assert op is not None and "%" in op.text  # `phase := phase % (2.0 * pi) + ...`
    tip = nodes["p[1,c,ccw,2,1]"][1].find(".//svg:a", NS)
    assert tip is not None and op.text in (tip.get(f"{{{NS['xlink']}}}title") or "")


def test_page_dot_reuses_the_layer_drawing() -> None:
    hpn = _hpn()
    files = figure_files(hpn)
    text = page_dot(hpn, hpn.pages["H"], files)
    assert text.startswith("// generated by rssmc from system lwr4_circle: page H")
    assert '"P[1]" [shape=doublecircle, label="P[1]", class="page", URL="fig-P_1.svg"' in text
    assert '"p[in]" [shape=circle, label="●", xlabel="p[in]"' in text
    layer = emit_dot(hpn)["dot/layer1-system.dot"]
    assert '"p[in]" [shape=circle, label="●", xlabel="p[in]"];' in layer


@needs_dot
def test_dot_failure_is_reported_with_the_page(tmp_path: Path) -> None:
    dot = shutil.which("dot")
    assert dot is not None
    with pytest.raises(GraphvizError) as err:
        run_dot(dot, "P[x]", "digraph { a -> }")
    assert err.value.page == "P[x]" and err.value.message
    with pytest.raises(GraphvizError):
        run_dot(str(tmp_path / "no-such-dot"), "P[x]", "digraph { a }")


# ------------------------------------------------------------------ a page dot cannot lay out

@needs_dot
def test_pages_drawn_in_parallel_are_the_pages_drawn_one_by_one() -> None:
    dot = shutil.which("dot")
    assert dot is not None
    hpn = _hpn()
    one, p1 = draw_figures(hpn, figure_files(hpn), dot, jobs=1)
    four, p4 = draw_figures(hpn, figure_files(hpn), dot, jobs=4)
    assert one == four and p1 == p4 == []


def _slow_on(pages: set[str], quick_too: bool) -> Callable[..., str]:
    """run_dot, with a first layout that times out on ``pages`` (the real dot, a timeout of
    0.1 ms), and the quick layout too if ``quick_too``."""
    real = svg_module.run_dot

    def run(dot: str, page: str, source: str, options: tuple[str, ...] = (),
            timeout: float | None = None) -> str:
        if page in pages and (not options or quick_too):
            timeout = 1e-4
        return real(dot, page, source, options, timeout)

    return run


@needs_dot
@pytest.mark.parametrize("quick_too", [False, True])
def test_one_page_dot_cannot_lay_out_does_not_fail_the_command(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch, quick_too: bool) -> None:
    """The page is laid out again with the quick layout (W849, a full figure), or drawn as a
    placeholder that says why (W849, and the explorer is written to show it); every other
    page is drawn as usual, and the command succeeds (it failed with E851)."""
    hpn = _hpn()
    names = figure_files(hpn)
    slow = next(p for p in names if p.startswith("P^B"))
    monkeypatch.setattr(svg_module, "run_dot", _slow_on({slow}, quick_too))
    out = tmp_path / "out"
    result = CliRunner().invoke(make_app(), ["render", str(LWR4), "-o", str(out)])
    assert result.exit_code == 0, result.output
    warnings = [line for line in result.output.splitlines() if "warning[W849]" in line]
    assert len(warnings) == 1 and slow in warnings[0], result.output
    figure = (out / names[slow]).read_text()
    ET.fromstring(figure)                                   # well-formed either way
    assert ('class="not-drawn"' in figure) is quick_too
    assert (out / f"{hpn.system}.html").exists() is quick_too
    others = [f for p, f in names.items() if p != slow]
    assert all('class="not-drawn"' not in (out / f).read_text() for f in others)


@needs_dot
def test_a_dot_that_fails_on_every_page_is_E851(tmp_path: Path,
                                               monkeypatch: pytest.MonkeyPatch) -> None:
    hpn = _hpn()
    monkeypatch.setattr(svg_module, "run_dot", _slow_on(set(figure_files(hpn)), True))
    out = tmp_path / "out"
    result = CliRunner().invoke(make_app(), ["render", str(LWR4), "-o", str(out)])
    assert result.exit_code == 1 and "error[E851]" in result.output, result.output
    assert (out / f"{hpn.system}.html").exists()


@needs_dot
def test_the_warnings_of_many_hard_pages_are_bounded(tmp_path: Path,
                                                     monkeypatch: pytest.MonkeyPatch) -> None:
    hpn = _hpn()
    names = figure_files(hpn)
    slow = set(list(names)[1:])                    # all but the root: no E851
    monkeypatch.setattr(svg_module, "run_dot", _slow_on(slow, False))
    result = CliRunner().invoke(make_app(), ["render", str(LWR4), "-o", str(tmp_path / "o")])
    assert result.exit_code == 0, result.output
    warnings = [line for line in result.output.splitlines() if "warning[W849]" in line]
    assert len(warnings) == PAGE_PROBLEMS_SHOWN + 1 < len(slow), result.output
    assert f"{len(slow) - PAGE_PROBLEMS_SHOWN} more pages" in warnings[-1]
