"""The documentation cites only what a user of the repository has.

For README.md, docs/*.md and the editors' READMEs:

(a) every relative path a document cites exists: the targets of markdown links (relative to
    the document, as GitHub resolves them) and the repository paths in inline code (a word
    starting with ``rssm_dsl/``, ``examples/``, ``tests/``, ... relative to the repository
    root), with ``#anchor`` and ``:line`` suffixes stripped; ``*`` and ``<placeholder>`` match
    as a glob;
(b) no document mentions files or notes a user does not have: a design file outside the
    repository, ``shared/``, an issue note;
(c) a link to ``X.md#anchor`` (or ``#anchor`` in the same document) names a heading of X
    (GitHub's slug: lowercase, punctuation dropped except ``-`` and ``_``, spaces to ``-``,
    ``-1``, ``-2`` for repeated headings) or an explicit ``<a id="anchor">``.

(d) Rule (b) also holds for the text (docstrings and comments) of every module of rssm_dsl/,
    rssm_core/ and bench/, and for the ROS 2 templates, whose text ends up in generated code.

Each failure names the document and the bad citation.
"""

from __future__ import annotations

import re
from functools import cache
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]

PREFIXES = ("rssm_dsl/", "rssm_core/", "examples/", "bench/", "tests/", "docs/", "editors/",
            "grammar/", "stdlib/", ".ci/")
# files and notes a user of the repository does not have
FORBIDDEN = re.compile(r"DESIGN\.md|shared/|issue notes?", re.IGNORECASE)

FENCE = re.compile(r"^ {0,3}(```|~~~).*?^ {0,3}\1[^\n]*$", re.MULTILINE | re.DOTALL)
LINK = re.compile(r"!?\[(?:[^\]\\]|\\.)*\]\(\s*<?([^)\s>]+)>?(?:\s+\"[^\"]*\")?\s*\)")
CODE = re.compile(r"(`+)(.+?)\1", re.DOTALL)
HEADING = re.compile(r"^ {0,3}(#{1,6})\s+(.*?)\s*#*\s*$", re.MULTILINE)
HTML_ANCHOR = re.compile(r"<a\s+(?:id|name)=\"([^\"]+)\"", re.IGNORECASE)
LINE_SUFFIX = re.compile(r"(?::\d+)+$")
PLACEHOLDER = re.compile(r"<[^<>/]*>|\{[^{}/]*\}")


def documents() -> list[Path]:
    docs = [ROOT / "README.md", *sorted((ROOT / "docs").glob("*.md"))]
    docs += sorted(p for p in (ROOT / "editors").rglob("README.md")
                   if "node_modules" not in p.relative_to(ROOT).parts)
    return [p for p in docs if p.is_file()]


DOCUMENTS = documents()


def _id(path: Path) -> str:
    return path.relative_to(ROOT).as_posix()


def prose(text: str) -> str:
    """The text without its fenced code blocks (a link or a path there is not a citation)."""
    return FENCE.sub("", text)


def links(text: str) -> list[str]:
    return [m.group(1) for m in LINK.finditer(prose(text))]


def code_paths(text: str) -> list[str]:
    """The words of inline code that look like repository paths."""
    found = []
    for m in CODE.finditer(prose(text)):
        for word in m.group(2).split():
            word = word.strip("'\"(),;")
            if word.startswith(PREFIXES):
                found.append(word)
    return found


def _plain(target: str) -> str:
    """A cited path without its anchor, ``:line`` suffix and trailing punctuation."""
    path = target.split("#", 1)[0].split("?", 1)[0]
    path = path.rstrip(".,;:")
    return LINE_SUFFIX.sub("", path)


def exists(base: Path, path: str) -> bool:
    pattern = PLACEHOLDER.sub("*", path)
    if "*" in pattern:
        try:
            rel = (base / pattern.rstrip("/")).resolve().relative_to(ROOT)
        except ValueError:
            return False
        return any(ROOT.glob(rel.as_posix()))
    return (base / path).exists()


def is_external(target: str) -> bool:
    return bool(re.match(r"^[a-zA-Z][a-zA-Z0-9+.-]*:", target))


def slug(heading: str) -> str:
    text = re.sub(r"!?\[([^\]]*)\]\([^)]*\)", r"\1", heading)      # a link: its text
    text = re.sub(r"<[^>]+>", "", text)                             # inline HTML
    text = text.replace("`", "").strip().lower()
    text = re.sub(r"[^\w\- ]", "", text)
    return text.replace(" ", "-")


