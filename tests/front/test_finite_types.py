"""Enumerations and bounded integers (ranges) in the front end: their syntax (and the lexing
of `..` next to floats), their types, the operators they take, and their diagnostics (each
code also has its example in examples/diagnostics/)."""

from __future__ import annotations

from pathlib import Path

import pytest

from rssm_dsl.diagnostics import DiagnosticBag
from rssm_dsl.pipeline import Compilation, compile_file
from rssm_dsl.semantics.typecheck import ExprChecker, Scope, Symbol
from rssm_dsl.semantics.types import INT, EnumT, RangeT
from rssm_dsl.source import SourceFile
from rssm_dsl.syntax import ast
from rssm_dsl.syntax.format import format_text
from rssm_dsl.syntax.parser import parse
from rssm_dsl.syntax.printer import type_text


def _module(text: str) -> ast.Module:
    result = parse(SourceFile("<t>", text))
    assert result.diagnostics == () and result.module is not None, result.diagnostics
    return result.module


# ---------------------------------------------------------------- syntax


def test_enum_declarations() -> None:
    m = _module("enum Phase { idle, approach, grasp, }\nenum One { only }\nenum None_ { }\n")
    phase, one, empty = m.decls
    assert isinstance(phase, ast.EnumDecl) and phase.name == "Phase"
    assert [x.name for x in phase.members] == ["idle", "approach", "grasp"]
    assert isinstance(one, ast.EnumDecl) and [x.name for x in one.members] == ["only"]
    assert isinstance(empty, ast.EnumDecl) and empty.members == ()   # E210, not a syntax error


@pytest.mark.parametrize(("written", "lo", "hi"), [
    ("0..3", 0, 3), ("-5..5", -5, 5), ("-9..-2", -9, -2), ("0 .. 11", 0, 11), ("7..7", 7, 7),
])
def test_range_types(written: str, lo: int, hi: int) -> None:
    [alias] = _module(f"type T = {written}\n").decls
    assert isinstance(alias, ast.AliasDecl)
    assert alias.type == ast.RangeType(alias.type.span, lo, hi)
    assert type_text(alias.type) == f"{lo}..{hi}"


def test_an_array_of_ranges() -> None:
    [rec] = _module("record R { slots: 0..11[4] }\n").decls
    assert isinstance(rec, ast.RecordDecl)
    t = rec.fields[0].type
    assert isinstance(t, ast.ArrayType) and t.size == 4
    assert isinstance(t.element, ast.RangeType) and (t.element.lo, t.element.hi) == (0, 11)


@pytest.mark.parametrize(("text", "value"), [
    ("1.", 1.0), (".5", 0.5), ("1.5e3", 1500.0), ("2.e3", 2000.0), ("1e-3", 0.001),
    ("6.02E23", 6.02e23), ("0.25", 0.25), ("3", 3),
])
def test_numbers_still_lex_as_before(text: str, value: float) -> None:
    [const] = _module(f"const c = {text}\n").decls
    assert isinstance(const, ast.ConstDecl) and isinstance(const.value, ast.Literal)
    assert const.value.value == value and type(const.value.value) is type(value)


def test_dot_dot_is_not_part_of_a_float() -> None:
    """`0..3` is INT `..` INT: the float `0.` would swallow the first dot."""
    [alias] = _module("type T = 0..3\n").decls
    assert isinstance(alias, ast.AliasDecl) and isinstance(alias.type, ast.RangeType)
    assert parse(SourceFile("<t>", "const c = 0..3\n")).diagnostics   # no range value


def test_enum_is_a_keyword() -> None:
    assert parse(SourceFile("<t>", "const enum = 1\n")).diagnostics


def test_the_formatter_prints_the_new_syntax_back() -> None:
    text = ("enum Phase {idle,approach ,\ngrasp,}\ntype Slot = 0 .. 11\n"
            "record R { a : - 5..-1 , b: 0..3 [2] }\nconst c = 1. + .5\n")
    result = format_text(text)
    # the enum was written on two lines and stays expanded; the record on one line stays
    assert result.text == ("enum Phase {\n  idle, approach,\n  grasp,\n}\n"
                           "type Slot = 0..11\nrecord R { a: -5..-1, b: 0..3[2] }\n"
                           "const c = 1. + .5\n")
    assert format_text(result.text).text == result.text


# ---------------------------------------------------------------- types and diagnostics


