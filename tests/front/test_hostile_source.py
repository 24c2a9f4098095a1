"""Hostile input: the compiler never crashes, stalls or blows up.

1. names that become file names are bounded (E011), long import paths are E009, not E900;
2. a diagnostic shows a bounded window of its source line;
3. at most MAX_SHOWN_PER_FILE diagnostics of a file are printed, then a count of the rest;
4. the line terminators are \\n, \\r\\n and a bare \\r, everywhere;
5. U+2028, U+2029 and U+0085 are ordinary characters: in a comment they get W012;
6. control characters of the source are printed escaped.
"""

from __future__ import annotations

import ast
import json
import subprocess
import sys
from pathlib import Path

import pytest

from rssm_dsl.diagnostics import Diagnostic
from rssm_dsl.diagnostics.diagnostic import MAX_QUOTED
from rssm_dsl.diagnostics.render import MAX_EXCERPT, MAX_SHOWN_PER_FILE, render_text
from rssm_dsl.filenames import (
    MAX_NAME_LENGTH,
    NAME_MAX_BYTES,
    UnusableFileName,
    file_name,
    fitted_file_name,
)
from rssm_dsl.pipeline import Compilation, compile_file
from rssm_dsl.source import SourceFile, Span, escape_controls, line_starts, split_lines
from tests.conftest import ROOT


def spec(system: str = "s", agent: str = "a1", behaviour: str = "idle", extra: str = "") -> str:
    """A clean one-agent system (``extra`` goes inside the control subsystem)."""
    return (f"system {system} {{\n"
            f"  agent {agent} {{\n"
            f"    control @ 10 Hz {{\n{extra}"
            f"      behaviour {behaviour} {{\n"
            f"        terminal never when false\n"
            f"      }}\n"
            f"      initial {behaviour}\n"
            f"    }}\n"
            f"  }}\n"
            f"}}\n")


def rssmc(*args: str | Path, cwd: Path) -> subprocess.CompletedProcess[str]:
    return subprocess.run([sys.executable, "-m", "rssm_dsl", *map(str, args)], cwd=cwd,
                          capture_output=True, text=True, timeout=300)


def compile_text(tmp_path: Path, text: str, name: str = "spec.rssm") -> Compilation:
    path = tmp_path / name
    path.write_bytes(text.encode("utf-8"))
    return compile_file(path)


def codes(comp: Compilation) -> list[str]:
    return [d.code for d in comp.diagnostics]


def assert_clean_failure(r: subprocess.CompletedProcess[str], code: str, exit_code: int = 1) -> None:
    assert r.returncode == exit_code, r.stderr
    assert "Traceback" not in r.stderr + r.stdout
    assert "E900" not in r.stderr
    assert f"[{code}]" in r.stderr, r.stderr


# ================================================================ 1. names that become file names

LONG = "a" * 300


def test_a_long_system_name_is_E011_at_the_name(tmp_path: Path) -> None:
    comp = compile_text(tmp_path, spec(system=LONG))
    assert codes(comp) == ["E011"]
    d = comp.diagnostics[0]
    assert (d.span.line, d.span.column, d.span.end_line, d.span.end_column) == (1, 8, 1, 308)
    assert "300 characters" in d.message
    assert d.hint is not None and f"at most {MAX_NAME_LENGTH} characters" in d.hint
    assert "system name" in d.hint


def test_check_and_compile_report_E011_and_write_nothing(tmp_path: Path) -> None:
    (tmp_path / "long.rssm").write_text(spec(system=LONG))
    assert_clean_failure(rssmc("check", "long.rssm", cwd=tmp_path), "E011")
    r = rssmc("compile", "long.rssm", "-o", "out", cwd=tmp_path)
    assert_clean_failure(r, "E011")
    assert "long.rssm:1:8: error[E011]" in r.stderr
    assert "help: shorten the system name" in r.stderr
    assert not (tmp_path / "out").exists()
    assert sorted(p.name for p in tmp_path.iterdir()) == ["long.rssm"]


