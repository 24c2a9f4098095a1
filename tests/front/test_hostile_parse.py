"""Hostile input to the parser: the compiler never crashes, stalls or blows up.

1. syntax-error cascades stop after MAX_ERRORS reported errors (or MAX_RECOVERIES in all),
   with a last error saying so; the work per error is bounded (a run of stray characters is
   one error, an unclosed string skips its line, an unclosed block comment ends the file);
2. E008 is reported as soon as nesting passes 64 levels (brackets, the operators of a chain,
   `if`s), not after the parser has read a megabyte of it; it never refuses what the AST
   builder accepts, and what is accepted compiles, formats and runs at the deepest level;
3. a number literal the compiler cannot read is E013 at the literal (not E005 at 1:1);
4. int is 64-bit: a constant int outside [-2**63, 2**63 - 1] is E214 at the expression.

The time bounds are generous on purpose (they are what the tests are about: before, these
inputs took from 10 s to hours); bench/check_hostile.py measures the real figures.
"""

from __future__ import annotations

import time
from pathlib import Path

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from rssm_dsl.pipeline import Compilation, compile_file
from rssm_dsl.source import SourceFile
from rssm_dsl.syntax import parser
from rssm_dsl.syntax.build import MAX_DEPTH, MAX_INT_DIGITS, MAX_NUMBER_CHARS
from rssm_dsl.syntax.parser import MAX_ERRORS, MAX_RECOVERIES, ParseResult, parse
from tests.fuzz.measure import Run, rssmc

MB = 1_000_000
BOUND = 5.0   # seconds for a megabyte of anything (the goal)


def parsed(text: str) -> ParseResult:
    return parse(SourceFile("t.rssm", text))


def timed_parse(text: str) -> tuple[ParseResult, float]:
    start = time.perf_counter()
    result = parsed(text)
    return result, time.perf_counter() - start


def codes(result: ParseResult | Compilation) -> list[str]:
    return [d.code for d in result.diagnostics]


def errors(comp: Compilation) -> list[str]:
    return [d.code for d in comp.diagnostics if d.is_error]


def spec(extra: str = "", update: str = "m := m + 1") -> str:
    """A clean one-agent system with memory `m: int`; ``extra`` goes into the control
    subsystem, ``update`` into its memory update."""
    return ("system s {\n  agent a1 {\n    control @ 10 Hz {\n      memory m: int = 0\n"
            f"{extra}"
            "      behaviour b {\n"
            f"        update memory {{\n          {update}\n        }}\n"
            "        terminal done when m > 3\n      }\n"
            "      initial b\n      switch b -> end when done\n    }\n  }\n}\n")


def compile_text(tmp_path: Path, text: str) -> Compilation:
    path = tmp_path / "spec.rssm"
    path.write_text(text, encoding="utf-8")
    return compile_file(path)


def assert_clean(run: Run, expected: str) -> None:
    assert run.code == 1, run.stderr[-2000:]
    assert "Traceback" not in run.stderr and "E900" not in run.stderr, run.stderr[-2000:]
    assert f"[{expected}]" in run.stderr, run.stderr[-2000:]


# ================================================================ 1. error cascades

BROKEN_AGENT = "agent a{i} {{ control @ 10 Hz {{ memory m: int = }} }} "


def broken_agents(size: int, sep: str = " ") -> str:
    out, n, i = ["system s {" + sep], 0, 0
    while n < size:
        item = BROKEN_AGENT.format(i=i) + sep
        out.append(item)
        n += len(item)
        i += 1
    return "".join(out) + "}\n"


def test_the_parse_stops_after_MAX_ERRORS_errors_and_says_where() -> None:
    text = broken_agents(200_000)
    result, seconds = timed_parse(text)
    assert seconds < BOUND
    assert codes(result) == ["E005"] * (MAX_ERRORS + 1)
    last = result.diagnostics[-1]
    assert "too many syntax errors" in last.message and last.hint is not None
    assert str(MAX_ERRORS) in last.hint
    assert result.diagnostics[-2].span.offset < last.span.offset < len(text) // 10
    assert result.module is None


