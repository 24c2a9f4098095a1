"""Every spec in examples/diagnostics/ triggers exactly the diagnostics written inline on the
offending lines, mypy style:

    input twist: float[2] form c   // expect: E005
    update torque {                // expect: E501 "new(setpoint) and not new(state)"
    send left | left               // expect: E606, E607 "appears twice"

A quoted fragment must occur in the message. A diagnostic past the end of a file counts as
on its last line. Expectations are collected from every non-stdlib file the program loaded
(so a helper module can carry the expectation of the import that closes a cycle).
"""

from __future__ import annotations

import re
from dataclasses import dataclass
from pathlib import Path

import pytest

from rssm_dsl.diagnostics import Diagnostic
from rssm_dsl.diagnostics.codes import BY_CODE, CODES
from rssm_dsl.diagnostics.render import render_text
from rssm_dsl.pipeline import Compilation, compile_file
from rssm_dsl.semantics.loader import STDLIB_PREFIX
from tests.conftest import EXAMPLES

DIAGNOSTICS = EXAMPLES / "diagnostics"
# Problems with the file itself, and the compiler's own failure: tested through the CLI.
CLI_ONLY = frozenset({"E001", "E002", "E003", "E004", "E900"})
# The backends' codes (8xx: simulate, render) are never reported by compiling a spec.
BACKEND = frozenset(c.code for c in CODES if c.code[1] == "8")

_ITEM = r'([A-Z]\d{3})(?:\s+"([^"]*)")?'
_EXPECT = re.compile(r"//\s*expect:(.*)$")
_LIST = re.compile(rf"\s*{_ITEM}(?:\s*,\s*{_ITEM})*\s*")
_SYSTEM = re.compile(r"^\s*system\s+[A-Za-z_]\w*\s*\{", re.MULTILINE)


@dataclass(frozen=True, order=True)
class Mark:
    """One diagnostic, expected or reported: where, which code, which message fragment."""

    file: str
    line: int
    code: str
    fragment: str | None = None

    def __str__(self) -> str:
        text = f"{self.file}:{self.line}: {self.code}"
        return text + (f' "{self.fragment}"' if self.fragment is not None else "")


def parse_expectations(file: str, text: str) -> list[Mark]:
    """The `// expect:` marks of one file. A malformed mark is an error, not ignored."""
    marks: list[Mark] = []
    for number, line in enumerate(text.splitlines(), start=1):
        found = _EXPECT.search(line)
        if found is None:
            continue
        body = found.group(1)
        if not _LIST.fullmatch(body):
            raise ValueError(f"{file}:{number}: malformed expectation {body.strip()!r}; "
                             'write `// expect: E501` or `// expect: E501 "fragment", W702`')
        for item in re.finditer(_ITEM, body):
            code, fragment = item.group(1), item.group(2)
            if code not in BY_CODE:
                raise ValueError(f"{file}:{number}: {code} is not a registered code")
            marks.append(Mark(file, number, code, fragment))
    return marks


def expected_marks(comp: Compilation) -> set[Mark]:
    out: set[Mark] = set()
    for file, source in comp.program.sources.items():
        if not file.startswith(STDLIB_PREFIX):
            out.update(parse_expectations(file, source.text))
    return out


def reported_marks(comp: Compilation, expected: set[Mark]) -> dict[Mark, Diagnostic]:
    """Each diagnostic as a mark; its fragment is that of the expectation it satisfies."""
    out: dict[Mark, Diagnostic] = {}
    for d in comp.diagnostics:
        line = d.span.line
        source = comp.program.sources.get(d.span.file)
        if source is not None:
            line = min(line, max(1, len(source.text.splitlines())))
        fragments = [m.fragment for m in expected
                     if (m.file, m.line, m.code) == (d.span.file, line, d.code)
                     and (m.fragment is None or m.fragment in d.message)]
        # prefer an expectation with a fragment the message satisfies
        fragment = next((f for f in fragments if f is not None), None)
        out[Mark(d.span.file, line, d.code, fragment)] = d
    return out