@cache
def anchors(path: Path) -> frozenset[str]:
    """The anchors GitHub gives the headings of ``path``, and its explicit ``<a id>``s."""
    text = path.read_text(encoding="utf-8")
    seen: dict[str, int] = {}
    out: set[str] = set(HTML_ANCHOR.findall(text))
    for m in HEADING.finditer(prose(text)):
        base = slug(m.group(2))
        n = seen.get(base, 0)
        seen[base] = n + 1
        out.add(base if n == 0 else f"{base}-{n}")
    return frozenset(out)


@pytest.mark.parametrize("doc", DOCUMENTS, ids=_id)
def test_cited_paths_exist(doc: Path) -> None:
    text = doc.read_text(encoding="utf-8")
    bad = []
    for target in links(text):
        if is_external(target) or target.startswith("#"):
            continue
        path = _plain(target)
        if path and not exists(doc.parent, path):
            bad.append(f"link ({target})")
    for word in code_paths(text):
        path = _plain(word)
        if path and not exists(ROOT, path):
            bad.append(f"`{word}`")
    assert not bad, f"{_id(doc)} cites paths that do not exist: {', '.join(bad)}"


@pytest.mark.parametrize("doc", DOCUMENTS, ids=_id)
def test_no_files_or_notes_users_lack(doc: Path) -> None:
    bad = [f"line {n}: {line.strip()}"
           for n, line in enumerate(doc.read_text(encoding="utf-8").splitlines(), 1)
           if FORBIDDEN.search(line)]
    assert not bad, f"{_id(doc)} cites what users do not have:\n" + "\n".join(bad)


@pytest.mark.parametrize("doc", DOCUMENTS, ids=_id)
def test_link_anchors_are_headings(doc: Path) -> None:
    text = doc.read_text(encoding="utf-8")
    bad = []
    for target in links(text):
        if is_external(target) or "#" not in target:
            continue
        path, _, anchor = target.partition("#")
        file = doc if not path else (doc.parent / path)
        if file.suffix != ".md" or not file.is_file():
            continue                      # a missing file is test_cited_paths_exist's report
        if anchor not in anchors(file.resolve()):
            bad.append(target)
    assert not bad, f"{_id(doc)} links to anchors that are no heading: {', '.join(bad)}"


def sources() -> list[Path]:
    files = []
    for top in ("rssm_dsl", "rssm_core", "bench"):
        for p in sorted((ROOT / top).rglob("*")):
            if (p.is_file() and "__pycache__" not in p.parts
                    and (p.suffix in (".py", ".md", ".txt") or p.name.endswith(".j2"))):
                files.append(p)
    return files


@pytest.mark.parametrize("top", ["rssm_dsl", "rssm_core", "bench"])
def test_modules_cite_no_files_or_notes_users_lack(top: str) -> None:
    bad = []
    for path in sources():
        if path.relative_to(ROOT).parts[0] != top:
            continue
        for n, line in enumerate(path.read_text(encoding="utf-8").splitlines(), 1):
            if FORBIDDEN.search(line):
                bad.append(f"{_id(path)}:{n}: {line.strip()}")
    assert not bad, "modules cite what users do not have:\n" + "\n".join(bad)


def test_the_checks_see_what_they_check() -> None:
    """Not vacuous: the documents cite paths and anchors, and the rules catch a bad one."""
    assert len(DOCUMENTS) >= 8
    cited = [w for d in DOCUMENTS for w in code_paths(d.read_text(encoding="utf-8"))]
    assert len(cited) > 50
    assert any("#" in t for d in DOCUMENTS for t in links(d.read_text(encoding="utf-8")))
    assert not exists(ROOT, "rssm_dsl/no_such_module.py")
    assert exists(ROOT, "examples/verify/*.rssm") and exists(ROOT, "tests/golden/ros2/<spec>")
    assert code_paths("see `rssm_dsl/x.py:12` and `python bench/y.py --n 3`") == [
        "rssm_dsl/x.py:12", "bench/y.py"]
    assert _plain("docs/verify.md#how-values-are-tracked") == "docs/verify.md"
    assert _plain("rssm_dsl/x.py:12:3") == "rssm_dsl/x.py"
    assert slug("How new(x) is tracked") == "how-newx-is-tracked"
    assert slug("Cross-checks (`--cross-check`)") == "cross-checks---cross-check"
    assert slug("`rssmc render`: see the net") == "rssmc-render-see-the-net"
    assert "how-newx-is-tracked" in anchors(ROOT / "docs" / "verify.md")
    assert "e620" in anchors(ROOT / "docs" / "diagnostics.md")
    assert FORBIDDEN.search("see ../" + "shared/DESIGN" + ".md section 4")
    assert FORBIDDEN.search("the Issue " + "Note says")
    assert links("[a](x.md#b)\n```\n[c](y.md)\n```\n") == ["x.md#b"]
