"""The explorer is one self-contained file; user text cannot escape its JSON block."""

from __future__ import annotations

import base64
import hashlib
import json
import re
from html.parser import HTMLParser
from pathlib import Path

from rssm_dsl.diagnostics import DiagnosticBag
from rssm_dsl.hpn.flatten import flatten
from rssm_dsl.pipeline import compile_file
from rssm_dsl.render.html import asset, render_explorer, render_index, script_json
from rssm_dsl.render.names import figure_files
from rssm_dsl.render.playback import load_playback
from tests.render.support import LWR4, lwr4, lwr4_net, random_run, write_trace

EVIL = '</script><script>window.__pwned = 1</script><img src=x onerror="window.__pwned=2">'


class _Scripts(HTMLParser):
    """Collects the <script> elements as a browser's tokenizer splits them."""

    def __init__(self) -> None:
        super().__init__()
        self.scripts: list[tuple[dict[str, str | None], str]] = []
        self.tags: list[str] = []
        self._attrs: dict[str, str | None] | None = None

    def handle_starttag(self, tag: str, attrs: list[tuple[str, str | None]]) -> None:
        self.tags.append(tag)
        if tag == "script":
            self._attrs = dict(attrs)
            self.scripts.append((self._attrs, ""))

    def handle_data(self, data: str) -> None:
        if self._attrs is not None:
            attrs, text = self.scripts[-1]
            self.scripts[-1] = (attrs, text + data)

    def handle_endtag(self, tag: str) -> None:
        if tag == "script":
            self._attrs = None


def _parse(html: str) -> _Scripts:
    p = _Scripts()
    p.feed(html)
    return p


def test_script_json_cannot_close_the_script() -> None:
    text = script_json({"a": EVIL, "b": "x\u2028y & <!-- z"})
    assert "<" not in text and ">" not in text and "&" not in text and "\u2028" not in text
    assert json.loads(text) == {"a": EVIL, "b": "x\u2028y & <!-- z"}


def _evil_spec(tmp_path: Path) -> Path:
    spec = tmp_path / "evil.rssm"
    spec.write_text(f"// {EVIL}\n/* {EVIL} */\n" + LWR4.read_text(), encoding="utf-8")
    return spec


def test_user_text_in_the_spec_stays_data(tmp_path: Path) -> None:
    comp = compile_file(_evil_spec(tmp_path))
    assert comp.ok and comp.hpn is not None
    html = render_explorer(comp.hpn, flatten(comp.hpn), comp.program, f"{EVIL}.rssm", {}, None)
    assert EVIL not in html
    assert "<img" not in html
    parsed = _parse(html)
    # exactly the JSON block and two scripts: the spec's text opened no element of its own
    assert [a.get("type") for a, _ in parsed.scripts] == ["application/json", None, None]
    data = json.loads(parsed.scripts[0][1])
    evil_file = next(f for f in data["sources"] if f.endswith("evil.rssm"))
    assert data["sources"][evil_file][0] == f"// {EVIL}"


def test_content_security_policy_allows_only_the_inlined_scripts() -> None:
    comp = lwr4()
    assert comp.hpn is not None
    html = render_explorer(comp.hpn, lwr4_net(), comp.program, "x.rssm", {}, None)
    csp = re.search(r'http-equiv="Content-Security-Policy" content="([^"]*)"', html)
    assert csp is not None
    policy = csp.group(1).replace("&#39;", "'")
    assert "default-src 'none'" in policy and "unsafe-inline" not in policy.split(";")[1]
    hashes = set(re.findall(r"'sha256-([^']+)'", policy))
    scripts = [text for attrs, text in _parse(html).scripts if attrs.get("type") is None]
    assert scripts == [asset("dagre.min.js"), asset("explorer.js")]
    assert hashes == {base64.b64encode(hashlib.sha256(s.encode()).digest()).decode()
                      for s in scripts}
    # nothing that would load from elsewhere
    assert not re.search(r"""(src|href)=["']?(https?:)?//""", html)
    assert "sourceMappingURL" not in html


def test_explorer_embeds_ir_flat_net_sources_and_playback(tmp_path: Path) -> None:
    comp = lwr4()
    hpn = comp.hpn
    assert hpn is not None
    net = lwr4_net()
    names = random_run(net, 50, seed=2)
    bag = DiagnosticBag()
    pb = load_playback(write_trace(tmp_path / "t.jsonl", names), net, bag)
    files = figure_files(hpn)
    html = render_explorer(hpn, net, comp.program, "examples/lwr4_circle.rssm", files, pb)
    data = json.loads(_parse(html).scripts[0][1])
    assert data["format"] == "rssmc-explorer"
    assert {p["id"] for p in data["ir"]["pages"]} == set(hpn.pages)
    assert data["figures"]["P^B[1,lwr,move]"] == "fig-PB_1_lwr_move.svg"
    names_of = data["flat"]["names"]
    assert [names_of[t] for t in data["playback"]["fired"]] == names
    place_of = data["flat"]["place_of"]
    assert set(place_of) == set(hpn.places)
    # fused places are one flat place
    assert hpn.places["p[1,lwr,move,rcv,1,2]"].fusion == hpn.places["p[1,c,cw,snd,1,2]"].fusion
    assert place_of["p[1,lwr,move,rcv,1,2]"] == place_of["p[1,c,cw,snd,1,2]"]
    span = hpn.pages["P^B[1,lwr,move]"].span
    assert data["sources"][span.file][span.line - 1] == comp.program.line(span.file, span.line)
    assert any(f.startswith("<stdlib>/") for f in data["sources"])


def test_index_lists_every_page_with_its_file() -> None:
    hpn = lwr4().hpn
    assert hpn is not None
    files = figure_files(hpn)
    html = render_index(hpn, "examples/lwr4_circle.rssm", files, "lwr4_circle.html", None)
    for page_id, name in files.items():
        assert f'<a href="{name}">{name}</a>' in html
        assert f">{page_id}<" in html
    assert 'href="lwr4_circle.html"' in html
    missing = render_index(hpn, "x", {}, None, "Graphviz `dot` is not installed")
    assert "No figures were drawn" in missing and ".svg" not in missing


def test_the_vendored_layout_library_is_the_locked_npm_package() -> None:
    lock = json.loads(asset("package-lock.json"))
    version = lock["packages"]["node_modules/@dagrejs/dagre"]["version"]
    assert json.loads(asset("package.json"))["dependencies"]["@dagrejs/dagre"] == version
    js = asset("dagre.min.js")
    assert f'"{version}"' in js and "sourceMappingURL" not in js
    licence = asset("LICENSE.dagre.txt")
    assert f"@dagrejs/dagre {version}" in licence and "Permission is hereby granted" in licence
