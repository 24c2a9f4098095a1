"""The repository's own specifications are in the canonical layout (`rssmc fmt --check
examples stdlib` finds nothing to change), and the one-line rule of the formatter: a block
written on one line stays on one line when it holds one declaration, statement or member list
and fits in LINE_LENGTH columns; any other block is laid out on lines."""

from __future__ import annotations

import re
from pathlib import Path

import pytest

from rssm_dsl.pipeline import compile_file
from rssm_dsl.syntax.format import LINE_LENGTH, format_text
from tests.format.test_format import _comments, _diagnostics, _ir

ROOT = Path(__file__).resolve().parents[2]
SHIPPED = sorted(p for folder in ("examples", "stdlib") for p in (ROOT / folder).rglob("*.rssm"))
SPECS = sorted(p for folder in ("examples", "stdlib", "tests") for p in (ROOT / folder).rglob(
    "*.rssm"))
# the examples of syntax errors: the formatter reports them and leaves them as they are
SYNTAX_ERRORS = frozenset({"E005", "E006", "E007", "E008", "E013"})


def _fmt(text: str) -> str:
    result = format_text(text)
    assert result.text is not None, result.diagnostics
    return result.text


def _id(p: Path) -> str:
    return str(p.relative_to(ROOT))


def test_there_are_examples_and_stdlib_modules() -> None:
    assert ROOT / "examples" / "lwr4_circle.rssm" in SHIPPED
    assert any(p.is_relative_to(ROOT / "stdlib") for p in SHIPPED)


@pytest.mark.parametrize("path", SHIPPED, ids=_id)
def test_the_shipped_specification_is_formatted(path: Path) -> None:
    text = path.read_text(encoding="utf-8")
    result = format_text(text, str(path))
    if result.text is None:      # examples/diagnostics/E005 ...: syntax errors on purpose
        assert {d.code for d in result.diagnostics} <= SYNTAX_ERRORS, result.diagnostics
        assert path.parent == ROOT / "examples" / "diagnostics"
        return
    assert result.text == text, f"`rssmc fmt {_id(path)}` would reformat it"


# ------------------------------------------------------------------ the one-line rule

def _system(body: str, indent: str = "      ") -> str:
    """A one-subsystem system around the lines of `body` (given at the subsystem's depth)."""
    lines = "".join(indent + line + "\n" for line in body.splitlines())
    return ("system s {\n  agent a {\n    control @ 10 Hz {\n"
            f"{lines}    }}\n  }}\n}}\n")


def test_a_one_line_enum_stays_on_one_line() -> None:
    text = "enum Cmd { stay, job, charge }\n"
    assert _fmt(text) == text
    assert _fmt("enum   Cmd{stay ,job,charge}\n") == text


def test_a_several_line_enum_stays_on_several_lines() -> None:
    text = "enum Cmd {\n  stay, job, charge\n}\n"
    assert _fmt(text) == text
    assert _fmt("enum Cmd { stay, job,\n charge }\n") == "enum Cmd {\n  stay, job,\n  charge\n}\n"


def test_a_one_line_record_and_an_empty_block_stay() -> None:
    text = "record Pose { position: float[3], yaw: float }  // cell frame\nenum Bin { }\n"
    assert _fmt(text) == text
    assert _fmt("record Pose {position: float[3],yaw: float}\n") == (
        "record Pose { position: float[3], yaw: float }\n")


def test_a_one_line_update_stays_and_a_several_line_one_stays_expanded() -> None:
    one = _system("memory m: int = 0\nbehaviour b {\n  update memory { m := m + 1 }\n"
                  "  terminal never when false\n}\ninitial b")
    assert _fmt(one) == one
    several = one.replace("update memory { m := m + 1 }",
                          "update memory {\n          m := m + 1\n        }")
    assert _fmt(several) == several


def test_a_one_line_behaviour_stays() -> None:
    text = _system("behaviour b { terminal never when false }\ninitial b")
    assert _fmt(text) == text


def _update_of_width(width: int) -> tuple[str, str]:
    """A system whose one-line `update memory { v := 0 }` line is `width` columns wide (the
    memory's name `v` made as long as needed), and that name."""
    name = "v" * (width - len("        update memory {  := 0 }"))
    line = f"  update memory {{ {name} := 0 }}"
    assert len("      " + line) == width
    return _system(f"memory {name}: int = 0\nbehaviour b {{\n{line}\n"
                   "  terminal never when false\n}\ninitial b"), name


