"""The documentation agrees with the compiler: docs/diagnostics.md documents exactly the codes
of the registry (same slugs and severities, with the anchors the JSON output links to), and
every complete ```rssm block of docs/language.md compiles with zero diagnostics."""

from __future__ import annotations

import re
from pathlib import Path

import pytest

from rssm_dsl.diagnostics.codes import CODES
from rssm_dsl.diagnostics.diagnostic import DOCS_URL
from rssm_dsl.diagnostics.render import render_text
from rssm_dsl.pipeline import compile_file
from tests.conftest import ROOT

DOCS = ROOT / "docs"
_HEADING = re.compile(r"^### ([A-Z]\d{3}) (\S+)\s*$", re.MULTILINE)
_ANCHOR = re.compile(r'^<a id="([a-z]\d{3})"></a>\s*$', re.MULTILINE)
_SEVERITY = re.compile(r"^\*\*Severity:\*\* (\w+)\s*$", re.MULTILINE)
_FENCE = re.compile(r"^```([^\n]*)\n(.*?)^```\s*$", re.MULTILINE | re.DOTALL)


def _sections(text: str) -> dict[str, tuple[str, str]]:
    """code -> (slug, the section's text up to the next heading)."""
    heads = list(_HEADING.finditer(text))
    out: dict[str, tuple[str, str]] = {}
    for i, h in enumerate(heads):
        end = heads[i + 1].start() if i + 1 < len(heads) else len(text)
        assert h.group(1) not in out, f"{h.group(1)} is documented twice"
        out[h.group(1)] = (h.group(2), text[h.end():end])
    return out


def test_diagnostics_doc_matches_the_registry() -> None:
    text = (DOCS / "diagnostics.md").read_text(encoding="utf-8")
    sections = _sections(text)
    documented = {code: slug for code, (slug, _) in sections.items()}
    assert documented == {c.code: c.slug for c in CODES}
    for c in CODES:
        severities = _SEVERITY.findall(sections[c.code][1])
        assert severities == [c.severity.value], f"{c.code}: severity {severities}"


def test_every_code_has_the_anchor_the_json_links_to() -> None:
    text = (DOCS / "diagnostics.md").read_text(encoding="utf-8")
    anchors = _ANCHOR.findall(text)
    assert sorted(anchors) == sorted(c.code.lower() for c in CODES)
    # each anchor sits right before its heading
    for c in CODES:
        assert re.search(rf'<a id="{c.code.lower()}"></a>\s*\n### {c.code} ', text), c.code
    assert DOCS_URL.endswith("docs/diagnostics.md")


def _rssm_blocks(path: Path) -> list[tuple[int, str, str]]:
    """(line, info string, text) of every ```rssm block of a Markdown file."""
    text = path.read_text(encoding="utf-8")
    out = []
    for m in _FENCE.finditer(text):
        info = m.group(1).strip()
        if info.split()[:1] == ["rssm"]:
            out.append((text.count("\n", 0, m.start()) + 1, info, m.group(2)))
    return out


LANGUAGE_BLOCKS = _rssm_blocks(DOCS / "language.md")
COMPLETE = [(line, body) for line, info, body in LANGUAGE_BLOCKS if info == "rssm"]


def test_language_doc_has_examples() -> None:
    assert len(COMPLETE) >= 5
    infos = {info for _, info, _ in LANGUAGE_BLOCKS}
    assert infos <= {"rssm", "rssm fragment"}, f"unknown info strings: {infos}"


@pytest.mark.parametrize(("line", "body"), COMPLETE, ids=[f"line{n}" for n, _ in COMPLETE])
def test_language_example_compiles_clean(tmp_path: Path, line: int, body: str) -> None:
    spec = tmp_path / f"language_md_line{line}.rssm"
    spec.write_text(body, encoding="utf-8")
    comp = compile_file(spec)
    # the blocks bind devices to a robot's own modules (`my_robot.gripper:Jaw`), which are not
    # here: W218 says so, and nothing else may be reported
    assert not [d for d in comp.diagnostics if d.code != "W218"], (
        f"docs/language.md block at line {line}:\n"
        + render_text(comp.diagnostics, comp.program.line))
    assert comp.hpn is not None
