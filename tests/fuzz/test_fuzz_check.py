"""Fuzzing the front end: whatever the input, `compile_file` (rssm_dsl/pipeline.py) returns
diagnostics and never raises, and `rssmc compile FILE -o DIR` never crashes.

Inputs:

- grammar-aware: random streams of the grammar's own tokens (keywords, punctuation, names,
  numbers, strings, comments) mixed with lines and whole declarations spliced from the
  example specs (examples/**/*.rssm);
- mutations of the example specs: deletions, duplications, swaps and truncations of byte
  ranges, random Unicode, invalid UTF-8, NUL and binary garbage, huge literals, long lines
  and deep nesting.

Each input must give: no exception and no E900; only codes of the registry
(rssm_dsl/diagnostics/codes.py), each at a span with line >= 1 and column >= 1 inside its
file; within a time bound. A few run through the CLI in a subprocess, which must also write
nothing when there are errors and stay within a memory bound (ru_maxrss from os.wait4).

The runs are reproducible (derandomize=True, no example database) and sized for CI (well
under two minutes for the file). For a longer local run, set RSSMC_FUZZ_EXAMPLES (examples
per in-process test, default 1000) and RSSMC_FUZZ_CLI (CLI runs, default 6), e.g.

    RSSMC_FUZZ_EXAMPLES=20000 RSSMC_FUZZ_CLI=100 pytest tests/fuzz -x

A failure prints the input (hypothesis shrinks it); fix it, or add it to tests/front as a
regression test.
"""

from __future__ import annotations

import os
import time
from functools import cache
from pathlib import Path

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from lark.exceptions import LarkError

from rssm_dsl.diagnostics.codes import BY_CODE
from rssm_dsl.pipeline import Compilation, compile_file
from rssm_dsl.source import split_lines
from rssm_dsl.syntax.parser import _lark
from tests.conftest import EXAMPLES
from tests.fuzz.measure import rssmc

EXAMPLES_PER_TEST = int(os.environ.get("RSSMC_FUZZ_EXAMPLES", "1000"))
CLI_RUNS = int(os.environ.get("RSSMC_FUZZ_CLI", "6"))
SECONDS_PER_INPUT = 5.0
CLI_PEAK_MB = 500

SETTINGS = settings(max_examples=EXAMPLES_PER_TEST, deadline=None, derandomize=True,
                    database=None, print_blob=True,
                    suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large,
                                           HealthCheck.large_base_example])

SPECS = sorted(EXAMPLES.rglob("*.rssm"))


@cache
def spec_bytes(path: Path) -> bytes:
    return path.read_bytes()


@cache
def grammar_words() -> tuple[str, ...]:
    """Every fixed terminal of the grammar: keywords and punctuation."""
    return tuple(sorted(str(t.pattern.value) for t in _lark().terminals
                        if t.pattern.type == "str"))


@cache
def spec_lines() -> tuple[str, ...]:
    return tuple(line for p in SPECS for line in spec_bytes(p).decode("utf-8").splitlines()
                 if line.strip())


# ------------------------------------------------------------------------ checking one input


def check_compilation(comp: Compilation, path: Path) -> None:
    for d in comp.diagnostics:
        assert d.code in BY_CODE and d.code != "E900", d
        s = d.span
        assert s.line >= 1 and s.column >= 1 and s.end_line >= 1 and s.end_column >= 1, d
        assert (s.end_line, s.end_column) >= (s.line, s.column), d
        source = comp.program.sources.get(s.file)
        if source is None:                 # a problem with the file itself, at 1:1
            assert (s.line, s.column) == (1, 1), d
            continue
        lines = split_lines(source.text)
        assert s.end_line <= len(lines), (d, len(lines))
        assert s.column <= len(lines[s.line - 1]) + 1, (d, len(lines[s.line - 1]))
        assert s.end_column <= len(lines[s.end_line - 1]) + 1, d
    if not comp.ok:
        assert comp.hpn is None
    del path


def compile_text(path: Path, text: str) -> None:
    """Compile ``text`` as the spec at ``path`` (imports resolve next to it)."""
    start = time.perf_counter()
    comp = compile_file(path, overrides={path.resolve(): text})
    assert time.perf_counter() - start < SECONDS_PER_INPUT
    check_compilation(comp, path)


def compile_bytes(folder: Path, data: bytes) -> None:
    """Compile ``data`` written to a file (what the loader does with bytes: E003, E004)."""
    path = folder / "fuzz.rssm"
    path.write_bytes(data)
    start = time.perf_counter()
    comp = compile_file(path)
    assert time.perf_counter() - start < SECONDS_PER_INPUT
    check_compilation(comp, path)


# ------------------------------------------------------------------------ grammar-aware inputs

NAMES = st.sampled_from(["x", "a1", "c", "e", "r", "E", "R", "memory", "end", "new", "pi",
                         "inf", "Phase", "idle", "m", "_", "lwr", "s", "t0", "q"])
