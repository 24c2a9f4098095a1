"""Syntax errors with a hint that says what to write instead (issue "language server at
editor speed"): a Python-style conditional, a reserved word used as a name, and a rate
without its unit. Each is E005 at the token the parser could not take."""

from __future__ import annotations

import pytest

from rssm_dsl.diagnostics import Diagnostic
from rssm_dsl.source import SourceFile
from rssm_dsl.syntax.parser import parse


def only_error(text: str) -> Diagnostic:
    result = parse(SourceFile("t.rssm", text))
    assert len(result.diagnostics) == 1, [str(d) for d in result.diagnostics]
    return result.diagnostics[0]


def at(d: Diagnostic) -> tuple[str, int, int]:
    return d.code, d.span.line, d.span.column


def subsystem(body: str, rate: str = "@ 20 Hz") -> str:
    return ("system s {\n  agent a {\n"
            f"    control {rate} {{\n"
            f"{body}"
            "    }\n  }\n}\n")


UPDATE = ("      memory m: int = 0\n"
          "      behaviour b {\n"
          "        update memory {\n"
          "          m := {value}\n"
          "        }\n"
          "      }\n")


# ------------------------------------------------------------ `a if c else b`

@pytest.mark.parametrize(("value", "column"), [
    ("1 if m > 0 else 2", 18),
    ("(m + 1 if m > 0 else 2) * 3", 23),
])
def test_a_python_conditional_says_to_write_if_then_else(value: str, column: int) -> None:
    d = only_error(subsystem(UPDATE.replace("{value}", value)))
    assert at(d) == ("E005", 7, column)
    assert "'if' after a value" in d.message
    assert d.hint is not None and "if CONDITION then" in d.hint and "else" in d.hint


def test_the_hint_shows_the_value_in_its_place() -> None:
    d = only_error("const k: int = 1 if true else 2\n")
    assert at(d) == ("E005", 1, 18)
    assert d.hint == "write `if CONDITION then 1 else OTHER` (not `1 if CONDITION else OTHER`)"


def test_rssm_conditionals_are_not_errors() -> None:
    assert parse(SourceFile("t.rssm", "const k: int = if true then 1 else 2\n")).diagnostics == ()


# ------------------------------------------------------------ a reserved word as a name

def test_error_as_a_memory_name_says_it_is_reserved() -> None:
    d = only_error(subsystem("      memory error: int = 0\n"))
    assert at(d) == ("E005", 4, 14)
    assert "reserved word 'error'" in d.message
    assert d.hint is not None
    assert "'error' is a reserved word" in d.hint and "error NAME when" in d.hint
    assert "pick another name" in d.hint


@pytest.mark.parametrize(("text", "word", "line", "column"), [
    ("const if = 3\n", "if", 1, 7),
    ("const terminal: int = 3\n", "terminal", 1, 7),
    (subsystem("      param input: float = 1.0\n"), "input", 4, 13),
    (subsystem("      behaviour error {\n        terminal t when true\n      }\n"
               "      initial error\n"), "error", 4, 17),
    (subsystem(UPDATE.replace("{value}", "error + 1")), "error", 7, 16),
    (subsystem(UPDATE.replace("m := {value}", "error := 1")), "error", 7, 11),
])
def test_a_reserved_word_used_as_a_name(text: str, word: str, line: int, column: int) -> None:
    d = parse(SourceFile("t.rssm", text)).diagnostics[0]
    assert at(d) == ("E005", line, column)
    assert f"reserved word '{word}'" in d.message
    assert d.hint is not None and f"'{word}' is a reserved word" in d.hint
    assert "pick another name" in d.hint


def test_the_reserved_word_is_read_as_a_name_and_the_parse_goes_on() -> None:
    # one error, not a cascade: `error` is read as the name it was meant to be
    result = parse(SourceFile("t.rssm", "const error = 1\nconst k = 2\n"))
    assert [at(d) for d in result.diagnostics] == [("E005", 1, 7)]
    assert result.module is not None
    assert [d.name for d in result.module.decls] == ["error", "k"]  # type: ignore[union-attr]


def test_a_missing_name_before_a_keyword_gets_no_reserved_word_hint() -> None:
    # `switch b -> when t`: the target is missing; `when` is not meant as a name
    text = subsystem("      behaviour b {\n        terminal t when true\n      }\n"
                     "      initial b\n      switch b -> when t\n")
    d = parse(SourceFile("t.rssm", text)).diagnostics[0]
    assert at(d) == ("E005", 8, 19)
    assert "reserved word" not in d.message and d.hint is None


# ------------------------------------------------------------ a rate without its unit

def test_a_rate_without_its_unit_says_to_write_hz() -> None:
    d = only_error(subsystem("      memory m: int = 0\n", rate="@ 20"))
    assert at(d) == ("E005", 3, 18)
    assert "missing the unit of the rate 20" in d.message
    assert d.hint is not None and "`@ 20 Hz`" in d.hint and "kHz" in d.hint


@pytest.mark.parametrize(("text", "number", "line", "column"), [
    ('device effector Arm @ 100 {\n  binding "m:f"\n}\n', "100", 1, 27),
    (subsystem("", rate="c @ 2.5"), "2.5", 3, 21),
    ("system s {\n  agent a {\n    real effector arm: Arm @ 50\n  }\n}\n", "50", 4, 3),
])
def test_every_rate_needs_its_unit(text: str, number: str, line: int, column: int) -> None:
    d = only_error(text)
    assert at(d) == ("E005", line, column)
    assert d.hint is not None and f"`@ {number} Hz`" in d.hint


def test_a_unit_in_the_wrong_case_says_how_it_is_written() -> None:
    d = parse(SourceFile("t.rssm", subsystem("", rate="@ 20 hz"))).diagnostics[0]
    assert at(d) == ("E005", 3, 18)
    assert d.hint == "the unit of a rate is written `Hz`"
