"""The HTML outputs of `rssmc render`: the self-contained explorer and the index of figures.

The explorer is one file: the HPN IR (rssm_dsl/emit/json_ir.py), the flattened net's pre/post
sets, the text of the specification files the IR points to, the playback (a window of the
firing sequence: transition indices and marking checkpoints, see playback.py) and the series
of a run (decimated, see series.py) are embedded as one JSON block; the vendored layout
library (assets/dagre.min.js, from the npm package @dagrejs/dagre, see
assets/package-lock.json and assets/vendor.sh) and the explorer's own script and style sheet
are inlined. Nothing is fetched when the page is opened, and its
Content-Security-Policy forbids any fetch (scripts are allowed by hash only).

User text never enters the markup: Jinja2 autoescapes every value, and the JSON block escapes
`<`, `>`, `&` and the JavaScript line separators, so no `</script>` can close it early; the
script builds the DOM with textContent only.
"""

from __future__ import annotations

import base64
import hashlib
import json
import math
from importlib import resources
from typing import Any

from jinja2 import Environment, PackageLoader, StrictUndefined
from markupsafe import Markup

from rssm_core.records import dataclass
from rssm_dsl import __version__
from rssm_dsl.emit.json_ir import to_json
from rssm_dsl.emit.order import pages_in_order
from rssm_dsl.hpn.flat import FlatNet
from rssm_dsl.hpn.ir import HPN
from rssm_dsl.render.playback import WINDOW_HINT, Playback
from rssm_dsl.render.series import SeriesPanel, panel_json
from rssm_dsl.semantics.loader import Program
from rssm_dsl.source import split_lines

FORMAT = "rssmc-explorer"
FORMAT_VERSION = 2
_JS_ESCAPES = {"<": "\\u003c", ">": "\\u003e", "&": "\\u0026",
               "\u2028": "\\u2028", "\u2029": "\\u2029"}


@dataclass(frozen=True, slots=True)
class IndexRow:
    layer: str
    depth: int
    page: str
    label: str
    file: str | None


def _env() -> Environment:
    return Environment(loader=PackageLoader("rssm_dsl.render", "templates"), autoescape=True,
                       undefined=StrictUndefined, trim_blocks=True, lstrip_blocks=True,
                       keep_trailing_newline=True)


def asset(name: str) -> str:
    """The text of a file shipped in rssm_dsl/render/assets."""
    return resources.files("rssm_dsl.render").joinpath("assets", name).read_text(encoding="utf-8")


def script_json(value: Any) -> str:
    """JSON safe to place inside <script type="application/json">: no `<`, `>` or `&` in it
    (those occur only inside JSON strings, where \\u escapes mean the same)."""
    text = json.dumps(value, ensure_ascii=False, separators=(",", ":"), sort_keys=False)
    return "".join(_JS_ESCAPES.get(ch, ch) for ch in text)


def _inline(text: str, tag: str) -> Markup:
    """A shipped asset placed verbatim inside <tag>; it must not be able to close the tag."""
    if f"</{tag}" in text.lower():
        raise ValueError(f"asset contains </{tag}")
    return Markup(text)


def _sha256(text: str) -> str:
    """A CSP source expression allowing exactly this inline script."""
    digest = hashlib.sha256(text.encode("utf-8")).digest()
    return f"'sha256-{base64.b64encode(digest).decode()}'"


def _flat_json(net: FlatNet) -> dict[str, Any]:
    place_of = {origin: p.index for p in net.places for origin in p.origin}
    names = [""] * len(net.transitions)
    for t in net.transitions:
        names[t.index] = t.name
    return {
        "places": [p.name for p in net.places],
        "names": names,                # transition index -> name (the playback's indices)
        "place_of": place_of,
        "transitions": {t.name: {"pre": list(t.pre), "post": list(t.post)}
                        for t in net.transitions},
        "initial": sorted(net.initial),
        "final": sorted(net.final),
    }


def _finite(t: float | None) -> float | None:
    """A time JSON can hold (a trace may say NaN or Infinity; JSON.parse would refuse it)."""
    return t if t is not None and math.isfinite(t) else None