INTS = st.one_of(st.integers(0, 10**20).map(str),
                 st.sampled_from(["0", "9223372036854775807", "9223372036854775808",
                                  "1" * 30, "0" * 50 + "7", "9" * 5000]))
FLOATS = st.one_of(
    st.floats(allow_nan=False, allow_infinity=False).map(lambda f: repr(abs(f))),
    st.sampled_from(["1e999", "1.0e-999", ".5", "2.", "1e5", "3.5E+2", "1" * 500 + ".0"]))
STRINGS = st.sampled_from(['"m:f"', '"a.b:C"', '"x', '"\\"', '""', '"\u00e9"', '"a\\nb"'])
SPACE = st.sampled_from([" ", " ", " ", "\n", "\t", "  // note\n", " /* c */ ", "\r\n", "\r",
                         "\u2028", "\u00a0", ""])
TOKEN = st.one_of(st.sampled_from(grammar_words()), NAMES, INTS, FLOATS, STRINGS,
                  st.sampled_from(["/*", "*/", "//", "#", "$", "`", "\u2212", "\u00d7", "\x00",
                                   "\x1b[2J", "\ufeff", "é"]))
SPLICE = st.sampled_from(spec_lines())


@st.composite
def token_stream(draw: st.DrawFn) -> str:
    parts: list[str] = []
    for _ in range(draw(st.integers(0, 120))):
        if draw(st.integers(0, 9)) == 0:
            parts.append("\n" + draw(SPLICE) + "\n")
        else:
            parts.append(draw(TOKEN))
        parts.append(draw(SPACE))
    return "".join(parts)


@st.composite
def declarations(draw: st.DrawFn) -> str:
    """Whole declarations from the examples, reordered and cut, with token noise."""
    spec = draw(st.sampled_from(SPECS))
    lines = spec_bytes(spec).decode("utf-8").splitlines(keepends=True)
    out: list[str] = []
    for _ in range(draw(st.integers(1, 6))):
        a = draw(st.integers(0, max(0, len(lines) - 1)))
        b = draw(st.integers(a, min(len(lines), a + 40)))
        out.append("".join(lines[a:b]))
        if draw(st.booleans()):
            out.append(draw(token_stream()))
    return "".join(out)


@SETTINGS
@given(st.one_of(token_stream(), declarations()), st.sampled_from(SPECS))
def test_grammar_aware_inputs(text: str, spec: Path) -> None:
    compile_text(spec, text)


# ------------------------------------------------------------------------ mutated examples

GARBAGE = st.one_of(
    st.text(max_size=40),                                         # any Unicode
    st.binary(max_size=40).map(lambda b: b.decode("latin-1")),
    st.sampled_from(["9" * 5000, "1e999", "0." + "1" * 600, "(" * 200, ")" * 200,
                     "1+" * 3000 + "1", "-" * 3000, "if " * 300, "[" * 100, "{" * 100,
                     "x" * 100_000, " " * 50_000, "/*", '"', "\\", "\x00", "\r", "\u2028",
                     "\ud7ff", "not " * 200, "a." * 500 + "b", "x[0]" * 300]),
)


@st.composite
def mutated(draw: st.DrawFn) -> tuple[Path, str]:
    spec = draw(st.sampled_from(SPECS))
    text = spec_bytes(spec).decode("utf-8")
    for _ in range(draw(st.integers(1, 6))):
        n = len(text)
        a = draw(st.integers(0, n))
        b = draw(st.integers(a, min(n, a + 200)))
        kind = draw(st.integers(0, 5))
        if kind == 0:
            text = text[:a] + text[b:]                                  # delete
        elif kind == 1:
            text = text[:a] + draw(GARBAGE) + text[b:]                  # replace
        elif kind == 2:
            text = text[:b] + text[a:b] * draw(st.integers(1, 50)) + text[b:]   # duplicate
        elif kind == 3:
            c = draw(st.integers(0, n))
            d = draw(st.integers(c, min(n, c + 200)))
            if b <= c:
                text = text[:a] + text[c:d] + text[b:c] + text[a:b] + text[d:]  # swap
        elif kind == 4:
            text = text[:a]                                             # truncate
        else:
            text = text[:a] + draw(GARBAGE) + text[a:]                  # insert
    return spec, text


@SETTINGS
@given(mutated())
def test_mutated_examples(case: tuple[Path, str]) -> None:
    spec, text = case
    compile_text(spec, text)


@cache
def spec_tokens(path: Path) -> tuple[tuple[int, int, str, str], ...]:
    """(start, end, terminal, text) of the tokens of an example spec."""
    text = spec_bytes(path).decode("utf-8")
    out: list[tuple[int, int, str, str]] = []
    try:
        for t in _lark().lex(text):
            out.append((t.start_pos or 0, t.end_pos or 0, t.type, str(t)))
    except LarkError:
        pass                      # examples/diagnostics/E006_*: the tokens before the error
    return tuple(out)


