"""The canonical formatter: idempotent, keeps every comment, changes no IR."""

from __future__ import annotations

import re
import shutil
import subprocess
import sys
from pathlib import Path

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from rssm_dsl.emit.dump import dump_text
from rssm_dsl.pipeline import Compilation, compile_file
from rssm_dsl.syntax.format import _lex, format_text, keywords

ROOT = Path(__file__).resolve().parents[2]
SPECS = sorted(p for folder in ("examples", "stdlib", "tests") for p in (ROOT / folder).rglob(
    "*.rssm"))
EXAMPLE = ROOT / "tests" / "lsp" / "data" / "circle.rssm"
_AT = re.compile(r"@\S+:\d+")


def _comments(text: str) -> list[str]:
    return [str(t) for t in _lex(text) if t.type in ("COMMENT", "BLOCK_COMMENT")]


def _ir(comp: Compilation) -> str:
    """The IR dump with spans stripped (formatting moves text between lines)."""
    assert comp.hpn is not None
    return _AT.sub("@", dump_text(comp.hpn))


def _diagnostics(comp: Compilation) -> list[tuple[str, str]]:
    return [(d.code, d.message) for d in comp.diagnostics]


def test_there_are_specs_to_format() -> None:
    assert EXAMPLE in SPECS and ROOT / "examples" / "lwr4_circle.rssm" in SPECS


@pytest.mark.parametrize("path", SPECS, ids=lambda p: str(p.relative_to(ROOT)))
def test_formatting_keeps_comments_and_ir_and_is_idempotent(path: Path) -> None:
    text = path.read_text(encoding="utf-8")
    result = format_text(text, str(path))
    if result.text is None:   # a spec with syntax errors (examples/diagnostics): untouched
        assert result.diagnostics
        assert all(d.code in ("E005", "E006", "E007", "E008", "E013") for d in result.diagnostics)
        return
    formatted = result.text
    assert format_text(formatted, str(path)).text == formatted
    assert _comments(formatted) == _comments(text)
    before = compile_file(path)
    after = compile_file(path, overrides={path.resolve(): formatted})
    if before.hpn is not None:
        assert after.hpn is not None
        assert _ir(after) == _ir(before)
    else:
        assert [c for c, _ in _diagnostics(after)] == [c for c, _ in _diagnostics(before)]


def test_the_test_suites_copy_of_the_example_is_formatted() -> None:
    path = ROOT / "tests" / "lsp" / "data" / "circle.rssm"
    text = path.read_text(encoding="utf-8")
    assert format_text(text, str(path)).text == text


def test_trailing_comments_of_consecutive_lines_are_aligned() -> None:
    text = ("record Blob {\n  visible: bool // seen?\n  x: float          // left to right\n"
            "\n  size: float // of the image\n}\n")
    assert format_text(text).text == (
        "record Blob {\n  visible: bool  // seen?\n  x: float       // left to right\n"
        "\n  size: float  // of the image\n}\n")


MESSY = """

// héllo — a messy file 😀
import std.types
record R { a: float, b: int,
  c: float[3] }
const K : float=-2.5*(1+ 2)   // trailing
extern f(x:float,
y: R) -> float = "m.mod:fn"
system s { agent a1 { control c @ 100 Hz { param p: float = 1.0 memory m: R = {a: 1.0, b: 2,
c: [1.0,2.0, 3.0]}
 output o: float to e.x nonblocking
  behaviour b1 { update o { o := f(p,
  m) + -p * K } update memory { m.a := if p > 0 then - p else p }
 terminal t when m.a>=2.0 /* inline */ send o }


      initial b1
  switch b1 -> end otherwise
  }
  effector x { input i: float from c blocking
  behaviour mv { update memory { case new(i): skip
   otherwise : skip } terminal never when false receive i }
  initial mv } } }
/* block
   comment */
"""

CANONICAL = """// héllo — a messy file 😀
import std.types
record R {
  a: float,
  b: int,
  c: float[3]
}
const K: float = -2.5 * (1 + 2)  // trailing
extern f(x: float,
         y: R) -> float = "m.mod:fn"
system s {
  agent a1 {
    control c @ 100 Hz {
      param p: float = 1.0
      memory m: R = {a: 1.0, b: 2,
                     c: [1.0, 2.0, 3.0]}
      output o: float to e.x nonblocking
      behaviour b1 {
        update o {
          o := f(p,
                 m) + -p * K
        }
        update memory { m.a := if p > 0 then -p else p }
        terminal t when m.a >= 2.0 /* inline */
        send o
      }

      initial b1
      switch b1 -> end otherwise
    }
    effector x {
      input i: float from c blocking
      behaviour mv {
        update memory {
          case new(i):
            skip
          otherwise:
            skip
        }
        terminal never when false
        receive i
      }
      initial mv
    }
  }
}
/* block
   comment */
"""


def test_a_messy_file_gets_the_canonical_layout() -> None:
    result = format_text(MESSY)
    assert result.text == CANONICAL
    assert format_text(CANONICAL).text == CANONICAL


def test_continuation_lines_and_operators() -> None:
    text = ("const A: float = 1.0 +\n2.0\nconst B: bool = not true and\n"
            "(1 < 2 or\n3 >= 4)\nconst C: int = -(-3)\n")
    assert format_text(text).text == (
        "const A: float = 1.0 +\n    2.0\nconst B: bool = not true and\n"
        "    (1 < 2 or\n     3 >= 4)\nconst C: int = -(-3)\n")


def test_syntax_errors_are_reported_not_formatted() -> None:
    result = format_text("system s { agent a1 { control { behaviour b {")
    assert result.text is None
    assert [d.code for d in result.diagnostics] == ["E007"]