def test_a_system_name_at_the_limit_compiles(tmp_path: Path) -> None:
    name = "s" * MAX_NAME_LENGTH
    (tmp_path / "max.rssm").write_text(spec(system=name))
    r = rssmc("compile", "max.rssm", "-o", "out", "-q", cwd=tmp_path)
    assert r.returncode == 0, r.stderr
    assert (tmp_path / "out" / f"{name}.hpn.json").is_file()


@pytest.mark.parametrize("kind", ["agent", "effector", "device", "record"])
def test_other_names_that_name_files_are_E011(tmp_path: Path, kind: str) -> None:
    name = "n" * (MAX_NAME_LENGTH + 1)
    if kind == "agent":
        text = spec(agent=name)
    elif kind == "record":
        text = f"record {name} {{ x: float }}\n" + spec()
    elif kind == "effector":
        text = spec().replace("  }\n}\n", f"    effector {name} {{\n      behaviour b {{\n"
                              "        terminal never when false\n      }\n      initial b\n"
                              "    }\n  }\n}\n")
    else:
        text = ("device effector Drive {\n  input v: float nonblocking\n"
                '  binding "m:D"\n}\n' + spec().replace(
                    "  }\n}\n", f"    real effector {name}: Drive\n  }}\n}}\n"))
    comp = compile_text(tmp_path, text)
    e011 = [d for d in comp.diagnostics if d.code == "E011"]
    assert len(e011) == 1, render_text(comp.diagnostics, comp.program.line)
    line = comp.program.line(e011[0].span.file, e011[0].span.line)
    assert line[e011[0].span.column - 1:].startswith(name)


@pytest.mark.parametrize("imp", [f'import "{LONG}.rssm"', f"import {LONG}.{LONG}",
                                 f"import x.{'y' * 5000}"])
def test_a_long_import_path_is_E009(tmp_path: Path, imp: str) -> None:
    (tmp_path / "imp.rssm").write_text(imp + "\n" + spec())
    r = rssmc("check", "imp.rssm", cwd=tmp_path)
    assert_clean_failure(r, "E009")
    assert "help: modules are looked up next to this file" in r.stderr
    assert len(r.stderr) < 3000  # the path is quoted shortened


def test_an_import_path_with_a_nul_is_E009(tmp_path: Path) -> None:
    comp = compile_text(tmp_path, 'import "a\\u0000b"\n' + spec())   # the string decodes to a NUL
    assert codes(comp) == ["E009"]
    assert "\\x00" in comp.diagnostics[0].message


def test_a_root_file_name_too_long_is_E001(tmp_path: Path) -> None:
    r = rssmc("check", LONG + ".rssm", cwd=tmp_path)
    assert_clean_failure(r, "E001")


def test_an_output_folder_the_file_system_refuses_is_no_internal_error(tmp_path: Path) -> None:
    (tmp_path / "ok.rssm").write_text(spec())
    r = rssmc("compile", "ok.rssm", "-o", "o" * 300, cwd=tmp_path)
    assert r.returncode == 2, r.stderr
    assert "E900" not in r.stderr and "Traceback" not in r.stderr
    assert "rssmc: error[E881]: File name too long" in r.stderr
    assert sorted(p.name for p in tmp_path.iterdir()) == ["ok.rssm"]


def test_file_name_is_the_one_checked_way_to_a_file_name() -> None:
    assert file_name("lwr4", ".hpn.json") == "lwr4.hpn.json"
    assert file_name("a1", ".launch.py", prefix="pkg_") == "pkg_a1.launch.py"
    assert file_name("x" * MAX_NAME_LENGTH, ".paged.pnml")
    for bad in ["", ".", "..", "a/b", "a\\b", "a\x00b", "a\x1bb", "a:b", "x" * (MAX_NAME_LENGTH + 1)]:
        with pytest.raises(UnusableFileName):
            file_name(bad, ".json")
    with pytest.raises(UnusableFileName, match="characters long"):
        file_name("é" * MAX_NAME_LENGTH)  # 200 bytes of UTF-8: over the limit in bytes


def test_fitted_file_name_bounds_derived_names() -> None:
    long_a, long_b = "fig-P_1_" + "x" * 400 + "_a", "fig-P_1_" + "x" * 400 + "_b"
    a, b = fitted_file_name(long_a, ".svg"), fitted_file_name(long_b, ".svg")
    assert a != b and a.endswith(".svg") and b.endswith(".svg")
    assert len(a.encode()) <= NAME_MAX_BYTES - 16
    assert fitted_file_name("fig-H", ".svg") == "fig-H.svg"
    assert fitted_file_name("a/b:c\x07", ".svg") == "a-b-c-.svg"