def _compile(tmp_path: Path, decls: str, memory: str, body: str,
             terminal: str = "false", files: dict[str, str] | None = None) -> Compilation:
    for name, text in (files or {}).items():
        (tmp_path / name).write_text(text, encoding="utf-8")
    path = tmp_path / "spec.rssm"
    path.write_text(f"""{decls}
system s {{
  agent a1 {{
    control c {{
{memory}
      behaviour b {{
        update memory {{
{body}
        }}
        terminal t when {terminal}
      }}
      initial b
      switch b -> end when t
    }}
  }}
}}
""", encoding="utf-8")
    return compile_file(path)


def _codes(comp: Compilation) -> list[str]:
    return [d.code for d in comp.diagnostics if d.code[0] == "E"]


PHASE = "enum Phase { idle, approach, grasp, release }"


def test_enums_and_ranges_type_check(tmp_path: Path) -> None:
    comp = _compile(
        tmp_path, PHASE + "\ntype Slot = 0..11\nrecord Grip { phase: Phase, slot: Slot }\n"
        "const first: Phase = Phase.idle\nconst k: 0..3 = 2\n"
        "extern next_phase(p: Phase, n: 0..9) -> Phase = \"ops:next_phase\"",
        "      memory phase: Phase = first\n      memory slot: Slot = k\n"
        "      memory grip: Grip = {phase: Phase.grasp, slot: 3}\n"
        "      memory ring: Phase[3] = [Phase.idle, Phase.grasp, Phase.idle]\n"
        "      memory n: int = 0\n      memory x: float = 0.0",
        "          phase := if slot > 3 then Phase.release else next_phase(phase, slot)\n"
        "          slot := (slot + 1) % 12\n"
        "          n := slot * 2 - abs(slot) + min(slot, 3)\n"
        "          x := slot / 2 + slot\n"
        "          grip.slot := n\n"
        "          ring[slot % 3] := grip.phase",
        "phase == Phase.release and phase != first and ring[0] == Phase.idle and x >= 0.0")
    assert comp.ok, [str(d) for d in comp.diagnostics]
    assert comp.system is not None
    types = dict(comp.system.types)
    assert types["Phase"] == EnumT("Phase", ("idle", "approach", "grasp", "release"))
    assert types["Slot"] == RangeT(0, 11)


@pytest.mark.parametrize(("body", "code", "fragment"), [
    ("phase := Phase.grab", "E212", "enum Phase has no member 'grab'"),
    ("phase := Phase", "E103", "'Phase' is an enum type, not a value"),
    ("phase := 1", "E201", "cannot assign int to 'phase' of type Phase"),
    ("n := phase + 1", "E203", "'+' does not apply to Phase and int"),
    ("b := phase < Phase.grasp", "E203", "'<' compares numbers"),
    ("b := phase == 2", "E203", "cannot compare Phase with int"),
    ("b := phase == Light.red", "E203", "cannot compare Phase with Light"),
    ("slot := 2.5", "E201", "cannot assign float to 'slot' of type 0..3"),
    ("slot := 4", "E214", "value 4 is outside 0..3 of slot"),
    ("slot := -1", "E214", "value -1 is outside 0..3 of slot"),
    ("slot := 2 * 3 - 1", "E214", "value 5 is outside 0..3 of slot"),
    ("slot := if b then 9 else 0", "E214", "value 9 is outside 0..3 of slot"),
    ("phase := Phase.idle.x", "E207", "a value of type Phase has no fields"),
])
def test_enum_and_range_misuse(tmp_path: Path, body: str, code: str, fragment: str) -> None:
    comp = _compile(tmp_path, PHASE + "\nenum Light { red, green }",
                    "      memory phase: Phase\n      memory slot: 0..3\n"
                    "      memory n: int\n      memory b: bool",
                    f"          {body}", "phase == Phase.idle and slot > n and b")
    assert _codes(comp) == [code], [str(d) for d in comp.diagnostics]
    assert fragment in comp.diagnostics[[d.code for d in comp.diagnostics].index(code)].message


def test_arithmetic_on_a_range_is_an_int() -> None:
    span = SourceFile("<t>", "").span(0, 0)
    scope = Scope({"slot": Symbol("memory", RangeT(0, 3), span)}, {})
    checker = ExprChecker(DiagnosticBag())
    for text, want in (("slot", RangeT(0, 3)), ("slot + 1", INT), ("-slot", INT),
                       ("abs(slot)", INT), ("if true then slot else 2", INT),
                       ("if true then slot else slot", RangeT(0, 3))):
        [const] = _module(f"const c = {text}\n").decls
        assert isinstance(const, ast.ConstDecl)
        assert checker.check(const.value, scope) == want, text