def test_errors_that_are_echoes_count_too() -> None:
    # every stray character is within three tokens of the previous error: all echoes
    text = "const k = 1\n" + "é a " * 100_000
    result, seconds = timed_parse(text)
    assert seconds < BOUND
    assert len(result.diagnostics) < MAX_ERRORS
    assert "too many syntax errors" in result.diagnostics[-1].message
    assert result.diagnostics[-1].span.offset < 4 * MAX_RECOVERIES + 20


def test_a_run_of_stray_characters_is_one_error() -> None:
    result = parsed("const k = 1 €€€ \u00a0\u00a0 ×× \nconst j = 2\n")
    assert codes(result) == ["E006"]
    assert result.diagnostics[0].span.column == 13
    assert "U+20AC EURO SIGN" in result.diagnostics[0].message


def test_a_megabyte_of_stray_characters() -> None:
    result, seconds = timed_parse("é" * (MB // 2))
    assert seconds < BOUND
    assert codes(result) == ["E006"]


def test_an_unclosed_string_skips_its_line() -> None:
    result = parsed('const s = "abc\nconst k = 1\n')
    assert codes(result) == ["E006"]
    assert "unclosed string" in result.diagnostics[0].message
    result, seconds = timed_parse('"\\' * 100_000)        # each '"' used to rescan the line
    assert seconds < BOUND and codes(result) == ["E006"]


def test_an_unclosed_block_comment_ends_the_file_once() -> None:
    result = parsed("const k = 1 /* not closed\nconst j = 2\n")
    assert codes(result) == ["E007"]
    d = result.diagnostics[0]
    assert (d.span.line, d.span.column) == (1, 13) and "never closed" in d.message
    # every `/*` used to rescan the rest of the file (200 KB: a minute; 1 MB: hours)
    text = "system s { " + "agent a { control { memory m: int = 1 /*" * 5_000
    result, seconds = timed_parse(text)
    assert seconds < BOUND and codes(result) == ["E007"]


def test_error_recovery_trials_leave_no_trace_in_the_tree() -> None:
    # a trial repair (a placeholder name after `import`) used to be appended to the real
    # parse's list of imports too: a second import, its span ending at 1:1 before it starts
    result = parsed("device receptor C @ 60 Hz {\n import \n . \nrecord Blob {")
    assert result.module is not None
    [imp] = result.module.imports
    assert (imp.span.line, imp.span.column, imp.span.end_line, imp.span.end_column) == (3, 2, 4, 7)


def test_a_closed_block_comment_is_a_comment() -> None:
    assert codes(parsed("const k = 1 /* a /* b */ / 2\n")) == []


@pytest.mark.parametrize("sep", [" ", "\n"], ids=["one line", "one per line"])
def test_check_a_megabyte_of_broken_agents(tmp_path: Path, sep: str) -> None:
    (tmp_path / "broken.rssm").write_text(broken_agents(MB, sep))
    run = rssmc("check", "broken.rssm", cwd=tmp_path)
    assert_clean(run, "E005")
    assert run.seconds < BOUND and run.peak_mb < 500


def test_check_a_megabyte_of_undeclared_names(tmp_path: Path) -> None:
    """Each undeclared name may get a "did you mean" over every declared one: a file of
    tens of thousands of them was quadratic (8,000 lines: 43 s); the suggestions stop after
    SUGGESTIONS_AT_MOST in one analysis."""
    lines, size = [], 0
    while size < MB:
        k = len(lines)
        lines.append(f"const c{k}: int = zz{k}\n")
        size += len(lines[-1])
    (tmp_path / "undeclared.rssm").write_text("".join(lines))
    run = rssmc("check", "undeclared.rssm", cwd=tmp_path)
    assert run.code == 1 and "[E102]" in run.stderr and "Traceback" not in run.stderr
    assert run.seconds < BOUND and run.peak_mb < 500


# ================================================================ 2. nesting (E008)


def test_brackets_deeper_than_the_limit_are_E008_at_the_bracket() -> None:
    ok = "const k = " + "(" * MAX_DEPTH + "1" + ")" * MAX_DEPTH + "\n"
    assert codes(parsed(ok)) == []
    deep = "const k = " + "(" * (MAX_DEPTH + 1) + "1" + ")" * (MAX_DEPTH + 1) + "\n"
    result = parsed(deep)
    assert codes(result) == ["E008"]
    assert result.diagnostics[0].span.column == 11 + MAX_DEPTH
    assert "brackets" in result.diagnostics[0].message


@pytest.mark.parametrize("text", [
    "const k = " + "(" * 100_000 + "1" + ")" * 100_000 + "\n",
    "const k = " + "[" * 100_000 + "1" + "]" * 100_000 + "\n",
    "const k = " + "f(" * 100_000 + "1" + ")" * 100_000 + "\n",
    "const k: int = " + "1+" * (MB // 2) + "1\n",
    "const k: int = " + "-" * MB + "1\n",
    "const k: bool = " + "not " * (MB // 4) + "true\n",
    "const k: int = " + "if 1 > 0 then 1 else " * (MB // 21) + "0\n",
    "const k: int = " + "if " * (MB // 3) + "1\n",
    "const k: int = 1" + " * 2 + 3" * (MB // 8) + "\n",
], ids=["parens", "arrays", "calls", "1+1+...", "minus", "not", "else if", "if if", "mixed"])
def test_a_megabyte_of_nesting_is_E008_at_once(text: str) -> None:
    result, seconds = timed_parse(text)
    assert codes(result) == ["E008"]
    assert seconds < 1.0        # reported at the 65th level, not at the end of the text


def test_a_chain_is_refused_at_its_65th_operator() -> None:
    assert codes(parsed("const k: int = " + "1+" * MAX_DEPTH + "1\n")) == []
    result = parsed("const k: int = " + "1+" * (MAX_DEPTH + 1) + "1\n")
    assert codes(result) == ["E008"]
    d = result.diagnostics[0]
    assert d.span.column == 16 and d.span.end_column == 16 + 2 * (MAX_DEPTH + 1)
    assert "each operator of a chain" in d.message


def test_chains_that_are_not_deep_are_accepted() -> None:
    # 400 operators, no deeper than 9: products of 8 summed 50 times... per `and`
    term = " + ".join(["a * b * c"] * 10)
    text = "const k: bool = " + " and ".join([f"{term} > 0"] * 10) + "\n"
    assert codes(parsed(text)) == []


OPERATORS = ["+", "-", "*", "/", "%", "==", "!=", "<", ">=", "and", "or"]
OPERANDS = ["1", "x", "(1 + x)", "f(1, y)", "a[1]", "r.f", "(if a then b else c)"]


@st.composite
def chains(draw: st.DrawFn) -> str:
    n = draw(st.integers(1, 150))
    parts: list[str] = []
    for i in range(n):
        prefixes = draw(st.lists(st.sampled_from(["-", "not "]), max_size=3))
        parts.append("".join(prefixes) + draw(st.sampled_from(OPERANDS)))
        if i < n - 1:
            parts.append(draw(st.sampled_from(OPERATORS)))
    ifs = draw(st.integers(0, 70))
    return "const k = " + "if c then 1 else " * ifs + " ".join(parts) + "\n"


@settings(max_examples=300, deadline=None, derandomize=True, database=None,
          suppress_health_check=[HealthCheck.too_slow])
@given(chains())
def test_early_E008_agrees_with_the_AST_builder(text: str) -> None:
    """The parser's early check only reports what the builder would report later."""
    early = codes(parsed(text))
    check = parser._Nesting._check
    try:
        parser._Nesting._check = lambda self, level, tok: None  # type: ignore[method-assign]
        late = codes(parsed(text))
    finally:
        parser._Nesting._check = check  # type: ignore[method-assign]
    assert early == late


def test_the_deepest_accepted_expressions_compile_format_and_run(tmp_path: Path) -> None:
    chain = " + ".join(["m"] * MAX_DEPTH)                         # depth 63, in `m := ...`
    ifs = "if m > 0 then 1 else " * (MAX_DEPTH - 2) + "0"
    parens = "(" * (MAX_DEPTH - 9) + "m" + ")" * (MAX_DEPTH - 9)    # 5 blocks around
    text = spec(extra=f"      memory k: int = {' + '.join(['1'] * (MAX_DEPTH + 1))}\n"
                      "      memory f: float = 0.0\n",
                update=f"m := {chain}\n          k := {ifs}\n          f := {parens} * 1.0 + "
                       f"{'-' * (MAX_DEPTH - 4)}m")
    (tmp_path / "deep.rssm").write_text(text)
    comp = compile_text(tmp_path, text)
    assert comp.ok and comp.hpn is not None, [str(d) for d in comp.diagnostics]
    for args in (("compile", "deep.rssm", "-o", "out", "-q"), ("fmt", "--check", "deep.rssm"),
                 ("simulate", "--steps", "20", "deep.rssm")):
        run = rssmc(*args, cwd=tmp_path)
        assert "Traceback" not in run.stderr and "E900" not in run.stderr, run.stderr[-2000:]
        assert run.code == 0, run.stderr[-2000:]
    assert (tmp_path / "out" / "s.hpn.json").is_file()


def test_check_compile_and_fmt_of_a_megabyte_chain(tmp_path: Path) -> None:
    (tmp_path / "chain.rssm").write_text(spec(update="m := " + "1+" * (MB // 2) + "1"))
    for args in (("check", "chain.rssm"), ("compile", "chain.rssm", "-o", "out"),
                 ("fmt", "--check", "chain.rssm")):
        run = rssmc(*args, cwd=tmp_path)
        assert_clean(run, "E008")
        assert run.seconds < BOUND and run.peak_mb < 500
    assert not (tmp_path / "out").exists()


# ================================================================ 3. number literals (E013)


@pytest.mark.parametrize("literal", ["1" * 5000, "9" * (MAX_INT_DIGITS + 1), "1" * 1_000_000])
def test_an_int_literal_with_too_many_digits_is_E013_at_the_literal(literal: str) -> None:
    result = parsed(f"const a = 1\nconst k: int = {literal}\n")
    assert codes(result) == ["E013"]
    d = result.diagnostics[0]
    assert (d.span.line, d.span.column, d.span.end_column) == (2, 16, 16 + len(literal))
    assert f"{len(literal)} digits" in d.message and len(d.message) < 200
    assert d.hint is not None and "9223372036854775807" in d.hint


def test_int_literals_up_to_19_digits_are_read() -> None:
    result = parsed("const a = 9999999999999999999\nconst b = " + "0" * 5000 + "42\n")
    assert codes(result) == []
    assert result.module is not None
    values = [d.value.value for d in result.module.decls]  # type: ignore[union-attr]
    assert values == [9999999999999999999, 42]


@pytest.mark.parametrize(("literal", "fragment"), [
    ("1e999", "too large for a float"),
    ("1.5E+400", "too large for a float"),
    ("0." + "1" * MAX_NUMBER_CHARS, f"{MAX_NUMBER_CHARS + 2} characters"),
    ("1" * 500 + ".0", "502 characters"),
])
def test_a_float_literal_too_long_or_too_large_is_E013(literal: str, fragment: str) -> None:
    result = parsed(f"const k: float = {literal}\n")
    assert codes(result) == ["E013"]
    assert fragment in result.diagnostics[0].message
    assert result.diagnostics[0].span.column == 18


def test_small_floats_are_not_errors() -> None:
    assert codes(parsed("const k: float = 1e-999\nconst j = 1.7976931348623157e308\n")) == []


def test_range_bounds_and_array_sizes_are_read_the_same_way() -> None:
    big = "1" * 40
    result = parsed(f"type R = 0..{big}\ntype A = float[{big}]\n")
    assert codes(result) == ["E013", "E013"]


def test_E013_is_reported_by_check(tmp_path: Path) -> None:
    comp = compile_text(tmp_path, spec(extra="      param p: int = " + "7" * 4400 + "\n"))
    assert codes(comp) == ["E013"] and comp.diagnostics[0].span.line == 5


# ================================================================ 4. int is 64-bit (E214)

INT_MAX = 2**63 - 1


@pytest.mark.parametrize(("decl", "line_of_error"), [
    ("      param big: int = 9223372036854775808\n", 5),
    ("      memory big: int = 9223372036854775808\n", 5),
    ("      param low: int = -9223372036854775809\n", 5),
    ("      param prod: int = 4611686018427387904 * 2\n", 5),
    ("      param step: int = 9223372036854775807 + 1 - 1\n", 5),   # overflows on the way
    ("      param neg: int = -(-9223372036854775808)\n", 5),
    ("      memory r: 0..3 = 9223372036854775808\n", 5),
], ids=["param", "memory", "negative", "product", "intermediate", "negated-min", "range"])
def test_an_int_constant_outside_64_bits_is_E214(tmp_path: Path, decl: str,
                                                 line_of_error: int) -> None:
    comp = compile_text(tmp_path, spec(extra=decl))
    assert errors(comp) == ["E214"], [str(d) for d in comp.diagnostics]
    d = next(d for d in comp.diagnostics if d.is_error)
    assert d.span.line == line_of_error and "64-bit range of int" in d.message
    assert d.hint is not None and "-9223372036854775808 to 9223372036854775807" in d.hint


def test_a_const_outside_64_bits_is_E214(tmp_path: Path) -> None:
    comp = compile_text(tmp_path, "const big: int = 9223372036854775808\nconst k = "
                        "9223372036854775807 * 3\n" + spec())
    assert errors(comp) == ["E214", "E214"]
    assert [d.span.column for d in comp.diagnostics if d.is_error] == [18, 11]


def test_the_int_extremes_are_accepted(tmp_path: Path) -> None:
    comp = compile_text(tmp_path, "const lo: int = -9223372036854775808\n" + spec(
        extra="      param hi: int = 9223372036854775807\n"
              "      param lo2: int = -9223372036854775807 - 1\n"
              "      memory x: -9223372036854775808..9223372036854775807 = -9223372036854775808\n",
        update="m := m + hi - hi + lo2 - lo2 + x - x"))
    assert comp.ok, [str(d) for d in comp.diagnostics]


def test_an_int_literal_outside_64_bits_in_a_statement_is_E214(tmp_path: Path) -> None:
    comp = compile_text(tmp_path, spec(update="m := m + 9223372036854775808"))
    assert errors(comp) == ["E214"]


def test_an_overflow_in_a_statement_is_left_to_the_run(tmp_path: Path) -> None:
    # computed when it runs, where it stops the run with E802 (tests/semantics/test_values.py)
    comp = compile_text(tmp_path, spec(update="m := 9223372036854775807 + 1"))
    assert comp.ok, [str(d) for d in comp.diagnostics]


# ================================================================ 5. strings


@pytest.mark.filterwarnings("error")
@pytest.mark.parametrize("escape", ["\\x", "\\d", "\\N", "\\u"])
def test_an_unknown_escape_is_E005_at_the_escape(escape: str) -> None:
    # it was E005 at 1:1 ("the file could not be parsed") or a DeprecationWarning
    result = parsed(f'extern f() -> int = "m:a{escape}b"\n')
    assert codes(result) == ["E005"]
    d = result.diagnostics[0]
    assert (d.span.line, d.span.column, d.span.end_column) == (1, 25, 27)
    assert f"unknown escape '{escape}'" in d.message


def test_strings_keep_their_characters_and_read_their_escapes() -> None:
    result = parsed('import "d\u00e9j\u00e0 vu/a\\"b\\\\c\\nd.rssm"\n')
    assert codes(result) == [] and result.module is not None
    assert result.module.imports[0].path == 'd\u00e9j\u00e0 vu/a"b\\c\nd.rssm'