def test_render_figure_names_are_bounded(tmp_path: Path) -> None:
    from rssm_dsl.render.names import figure_files

    comp = compile_text(tmp_path, spec(behaviour="b" * 1000))
    assert comp.ok and comp.hpn is not None, render_text(comp.diagnostics, comp.program.line)
    names = figure_files(comp.hpn)
    assert all(len(n.encode()) <= NAME_MAX_BYTES for n in names.values()), names
    assert len(set(names.values())) == len(names)


# ================================================================ 2. bounded excerpts

def _diag(line: int, column: int, width: int, file: str = "f.rssm", code: str = "E005") -> Diagnostic:
    return Diagnostic(code, "problem", Span(file, line, column, line, column + width))


def _excerpt(text: str, column: int, width: int) -> tuple[str, str]:
    """(source line, caret line) of a diagnostic on the first line of ``text``, gutters cut."""
    out = render_text([_diag(1, column, width)], lambda f, n: split_lines(text)[n - 1])
    lines = out.splitlines()
    assert lines[1].startswith("    1 | ") and lines[2].startswith("      | ")
    return lines[1][8:], lines[2][8:]


def test_a_short_line_is_shown_whole() -> None:
    src, caret = _excerpt("agent a { x }", 11, 1)
    assert src == "agent a { x }"
    assert caret == "          ^"


def test_a_long_line_is_shown_as_a_window_around_the_span() -> None:
    text = "a" * 500_000 + "BROKEN" + "b" * 500_000
    src, caret = _excerpt(text, 500_001, 6)
    assert len(src) <= MAX_EXCERPT + 6 and len(caret) <= MAX_EXCERPT + 6
    assert src.startswith("...") and src.endswith("...")
    at = caret.index("^")
    assert src[at:at + 6] == "BROKEN" and caret[at:] == "^^^^^^"


def test_a_span_at_the_start_of_a_long_line_cuts_only_the_right() -> None:
    src, caret = _excerpt("BROKEN" + "b" * 10_000, 1, 6)
    assert src.startswith("BROKEN") and src.endswith("...") and not src.startswith("...")
    assert caret == "^^^^^^"


def test_a_span_at_the_end_of_a_long_line_cuts_only_the_left() -> None:
    text = "a" * 10_000 + "END"
    src, caret = _excerpt(text, 10_001, 3)
    assert src.startswith("...") and src.endswith("END")
    assert src[caret.index("^"):] == "END"


def test_a_span_longer_than_the_window_is_cut() -> None:
    text = "x" * 50 + "y" * 5000
    src, caret = _excerpt(text, 51, 5000)
    assert caret.count("^") <= MAX_EXCERPT
    assert src.endswith("...") and caret.lstrip(" ").startswith("^")
    assert src[caret.index("^")] == "y"


def test_tabs_before_the_span_are_copied_to_the_caret_line() -> None:
    src, caret = _excerpt("\t\tx := 1", 3, 1)
    assert src == "\t\tx := 1" and caret == "\t\t^"


def test_a_file_of_one_long_broken_line_prints_a_bounded_report(tmp_path: Path) -> None:
    body = "agent a { control { x } } " * 2000
    (tmp_path / "broken.rssm").write_text("system s { " + body + "}")
    r = rssmc("check", "broken.rssm", cwd=tmp_path)
    assert_clean_failure(r, "E005")
    assert len(r.stderr) < 20_000, len(r.stderr)
    assert max(len(line) for line in r.stderr.splitlines()) < 200


# ================================================================ 3. a cap on the diagnostics per file