NUMBERS = ["0", "1", "7", "100000000", "9223372036854775807", "9223372036854775808",
           "1" * 25, "0.0", "1e308", "1e999", "4.9e-324", "1e-400", "2.5"]


@st.composite
def token_mutated(draw: st.DrawFn) -> tuple[Path, str]:
    """An example with some tokens replaced by others of the same kind: mostly still
    parses, so the checks, the HPN build and the backends' checks run on odd values."""
    spec = draw(st.sampled_from(SPECS))
    text = spec_bytes(spec).decode("utf-8")
    tokens = spec_tokens(spec)
    if not tokens:
        return spec, text
    names = sorted({v for _, _, kind, v in tokens if kind == "NAME"}) or ["x"]
    words = grammar_words()
    edits: dict[int, tuple[int, str]] = {}
    for _ in range(draw(st.integers(1, 8))):
        start, end, kind, _ = tokens[draw(st.integers(0, len(tokens) - 1))]
        if kind == "NAME":
            new = draw(st.sampled_from([*names, "x_new", "end", "memory", "pi"]))
        elif kind in ("INT", "FLOAT"):
            new = draw(st.sampled_from(NUMBERS))
        elif kind == "STRING":
            new = draw(STRINGS)
        else:
            new = draw(st.sampled_from([*words, ""]))
        edits[start] = (end, new)
    for start in sorted(edits, reverse=True):
        end, new = edits[start]
        text = text[:start] + new + text[end:]
    return spec, text


@SETTINGS
@given(token_mutated())
def test_token_mutated_examples(case: tuple[Path, str]) -> None:
    spec, text = case
    compile_text(spec, text)


@st.composite
def mutated_bytes(draw: st.DrawFn) -> bytes:
    data = spec_bytes(draw(st.sampled_from(SPECS)))
    a = draw(st.integers(0, len(data)))
    junk = draw(st.one_of(st.binary(min_size=1, max_size=20),
                          st.sampled_from([b"\xff", b"\xc3", b"\xed\xa0\x80", b"\x00",
                                           b"\xef\xbb\xbf", b"\xe2\x80\xa8"])))
    return data[:a] + junk + data[a:]


@settings(SETTINGS, max_examples=max(20, EXAMPLES_PER_TEST // 5))
@given(mutated_bytes())
def test_mutated_bytes(tmp_path_factory: pytest.TempPathFactory, data: bytes) -> None:
    compile_bytes(tmp_path_factory.getbasetemp(), data)


# ------------------------------------------------------------------------ the CLI


def cli_compile(folder: Path, data: bytes) -> None:
    (folder / "fuzz.rssm").write_bytes(data)
    out = folder / "out"
    run = rssmc("compile", "fuzz.rssm", "-o", "out", "-q", cwd=folder)
    assert run.code in (0, 1), run.stderr[-3000:]
    assert "Traceback" not in run.stderr and "E900" not in run.stderr, run.stderr[-3000:]
    if run.code == 1:
        assert "error[" in run.stderr, run.stderr[-3000:]
        assert not out.exists(), "an output folder was written for a spec with errors"
    else:
        assert any(out.glob("*.hpn.json"))
    assert run.seconds < SECONDS_PER_INPUT + 2.0      # plus the interpreter's start
    assert run.peak_mb < CLI_PEAK_MB


def big(text: str, size: int = 1_000_000) -> str:
    return (text * (size // max(1, len(text)) + 1))[:size]


HOSTILE: list[tuple[str, bytes]] = [
    ("example", spec_bytes(EXAMPLES / "lwr4_circle.rssm")),
    ("1 MB of examples back to back", big("".join(spec_bytes(p).decode() for p in SPECS[:20]))
     .encode()),
    ("1 MB of a truncated example", big(spec_bytes(EXAMPLES / "camera_tracker.rssm")
                                        .decode()[:700]).encode()),
    ("1 MB of grammar words", big(" ".join(grammar_words())).encode()),
    ("1 MB one line", big(spec_bytes(EXAMPLES / "relay_blocking.rssm").decode()
                          .replace("\n", " ")).encode()),
    ("binary", bytes(range(1, 256)) * 4000),
]


@pytest.mark.parametrize(("label", "data"), HOSTILE[:CLI_RUNS], ids=[h[0] for h in HOSTILE[:CLI_RUNS]])
def test_cli_compile_of_hostile_inputs(tmp_path: Path, label: str, data: bytes) -> None:
    cli_compile(tmp_path, data)


@settings(SETTINGS, max_examples=max(1, CLI_RUNS - len(HOSTILE)))
@given(mutated())
def test_cli_compile_of_mutated_examples(tmp_path_factory: pytest.TempPathFactory,
                                         case: tuple[Path, str]) -> None:
    cli_compile(tmp_path_factory.mktemp("cli"), case[1].encode("utf-8", "surrogatepass"))