def test_a_one_line_block_that_fits_exactly_stays() -> None:
    text, _ = _update_of_width(LINE_LENGTH)
    assert _fmt(text) == text


def test_a_one_line_block_too_long_is_split() -> None:
    text, name = _update_of_width(LINE_LENGTH + 1)
    formatted = _fmt(text)
    assert formatted == text.replace(f"update memory {{ {name} := 0 }}",
                                     f"update memory {{\n          {name} := 0\n        }}")
    assert _fmt(formatted) == formatted
    assert max(len(line) for line in formatted.splitlines()) <= LINE_LENGTH


def test_a_trailing_comment_does_not_count_in_the_width() -> None:
    text, _ = _update_of_width(LINE_LENGTH)
    text = text.replace(" := 0 }\n", " := 0 }  // " + "x" * 40 + "\n", 1)
    assert _fmt(text) == text


def test_a_long_one_line_enum_is_split_into_the_canonical_layout() -> None:
    members = ", ".join(f"member_{i}" for i in range(12))
    text = f"enum Many {{ {members} }}\n"
    assert len(text) > LINE_LENGTH
    assert _fmt(text) == f"enum Many {{\n  {members}\n}}\n"


@pytest.mark.parametrize("inner", [
    "m := 1 n := 2",                                # two statements
    "case new(i): m := i otherwise: skip",          # case labels
    "let k = 2 m := k",                             # a let and a statement
])
def test_a_one_line_block_of_several_statements_is_laid_out_on_lines(inner: str) -> None:
    text = _system(f"input i: int from e.x\nmemory m: int = 0\nmemory n: int = 0\n"
                   f"behaviour b {{\n  update memory {{ {inner} }}\n"
                   "  terminal never when false\n}\ninitial b")
    formatted = _fmt(text)
    assert "update memory {\n" in formatted
    assert _fmt(formatted) == formatted


def test_a_one_line_block_holding_a_block_is_split_and_the_inner_one_kept() -> None:
    text = _system("memory m: int = 0\n"
                   "behaviour b { update memory { m := m + 1 } terminal never when false }\n"
                   "initial b")
    want = _system("memory m: int = 0\nbehaviour b {\n  update memory { m := m + 1 }\n"
                   "  terminal never when false\n}\ninitial b")
    assert _fmt(text) == want
    assert _fmt(want) == want


def test_a_one_line_block_with_a_comment_inside_is_laid_out_on_lines() -> None:
    text = "enum Cmd { stay, /* idle */ job }\n"
    assert _fmt(text) == "enum Cmd {\n  stay, /* idle */ job\n}\n"


# ------------------------------------------------------------------ idempotence

_EXPANDED = re.compile(r"\{\n[ \t]*([^\n{}]*[^\n{} ])\n[ \t]*\}")


def _collapsed(text: str) -> str:
    """Every block the formatter printed as `{`, one line, `}` written on one line."""
    def join(m: re.Match[str]) -> str:
        inner = m.group(1)
        return m.group(0) if "//" in inner or "/*" in inner else "{ " + inner + " }"

    return _EXPANDED.sub(join, text)


@pytest.mark.parametrize("path", SPECS, ids=_id)
def test_formatting_is_idempotent_with_blocks_written_on_one_line(path: Path) -> None:
    """fmt(fmt(x)) == fmt(x) for every spec of the repository, as written and with every
    one-statement block joined on one line (kept where it fits, split again where not), the
    comments and the IR unchanged."""
    text = path.read_text(encoding="utf-8")
    first = format_text(text, str(path)).text
    if first is None:
        return                  # syntax errors: see test_the_shipped_specification_is_formatted
    assert format_text(first, str(path)).text == first
    joined = _collapsed(first)
    formatted = format_text(joined, str(path)).text
    assert formatted is not None
    assert format_text(formatted, str(path)).text == formatted
    assert _comments(formatted) == _comments(text)
    for line_text in formatted.splitlines():   # a kept one-line block fits
        code = line_text.split("//")[0].rstrip()
        if code.endswith("}") and "{ " in code and len(code) > LINE_LENGTH:
            pytest.fail(f"one-line block over {LINE_LENGTH} columns: {line_text!r}")
    before = compile_file(path)
    after = compile_file(path, overrides={path.resolve(): formatted})
    if before.hpn is not None:
        assert after.hpn is not None
        assert _ir(after) == _ir(before)
    else:
        assert [c for c, _ in _diagnostics(after)] == [c for c, _ in _diagnostics(before)]