def test_at_most_the_cap_is_printed_per_file_then_a_count() -> None:
    diags = [_diag(n, 1, 1) for n in range(1, 201)]
    diags += [_diag(n, 1, 1, code="W701") for n in range(201, 211)]
    diags += [_diag(n, 1, 1, file="g.rssm") for n in range(1, 4)]
    out = render_text(diags, lambda f, n: "x")
    lines = out.splitlines()
    assert sum(1 for line in lines if line.startswith("f.rssm:")) == MAX_SHOWN_PER_FILE
    assert sum(1 for line in lines if line.startswith("g.rssm:")) == 3
    more = 200 - MAX_SHOWN_PER_FILE
    assert f"... and {more} more errors (and 10 more warnings) in f.rssm" in lines
    assert not any("more" in line and "g.rssm" in line for line in lines)


def test_errors_are_printed_before_warnings_are_capped() -> None:
    diags = [_diag(n, 1, 1, code="W701") for n in range(1, 101)] + [_diag(500, 1, 1)]
    out = render_text(diags, lambda f, n: "")
    assert "f.rssm:500:1: error[E005]" in out
    assert f"... and {101 - MAX_SHOWN_PER_FILE} more warnings in f.rssm" in out
    assert "more error" not in out


def test_one_more_is_singular() -> None:
    out = render_text([_diag(n, 1, 1) for n in range(1, MAX_SHOWN_PER_FILE + 2)], lambda f, n: "")
    assert out.splitlines()[-1] == "... and 1 more error in f.rssm"


def test_the_summary_line_gives_the_true_totals(tmp_path: Path) -> None:
    names = [f"a{n}" for n in range(120)]
    agents = "".join(f"  agent {n} {{ }}\n" for n in names)   # each lacks its control subsystem
    (tmp_path / "many.rssm").write_text(f"system s {{\n{agents}}}\n")
    r = rssmc("check", "many.rssm", cwd=tmp_path)
    assert_clean_failure(r, "E301")
    assert r.stderr.count("error[E301]") == MAX_SHOWN_PER_FILE
    assert f"... and {120 - MAX_SHOWN_PER_FILE} more errors in many.rssm" in r.stderr
    assert r.stderr.rstrip().endswith("many.rssm: 120 errors, 0 warnings")
    # JSON keeps every diagnostic (see rssm_dsl/diagnostics/render.py)
    j = rssmc("check", "many.rssm", "--format", "json", cwd=tmp_path)
    assert len(json.loads(j.stdout)) == 120


def test_a_huge_name_is_not_repeated_in_full() -> None:
    name = "n" * 1_000_000
    d = Diagnostic("E101", f"agent '{name}' is declared twice", Span("f", 1, 1, 1, 2),
                   f"rename '{name}'")
    assert len(d.message) < MAX_QUOTED + 40 and d.hint is not None and len(d.hint) < MAX_QUOTED + 40
    assert d.message.startswith("agent 'nnn") and d.message.endswith("n' is declared twice")
    assert "…" in d.message


@pytest.mark.parametrize("where", ["agent", "param"])
def test_the_report_of_a_huge_name_is_bounded(tmp_path: Path, where: str) -> None:
    name = "n" * 300_000
    if where == "agent":    # a name of a file: E011, three times
        text = f"system s {{ agent {name} {{ }} agent {name} {{ }} agent {name} {{ }} }}"
    else:                   # declared three times: E101 twice, and W703
        text = spec(extra=f"      param {name}: float = 1.0\n" * 3)
    (tmp_path / "dup.rssm").write_text(text)
    r = rssmc("check", "dup.rssm", "--format", "json", cwd=tmp_path)
    assert r.returncode == 1, r.stderr
    diags = json.loads(r.stdout)
    assert {d["code"] for d in diags} >= ({"E011"} if where == "agent" else {"E101"})
    assert len(r.stdout) < 20_000
    t = rssmc("check", "dup.rssm", cwd=tmp_path)
    assert len(t.stderr) < 20_000


# ================================================================ 4. line terminators

def test_split_lines_is_the_rssm_definition_of_lines() -> None:
    text = "a\nb\r\nc\rd\u2028e\u2029f\x85g\x0bh\x0ci\x1cj\x1dk\x1el\n"
    assert split_lines(text) == ["a", "b", "c", "d\u2028e\u2029f\x85g\x0bh\x0ci\x1cj\x1dk\x1el", ""]
    assert line_starts(text) == [0, 2, 5, 7, len(text)]
    assert split_lines("") == [""] and line_starts("") == [0]
    assert split_lines("\r\r\n\n") == ["", "", "", ""]
    assert line_starts("\r\r\n\n") == [0, 1, 3, 4]