def mismatch(comp: Compilation) -> str | None:
    """None when the reported diagnostics are exactly the expected ones, else a report."""
    expected = expected_marks(comp)
    reported = reported_marks(comp, expected)
    if set(reported) == expected:
        return None
    lines = ["expected but not reported:"]
    lines += [f"  {m}" for m in sorted(expected - set(reported))] or ["  (none)"]
    lines.append("reported but not expected:")
    lines += [f"  {m}: {reported[m].message}" for m in sorted(set(reported) - expected)] or [
        "  (none)"]
    lines.append("all diagnostics:")
    lines.append(render_text(comp.diagnostics, comp.program.line) or "  (none)")
    return "\n".join(lines)


def root_specs() -> list[Path]:
    """The specs compiled as programs: those declaring a system, and the E104 no-system file
    (helper modules they import are not compiled on their own)."""
    return [p for p in sorted(DIAGNOSTICS.glob("*.rssm"))
            if _SYSTEM.search(p.read_text(encoding="utf-8")) or p.name.startswith("E104_")]


def _code_of(spec: Path) -> str:
    return spec.name.split("_", 1)[0]


SPECS = root_specs()


@pytest.mark.parametrize("spec", SPECS, ids=lambda p: p.name)
def test_spec_reports_exactly_its_expectations(spec: Path) -> None:
    comp = compile_file(spec)
    problem = mismatch(comp)
    assert problem is None, f"{spec.name}:\n{problem}"
    assert _code_of(spec) in {d.code for d in comp.diagnostics}, (
        f"{spec.name} is named for {_code_of(spec)} but does not trigger it")


def test_every_code_has_a_spec() -> None:
    wanted = {c.code for c in CODES} - CLI_ONLY - BACKEND
    covered = {_code_of(p) for p in SPECS}
    assert sorted(wanted - covered) == [], "codes without a spec in examples/diagnostics/"
    assert sorted(covered - wanted) == [], "specs named for unknown or CLI-only codes"


@pytest.mark.parametrize("spec", SPECS, ids=lambda p: p.name)
def test_spec_is_named_code_and_slug(spec: Path) -> None:
    code, _, rest = spec.stem.partition("_")
    assert rest == BY_CODE[code].slug, f"name it {code}_{BY_CODE[code].slug}.rssm"


# ---------------------------------------------------------------- the harness itself

def test_expectation_syntax() -> None:
    text = 'a\nx := 1 // expect: E501 "no, case", W702\n// expect:E101\n'
    assert parse_expectations("f", text) == [
        Mark("f", 2, "E501", "no, case"), Mark("f", 2, "W702"), Mark("f", 3, "E101")]
    with pytest.raises(ValueError, match="malformed"):
        parse_expectations("f", "// expect: E501 missing quotes\n")
    with pytest.raises(ValueError, match="not a registered code"):
        parse_expectations("f", "// expect: E999\n")


def _compile_text(tmp_path: Path, text: str) -> Compilation:
    path = tmp_path / "spec.rssm"
    path.write_text(text, encoding="utf-8")
    return compile_file(path)


def test_mismatches_are_caught(tmp_path: Path) -> None:
    base = (DIAGNOSTICS / "W703_unused-param.rssm").read_text(encoding="utf-8")
    assert mismatch(_compile_text(tmp_path, base)) is None
    unexpected = re.sub(r" // expect: W703.*", "", base)
    assert "reported but not expected" in (mismatch(_compile_text(tmp_path, unexpected)) or "")
    wrong_fragment = base.replace('"param', '"memory')
    report = mismatch(_compile_text(tmp_path, wrong_fragment)) or ""
    assert "expected but not reported" in report and "memory 'max_speed'" in report
    missing = base.replace("      input angle: float from c",
                           "      input angle: float from c // expect: W701")
    assert "W701" in (mismatch(_compile_text(tmp_path, missing)) or "")