def _times_json(pb: Playback) -> dict[str, list[Any]] | None:
    """The time of each window step as change points: from step k[i] on, the time is t[i]."""
    if pb.start_time is None and all(t is None for t in pb.times):
        return None
    ks: list[int] = [0]
    ts: list[float | None] = [_finite(pb.start_time)]
    for k, time in enumerate(pb.times, start=1):
        t = _finite(time)
        if t != ts[-1]:
            ks.append(k)
            ts.append(t)
    return {"k": ks, "t": ts}


def _playback_json(pb: Playback | None) -> dict[str, Any] | None:
    """The window of the firing sequence: the index of each fired transition, the whole
    marking every `every` steps, and the times; the explorer fires the rest."""
    if pb is None:
        return None
    return {"source": pb.source, "kind": pb.kind, "first": pb.first, "total": pb.total,
            "whole": pb.whole, "every": pb.every, "fired": list(pb.fired),
            "checkpoints": [list(c) for c in pb.checkpoints], "times": _times_json(pb),
            "span": [_finite(t) for t in pb.span] if pb.span is not None else None,
            "hint": None if pb.whole else WINDOW_HINT}


def _sources(hpn: HPN, program: Program) -> dict[str, list[str]]:
    """The lines of every specification file an IR element points to."""
    files = {p.span.file for p in hpn.pages.values()}
    files |= {p.span.file for p in hpn.places.values()}
    files |= {t.span.file for t in hpn.transitions.values()}
    files |= {f.span.file for f in hpn.fusions.values()}
    return {f: split_lines(program.sources[f].text) for f in sorted(files)
            if f in program.sources}


def explorer_data(hpn: HPN, net: FlatNet, program: Program, figures: dict[str, str],
                  playback: Playback | None, series: SeriesPanel | None = None) -> dict[str, Any]:
    return {
        "format": FORMAT,
        "version": FORMAT_VERSION,
        "generator": f"rssmc {__version__}",
        "ir": to_json(hpn),
        "flat": _flat_json(net),
        "sources": _sources(hpn, program),
        "figures": figures,
        "playback": _playback_json(playback),
        "series": panel_json(series),
    }


def render_explorer(hpn: HPN, net: FlatNet, program: Program, spec: str,
                    figures: dict[str, str], playback: Playback | None,
                    series: SeriesPanel | None = None) -> str:
    """The self-contained HTML explorer. `figures` maps page ids to SVG files written beside it
    (empty when none were drawn); `series`: the charts of a run's series, if any."""
    dagre = asset("dagre.min.js")
    explorer = asset("explorer.js")
    license_text = asset("LICENSE.dagre.txt")
    if "--" in license_text:
        raise ValueError("LICENSE.dagre.txt cannot go into an HTML comment")
    csp = ("default-src 'none'; "
           f"script-src {_sha256(dagre)} {_sha256(explorer)}; "
           "style-src 'unsafe-inline'; img-src data:; base-uri 'none'; form-action 'none'")
    data = explorer_data(hpn, net, program, figures, playback, series)
    return _env().get_template("explorer.html.j2").render(
        version=__version__, spec=spec, system=hpn.system, csp=csp,
        css=_inline(asset("explorer.css"), "style"),
        data=_inline(script_json(data), "script"),
        dagre_license=license_text, dagre=_inline(dagre, "script"),
        explorer=_inline(explorer, "script"),
    )


def index_rows(hpn: HPN, figures: dict[str, str]) -> list[IndexRow]:
    rows: list[IndexRow] = []
    for page in pages_in_order(hpn):
        depth = 0
        parent = page.parent
        while parent is not None:
            depth += 1
            parent = hpn.pages[parent].parent
        layer = "device" if page.layer == 0 else (
            f"{page.layer}.{page.sublayer}" if page.sublayer else str(page.layer))
        rows.append(IndexRow(layer, depth, page.id, page.label, figures.get(page.id)))
    return rows


def render_index(hpn: HPN, spec: str, figures: dict[str, str], explorer: str | None,
                 missing: str | None) -> str:
    """index.html: every page with its layer and its figure's file (page id -> file name)."""
    return _env().get_template("index.html.j2").render(
        version=__version__, spec=spec, system=hpn.system, explorer=explorer,
        rows=index_rows(hpn, figures), missing=missing,
    )