def test_source_lines_agree_with_split_lines() -> None:
    text = "one\r\ntwo\rthree\nfour\u2028still four\r"
    source = SourceFile("f", text)
    assert [source.line_text(n) for n in range(1, source.line_count + 1)] == split_lines(text)
    assert source.position(text.index("three")) == (3, 1)
    assert source.position(text.index("still")) == (4, 6)
    assert len(source.text) == len(text)   # the lexer's text: offsets unchanged


@pytest.mark.parametrize("newline", ["\n", "\r\n", "\r"], ids=["lf", "crlf", "cr"])
def test_every_line_terminator_reads_the_same(tmp_path: Path, newline: str) -> None:
    text = ("// a comment\n" + spec()).replace("\n", newline)
    comp = compile_text(tmp_path, text)
    assert codes(comp) == []
    broken = ("// a comment\n" + spec(extra="      param p: float = nope\n")).replace("\n", newline)
    comp = compile_text(tmp_path, broken)
    assert [(d.code, d.span.line, d.span.column) for d in comp.diagnostics] == [
        ("W703", 5, 13), ("E102", 5, 24)]
    assert comp.program.line(comp.diagnostics[0].span.file, 5) == "      param p: float = nope"


def test_a_cr_file_is_reported_at_its_lines_by_the_cli(tmp_path: Path) -> None:
    text = ("// a comment\n" + spec(extra="      param p: float = nope\n")).replace("\n", "\r")
    (tmp_path / "mac.rssm").write_bytes(text.encode())
    r = rssmc("check", "mac.rssm", cwd=tmp_path)
    assert_clean_failure(r, "E102")
    assert "mac.rssm:5:24: error[E102]" in r.stderr
    assert "    5 |       param p: float = nope\n" in r.stderr


def test_the_compiler_never_splits_source_text_with_splitlines() -> None:
    # str.splitlines also splits on U+2028, \x0b, \x0c, ...: lines are split_lines (source.py)
    allowed = {"ros2/toolchain.py", "render/svg.py"}   # these split the output of programs
    offenders = []
    for path in sorted((ROOT / "rssm_dsl").rglob("*.py")):
        rel = path.relative_to(ROOT / "rssm_dsl").as_posix()
        tree = ast.parse(path.read_text(encoding="utf-8"))
        offenders += [f"{rel}:{node.lineno}" for node in ast.walk(tree)
                      if isinstance(node, ast.Attribute) and node.attr == "splitlines"
                      and rel not in allowed]
    assert offenders == []


# ================================================================ 5. U+2028, U+2029, U+0085

def test_line_separators_are_looked_for_in_line_comments_only() -> None:
    from rssm_dsl.semantics.loader import line_separators_in_comments as find

    assert find("a // b\u2028c\u2029\nd // e\x85") == (6, 3)
    assert find('"// \u2028" /* // \u2028 */ x') is None     # in a string, in a block comment
    assert find("/* never closed // \u2028") is None          # the block comment runs to the end
    assert find('"unclosed // \u2028\n// \u2028') == (18, 1)  # an unclosed string skips its line
    assert find("no separator // here") is None


@pytest.mark.parametrize("sep", ["\u2028", "\u2029", "\x85"])
def test_a_line_separator_in_a_comment_is_W012(tmp_path: Path, sep: str) -> None:
    text = ("// a comment\n" + spec()).replace("\n", sep)
    comp = compile_text(tmp_path, text)
    w012 = [d for d in comp.diagnostics if d.code == "W012"]
    assert len(w012) == 1
    d = w012[0]
    assert (d.span.line, d.span.column) == (1, 13)
    assert f"U+{ord(sep):04X}" in d.message and "does not end a line" in d.message
    count = text.count(sep)
    assert f"{count} " in d.message   # how many the comment holds
    assert d.hint is not None and "line break" in d.hint


def test_W012_once_per_file_at_the_first_comment(tmp_path: Path) -> None:
    text = "// one\u2028two\n// three\u2029four\n" + spec()
    comp = compile_text(tmp_path, text)
    assert [(d.code, d.span.line, d.span.column) for d in comp.diagnostics] == [("W012", 1, 7)]
    assert "2 " in comp.diagnostics[0].message