@pytest.mark.parametrize(("decls", "code"), [
    ("enum E { }", "E210"),
    ("enum E { a, b, a }", "E211"),
    ("type R = 3..1", "E213"),
    ("const k: 0..3 = 7", "E214"),
    ("record P { s: 0..3 }\nconst p: P = {s: 4}", "E214"),
    ("const a: 0..3[2] = [1, 5]", "E214"),
    ("enum E { a }\nenum E { b }", "E101"),
])
def test_declaration_diagnostics(tmp_path: Path, decls: str, code: str) -> None:
    comp = _compile(tmp_path, decls, "      memory n: int", "          n := n + 1", "n > 3")
    assert _codes(comp) == [code], [str(d) for d in comp.diagnostics]


def test_enums_and_ranges_are_imported_like_records(tmp_path: Path) -> None:
    comp = _compile(tmp_path, 'import "kinds.rssm"',
                    "      memory phase: Phase = Phase.grasp\n      memory slot: Slot = 11",
                    "          phase := Phase.idle\n          slot := slot - 1",
                    "phase == Phase.idle and slot < 3",
                    files={"kinds.rssm": PHASE + "\ntype Slot = 0..11\n"})
    assert comp.ok, [str(d) for d in comp.diagnostics]
    bad = _compile(tmp_path, 'import "kinds.rssm"', "      memory phase: Phase",
                   "          phase := Phase.gone", "phase == Phase.idle",
                   files={"kinds.rssm": PHASE})
    assert _codes(bad) == ["E212"]


def _switching(tmp_path: Path, switches: str) -> list[str]:
    path = tmp_path / "switch.rssm"
    path.write_text(PHASE + f"""
system s {{
  agent a1 {{
    control c {{
      memory phase: Phase
      behaviour a {{
        update memory {{ phase := Phase.grasp }}
        terminal t when true
      }}
      initial a
{switches}
    }}
  }}
}}
""", encoding="utf-8")
    return [d.code for d in compile_file(path).diagnostics]


def test_switching_on_the_members_of_an_enum(tmp_path: Path) -> None:
    """Comparisons of one value with members of its enum exclude each other (no W604), and
    cover every case when they name all the members (no E603)."""
    every = ("      switch a -> a when phase == Phase.idle\n"
             "      switch a -> a when Phase.approach == phase\n"
             "      switch a -> end when phase == Phase.grasp\n"
             "      switch a -> a when phase == Phase.release\n")
    assert _switching(tmp_path, every) == []
    some = ("      switch a -> a when phase == Phase.idle\n"
            "      switch a -> end when phase == Phase.grasp\n")
    assert _switching(tmp_path, some) == ["E603"]
    negated = ("      switch a -> a when phase != Phase.grasp\n"
               "      switch a -> end when phase == Phase.grasp\n")
    assert _switching(tmp_path, negated) == []


@pytest.mark.parametrize(("body", "advice"), [
    ("slot := 2.5", "no conversion from float to int"),     # float into a range
    ("n := 2.5", "no conversion from float to int"),        # float into an int
    ("b := slot", "write a condition"),                     # a number where a bool is
    ("b := phase", "write a condition"),                    # an enum where a bool is
    ("n := b", "a bool is not a number"),                   # a bool where a number is
    ("phase := 1", "a member `Type.member`"),               # a number where an enum is
])
def test_a_type_mismatch_says_what_to_write(tmp_path: Path, body: str, advice: str) -> None:
    """E201 carries a help line chosen by the two types (the acceptance trial of issue 32
    met an E201 with no advice)."""
    comp = _compile(tmp_path, PHASE, "      memory phase: Phase\n      memory slot: 0..3\n"
                    "      memory n: int\n      memory b: bool",
                    f"          {body}", "phase == Phase.idle and slot > n and b")
    (d,) = [d for d in comp.diagnostics if d.code == "E201"]
    assert d.hint is not None and advice in d.hint, d.hint


def test_did_you_mean_says_where_the_proposed_name_is_declared(tmp_path: Path) -> None:
    """A typo in the declaration makes every correct use an unknown name: "did you mean"
    proposes the misspelt declaration, so the hint says where it is and that the fix may be
    there (the acceptance trial of issue 32)."""
    comp = _compile(tmp_path, PHASE, "      memory stauts: 0..3\n      memory phase: Phase",
                    "          status := status + 1", "phase == Phase.idle")
    hints = [d.hint for d in comp.diagnostics if d.code == "E102"]
    assert len(hints) == 2, [str(d) for d in comp.diagnostics]     # the target and the read
    for h in hints:
        assert h is not None and "did you mean 'stauts'?" in h
        assert "memory 'stauts' is declared at line" in h and "correct it there" in h, h