def test_keywords_come_from_the_grammar() -> None:
    assert {"system", "agent", "behaviour", "update", "otherwise", "nonblocking", "kHz",
            "and", "not"} <= keywords()
    assert "new" not in keywords()   # a built-in function, not a reserved word


# whitespace the formatter must see through: spaces, tabs, line breaks, blank lines
_GAPS = st.lists(st.sampled_from([" ", "  ", "\t", "\n", "\n\n", " \n   "]), min_size=400,
                 max_size=400)


@settings(max_examples=25, deadline=None)
@given(gaps=_GAPS)
def test_any_layout_of_the_example_formats_to_a_fixed_point_with_the_same_ir(
        gaps: list[str]) -> None:
    text = EXAMPLE.read_text(encoding="utf-8")
    tokens = [t for t in _lex(text) if t.type != "WS"]
    # re-join the tokens with arbitrary whitespace (a line comment still ends its line)
    pieces: list[str] = []
    for i, tok in enumerate(tokens):
        pieces.append(str(tok))
        gap = gaps[i % len(gaps)]
        pieces.append(gap if tok.type != "COMMENT" or "\n" in gap else "\n")
    shuffled = "".join(pieces)
    formatted = format_text(shuffled, str(EXAMPLE)).text
    assert formatted is not None
    assert format_text(formatted, str(EXAMPLE)).text == formatted
    assert _comments(formatted) == _comments(text)
    before = compile_file(EXAMPLE)
    after = compile_file(EXAMPLE, overrides={EXAMPLE.resolve(): formatted})
    assert _ir(after) == _ir(before)


def test_fmt_command_check_and_write(tmp_path: Path) -> None:
    messy = tmp_path / "messy.rssm"
    messy.write_text(MESSY, encoding="utf-8")
    clean = tmp_path / "clean.rssm"
    clean.write_text(CANONICAL, encoding="utf-8")
    broken = tmp_path / "broken.rssm"
    broken.write_text("system s {", encoding="utf-8")

    def rssmc(*args: str) -> subprocess.CompletedProcess[str]:
        return subprocess.run([sys.executable, "-m", "rssm_dsl", "fmt", *args],
                              capture_output=True, text=True, cwd=tmp_path, timeout=60)

    assert rssmc("--check", str(clean)).returncode == 0
    checked = rssmc("--check", str(messy), str(clean))
    assert checked.returncode == 1 and "messy.rssm: would be reformatted" in checked.stderr
    assert messy.read_text(encoding="utf-8") == MESSY          # --check writes nothing
    assert rssmc(str(messy)).returncode == 0
    assert messy.read_text(encoding="utf-8") == CANONICAL
    assert rssmc("--check", str(tmp_path / "messy.rssm")).returncode == 0
    failed = rssmc(str(broken))
    assert failed.returncode == 1 and "E007" in failed.stderr
    assert broken.read_text(encoding="utf-8") == "system s {"
    assert rssmc(str(tmp_path / "missing.rssm")).returncode == 2


def test_fmt_diff_shows_the_change_and_writes_nothing(tmp_path: Path) -> None:
    """`fmt --diff` prints a unified diff that turns the file into its formatted text,
    writes nothing, and exits as --check (the acceptance trial of issue 32: --check
    showed no change)."""
    messy = tmp_path / "messy.rssm"
    messy.write_text(MESSY, encoding="utf-8")
    clean = tmp_path / "clean.rssm"
    clean.write_text(CANONICAL, encoding="utf-8")
    run = subprocess.run([sys.executable, "-m", "rssm_dsl", "fmt", "--diff", str(messy),
                          str(clean)], capture_output=True, text=True, cwd=tmp_path, timeout=60)
    assert run.returncode == 1 and "messy.rssm: would be reformatted" in run.stderr
    assert messy.read_text(encoding="utf-8") == MESSY
    assert "clean.rssm" not in run.stdout              # an unchanged file shows nothing
    # the diff, applied to the file, gives the formatted text
    patch = shutil.which("patch")
    if patch is not None:
        applied = subprocess.run([patch, "-s", "-o", str(tmp_path / "out.rssm"), str(messy)],
                                 input=run.stdout, capture_output=True, text=True, timeout=60)
        assert applied.returncode == 0, applied.stderr
        assert (tmp_path / "out.rssm").read_text(encoding="utf-8") == CANONICAL
    removed = [ln[1:] for ln in run.stdout.splitlines(keepends=True)
               if ln.startswith("-") and not ln.startswith("---")]
    added = [ln[1:] for ln in run.stdout.splitlines(keepends=True)
             if ln.startswith("+") and not ln.startswith("+++")]
    assert removed and added
    assert all(line in MESSY.splitlines(keepends=True) for line in removed)
    assert all(line in CANONICAL.splitlines(keepends=True) for line in added)
    ok = subprocess.run([sys.executable, "-m", "rssm_dsl", "fmt", "--diff", str(clean)],
                        capture_output=True, text=True, cwd=tmp_path, timeout=60)
    assert ok.returncode == 0 and ok.stdout == ""


def test_bare_cr_line_ends_format_like_lf() -> None:
    """A bare CR ends a line (old Mac files), for the formatter as for the parser."""
    lf = "system s {\n  agent a {\n    control c @ 10 Hz {\n      // a comment\n" \
         "      behaviour b { terminal never when false }\n      initial b\n    }\n  }\n}\n"
    want = format_text(lf).text
    assert want is not None and "// a comment\n" in want
    assert format_text(lf.replace("\n", "\r")).text == want
    assert format_text(lf.replace("\n", "\r\n")).text == want