def test_a_line_separator_outside_comments_is_no_W012(tmp_path: Path) -> None:
    text = spec().replace('"', "")
    text = 'extern f() -> int = "m\u2028:f"\n' + text
    comp = compile_text(tmp_path, text)
    assert "W012" not in codes(comp)
    text = "/* a block\u2028comment */\n" + spec()
    assert codes(compile_text(tmp_path, text)) == []


def test_E006_names_a_line_separator(tmp_path: Path) -> None:
    comp = compile_text(tmp_path, spec().replace("\n", "\u2028", 1))
    d = next(d for d in comp.diagnostics if d.code == "E006")
    assert "U+2028 LINE SEPARATOR" in d.message and "not a line break" in d.message + (d.hint or "")


# ================================================================ 6. control characters are escaped

UNSAFE = [chr(c) for c in (*range(0x00, 0x09), *range(0x0a, 0x20), *range(0x7f, 0xa0),
                           *range(0x202a, 0x202f), *range(0x2066, 0x206a), 0x2028, 0x2029)]


def test_escape_controls() -> None:
    assert escape_controls("a\x07b\x1b[2J\u202ec\td\u00e9") == "a\\x07b\\x1b[2J\\u202ec\td\u00e9"
    assert not any(ch in escape_controls("".join(UNSAFE)) for ch in UNSAFE)


def test_control_characters_in_an_excerpt_are_escaped_and_the_caret_follows() -> None:
    src, caret = _excerpt("a\x07b \x1b[2J\u202e X", 11, 1)
    assert src == "a\\x07b \\x1b[2J\\u202e X"
    assert src[caret.index("^")] == "X"
    assert caret == " " * len(src[:-1]) + "^"


def test_a_control_character_span_is_escaped_under_its_caret() -> None:
    src, caret = _excerpt("x \x07 y", 3, 1)
    assert src == "x \\x07 y" and caret == "  ^^^^"


def test_a_spec_cannot_send_the_terminal_escape_sequences(tmp_path: Path) -> None:
    text = spec().replace("initial idle", "initial idle \x07 \x1b[2J\x9b2J") + \
        'import "evil\x1b[2J\u202e.rssm"\n'
    comp = compile_text(tmp_path, text)
    out = render_text(comp.diagnostics, comp.program.line)
    assert comp.diagnostics and not any(ch in out for ch in UNSAFE if ch != "\n")
    assert "\\x1b[2J" in out
    for d in comp.diagnostics:
        assert not any(ch in d.message for ch in UNSAFE), d.message


# ================================================================ the measured case

@pytest.mark.slow
def test_a_megabyte_single_line_file_prints_a_bounded_report(tmp_path: Path) -> None:
    text = "system s { " + "agent a { } " * 90_000 + "}"
    assert len(text) > 1_000_000
    (tmp_path / "mega.rssm").write_text(text)
    r = rssmc("check", "mega.rssm", cwd=tmp_path)
    assert_clean_failure(r, "E101")
    assert len(r.stderr) < 1_000_000 and len(r.stderr) < 30_000
    assert r.stderr.rstrip().endswith("mega.rssm: 90000 errors, 0 warnings")


# ================================================================ frequencies

@pytest.mark.parametrize(("hertz", "ok"), [("100 kHz", True), ("100000 Hz", True),
                                           ("100001 Hz", False), ("1e9 Hz", False),
                                           ("1e300 Hz", False), ("0 Hz", False),
                                           ("0.001 Hz", True)])
def test_a_frequency_is_positive_and_at_most_100_kHz(tmp_path: Path, hertz: str,
                                                      ok: bool) -> None:
    """A subsystem at 1 GHz was accepted, and a second of simulation was 10^9 iterations:
    E209 at the frequency, the spec refused."""
    text = spec().replace("@ 10 Hz", f"@ {hertz}")
    comp = compile_text(tmp_path, text)
    errors = [d for d in comp.diagnostics if d.is_error]
    if ok:
        assert not errors, errors
    else:
        assert [d.code for d in errors] == ["E209"] and errors[0].span.line == 3, errors
