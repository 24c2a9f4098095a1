"""Every quick fix and every rename gives a specification that parses and checks no worse
than before.

Exhaustive, in process: every spec of examples/diagnostics/ and deterministic mutations of
it (a declaration line deleted, a data-availability case dropped, a use made undeclared)
is analysed as the server analyses a document; every code action offered for each of its
diagnostics is applied, and every renameable declaration is renamed to a fresh name and to
the name of a declaration of its scope (which must be refused). A smaller test goes through
a real client (pytest-lsp).
"""

from __future__ import annotations

import re
from collections import Counter
from collections.abc import Iterator
from functools import cache
from pathlib import Path

import pytest
from lsprotocol import types as lsp
from pytest_lsp import LanguageClient

from rssm_dsl.diagnostics import Severity
from rssm_dsl.lsp.actions import Fixer
from rssm_dsl.lsp.analysis import Analysis, analyze_text
from rssm_dsl.lsp.convert import to_lsp
from rssm_dsl.lsp.index import Definition, SymbolIndex
from rssm_dsl.lsp.paths import path_of_display
from rssm_dsl.lsp.positions import UTF16
from rssm_dsl.lsp.rename import (
    RenameRefused,
    apply_edits,
    check_program,
    rename_in_program,
    target,
)
from rssm_dsl.lsp.server import FIXABLE
from rssm_dsl.semantics.loader import display_path
from tests.lsp.helpers import ROOT, close, open_doc, position_of
from tests.lsp.helpers import apply_edits as apply_lsp_edits

DIAGNOSTICS = ROOT / "examples" / "diagnostics"
SPECS = sorted(DIAGNOSTICS.glob("*.rssm"))

_DECLARATION = re.compile(r"^\s*(input|output|memory|param|switch|initial|send|receive|"
                          r"terminal|error|let|real)\b")
_CASE = re.compile(r"^\s*(case\b|otherwise\s*:)")
_ASSIGN = re.compile(r":=\s*([A-Za-z_][A-Za-z0-9_]*)")


def _analyze(path: Path, text: str, overrides: dict[Path, str] | None = None) -> Analysis:
    return analyze_text(path.as_uri(), path, display_path(path), text, 1, overrides or {},
                        None)


def _indent(line: str) -> int:
    return len(line) - len(line.lstrip())


def mutations(text: str) -> Iterator[tuple[str, str]]:
    """(what, mutated text): a declaration line deleted, a case (with its body) dropped, the
    name read by an assignment made undeclared."""
    lines = text.splitlines(keepends=True)
    for i, line in enumerate(lines):
        if _DECLARATION.match(line):
            yield f"line {i + 1} deleted", "".join(lines[:i] + lines[i + 1:])
        if _CASE.match(line):
            j = i + 1
            while j < len(lines) and lines[j].strip() and _indent(lines[j]) > _indent(line):
                j += 1
            yield f"case at line {i + 1} dropped", "".join(lines[:i] + lines[j:])
        m = _ASSIGN.search(line)
        if m is not None and m.group(1) not in ("if", "not", "true", "false"):
            changed = line[:m.start(1)] + m.group(1) + "_undeclared" + line[m.end(1):]
            yield f"use at line {i + 1} undeclared", "".join([*lines[:i], changed, *lines[i + 1:]])


def _errors(a: Analysis) -> int:
    return sum(d.severity is Severity.ERROR for d in a.diagnostics)


def _syntax(a: Analysis) -> int:
    """The errors of the parser and the loader (E0xx)."""
    return sum(d.code.startswith("E0") for d in a.diagnostics)


def _first_line(d: lsp.Diagnostic) -> tuple[str, str]:
    return str(d.code), d.message.split("\n")[0]


def check_actions(path: Path, text: str, what: str, applied: Counter[str] | None = None
                  ) -> list[str]:
    """Apply every code action offered for every diagnostic of `text`: the problems found.
    `applied` counts the actions applied by the code of their diagnostic."""
    a = _analyze(path, text)
    if applied is None:
        applied = Counter()
    if a.module is None:
        return []
    problems: list[str] = []
    fixer = Fixer(a.uri, a.module, a.text, a.lines, UTF16)
    for d in a.diagnostics:
        diag = to_lsp(d, a.lines, UTF16, lambda s: None)
        for action in fixer.fixes(diag):
            assert action.edit is not None and action.edit.changes is not None
            assert set(action.edit.changes) == {a.uri}, action.edit.changes
            new = apply_lsp_edits(text, list(action.edit.changes[a.uri]))
            b = _analyze(path, new)
            applied[d.code] += 1
            where = f"{path.name} ({what}): {action.title!r} for {d.code} {d.message!r}"
            if _syntax(b) > _syntax(a):
                problems.append(f"{where} gives a file that does not parse: "
                                f"{[(x.code, x.message) for x in b.diagnostics]}")
            elif _errors(b) > _errors(a):
                problems.append(f"{where} adds errors: {[x.code for x in a.diagnostics]} -> "
                                f"{[x.code for x in b.diagnostics]}")
            after = Counter(_first_line(to_lsp(x, b.lines, UTF16, lambda s: None))
                            for x in b.diagnostics)
            before = Counter(_first_line(to_lsp(x, a.lines, UTF16, lambda s: None))
                             for x in a.diagnostics)
            if action.is_preferred and after[_first_line(diag)] >= before[_first_line(diag)]:
                problems.append(f"{where} leaves its diagnostic: "
                                f"{[(x.code, x.message) for x in b.diagnostics]}")
    return problems


def _cases() -> Iterator[tuple[Path, str, str]]:
    for path in SPECS:
        text = path.read_text(encoding="utf-8")
        yield path, text, "as written"
        for what, mutated in mutations(text):
            yield path, mutated, what


def test_every_code_action_gives_a_spec_that_parses_and_checks_no_worse() -> None:
    problems: list[str] = []
    applied: Counter[str] = Counter()
    for path, text, what in _cases():
        problems += check_actions(path, text, what, applied)
    assert not problems, "\n".join(problems[:20])
    # the mutations reach every quick fix the server offers, many times
    assert set(applied) == FIXABLE and min(applied.values()) > 20, applied


def test_the_e304_fix_declares_an_array_buffer_that_parses() -> None:
    """The quick fix of E304 copied the buffer's type from its span, which stops before the
    closing bracket of an array type: `float[2`."""
    path = DIAGNOSTICS / "E304_unpaired-buffer.rssm"
    text = path.read_text(encoding="utf-8").replace(
        "      output aim: float[2] to e.ptz\n", "", 1)
    a = _analyze(path, text)
    [diag] = [to_lsp(d, a.lines, UTF16, lambda s: None) for d in a.diagnostics
              if d.code == "E304" and "'aim'" in d.message]
    assert a.module is not None
    [action] = Fixer(a.uri, a.module, a.text, a.lines, UTF16).fixes(diag)
    assert action.title == "Declare `output aim: float[2] to e.ptz` in head.c"
    applied: Counter[str] = Counter()
    assert check_actions(path, text, "output aim deleted", applied) == []
    assert applied == {"E304": 2}


def test_the_e304_fix_is_not_offered_when_the_name_is_taken() -> None:
    """The peer already declares a buffer of that name (in the wrong direction): declaring
    another would be a duplicate (E101)."""
    path = DIAGNOSTICS / "E304_unpaired-buffer.rssm"
    text = path.read_text(encoding="utf-8").replace(
        "      output aim: float[2] to e.ptz\n",
        "      output aim: float[2] to e.ptz\n      input zoom_level: float from e.ptz\n", 1)
    a = _analyze(path, text)
    assert a.module is not None
    fixer = Fixer(a.uri, a.module, a.text, a.lines, UTF16)
    for d in a.diagnostics:
        for action in fixer.fixes(to_lsp(d, a.lines, UTF16, lambda s: None)):
            assert "zoom_level" not in action.title
    assert check_actions(path, text, "zoom_level on both sides") == []


# ---------------------------------------------------------------------- rename
_NAMESPACES = (("buf:", "mem:", "param:"), ("devbuf:", "devparam:"),
               ("type:", "const:", "extern:", "device:"))


def _namespace(key: str) -> tuple[str, ...]:
    prefix = key.split(":", 1)[0] + ":"
    return next((n for n in _NAMESPACES if prefix in n), (prefix,))


def _same_scope(index: SymbolIndex, d: Definition) -> list[Definition]:
    """The other declarations of the scope of `d` (by which a rename must be refused)."""
    space = _namespace(d.key)
    out = [x for x in index.definitions.values() if x.key != d.key and x.name != d.name
           and x.key.startswith(space) and x.renameable
           and (x.container == d.container or space == _NAMESPACES[2])]
    return sorted(out, key=lambda x: x.key)[:2]


def _texts(path: Path, overrides: dict[Path, str]) -> dict[str, str]:
    return {f: s.text for f, s in check_program(path, overrides).program.sources.items()}


def check_renames(path: Path, text: str, what: str) -> tuple[list[str], Counter[str]]:
    """Rename every renameable declaration of the file to a fresh name (accepted, and the
    program checks with the same diagnostics) and to the name of another declaration of its
    scope (refused, the message naming it). The problems, and the renames done by kind."""
    overrides = {path.resolve(): text}
    checked = check_program(path, overrides)
    display = display_path(path)
    index = checked.index
    before = _analyze(path, text)
    problems: list[str] = []
    done: Counter[str] = Counter()
    seen: set[str] = set()
    for occ in index.occurrences.get(display, []):
        found = target(index, display, occ.span.offset)
        if found is None or found[1].key in seen:
            continue
        d = found[1]
        seen.add(d.key)
        where = f"{path.name} ({what}): {d.kind} '{d.name}' at line {occ.span.line}"
        # prepareRename answers at every occurrence of the name
        for other in index.references(d.key):
            if other.span.file == display:
                again = target(index, display, other.span.offset)
                if again is None or again[1].key != d.key:
                    problems.append(f"{where}: no rename at line {other.span.line}")
        fresh = f"{d.name}_rn"
        try:
            edits = rename_in_program(path, overrides, occ.span.offset, fresh)
        except RenameRefused as e:
            problems.append(f"{where}: renaming to a fresh name is refused: {e}")
            continue
        done[d.kind] += 1
        texts = _texts(path, overrides)
        renamed = dict(overrides)
        for file, fe in edits.items():
            renamed[path_of_display(file).resolve()] = apply_edits(texts[file], fe)
        after = _analyze(path, renamed[path.resolve()], renamed)
        codes = sorted(x.code for x in before.diagnostics)
        if sorted(x.code for x in after.diagnostics) != codes:
            problems.append(f"{where}: renamed to '{fresh}', it checks differently: {codes} -> "
                            f"{sorted(x.code for x in after.diagnostics)}")
        if re.search(rf"(?<![A-Za-z0-9_]){fresh}(?![A-Za-z0-9_])",
                     texts[display]) is None and fresh not in renamed[path.resolve()]:
            problems.append(f"{where}: renaming to '{fresh}' edits nothing")
        for other in _same_scope(index, d):
            try:
                rename_in_program(path, overrides, occ.span.offset, other.name)
            except RenameRefused as e:
                if f"'{other.name}'" not in str(e):
                    problems.append(f"{where}: the refusal of '{other.name}' does not name it: "
                                    f"{e}")
                continue
            problems.append(f"{where}: renaming to '{other.name}' ({other.kind} of the same "
                            "scope) is accepted")
    return problems, done


@cache
def _all_rename_results() -> tuple[list[str], Counter[str]]:
    problems: list[str] = []
    done: Counter[str] = Counter()
    for path in SPECS:
        found, kinds = check_renames(path, path.read_text(encoding="utf-8"), "as written")
        problems += found
        done += kinds
    return problems, done


def test_every_rename_checks_the_same_and_clashes_are_refused() -> None:
    problems, done = _all_rename_results()
    assert not problems, "\n".join(problems[:20])
    for kind in ("field", "behaviour", "input buffer", "output buffer", "parameter", "agent",
                 "memory", "record", "constant", "enum member", "terminal condition",
                 "effector subsystem", "property", "input buffer of a device"):
        assert done[kind], (kind, done)


def _renames_of_mutants(every: int) -> None:
    problems: list[str] = []
    for path in SPECS:
        for what, mutated in list(mutations(path.read_text(encoding="utf-8")))[::every]:
            problems += check_renames(path, mutated, what)[0]
    assert not problems, "\n".join(problems[:20])


@pytest.mark.slow
def test_every_rename_of_some_mutated_specs() -> None:
    """Every 16th mutant of each spec (18 s; the long variant below takes every 4th)."""
    _renames_of_mutants(16)


@pytest.mark.long
def test_every_rename_of_the_mutated_specs() -> None:
    _renames_of_mutants(4)


# ---------------------------------------------------------------------- a real client
pytestmark_client = pytest.mark.asyncio(loop_scope="module")


def _id(path: Path) -> lsp.TextDocumentIdentifier:
    return lsp.TextDocumentIdentifier(uri=path.as_uri())


@pytestmark_client
async def test_every_code_action_through_the_client(client: LanguageClient,
                                                    tmp_path: Path) -> None:
    """The actions the server offers for the E304, E501 and E603 examples (and the array
    buffer of E304 deleted) give files that parse and check no worse."""
    cases = [(name, (DIAGNOSTICS / name).read_text(encoding="utf-8")) for name in
             ("E304_unpaired-buffer.rssm", "E501_cases-not-exhaustive.rssm",
              "E603_switch-not-exhaustive.rssm")]
    cases.append(("E304_array.rssm", cases[0][1].replace(
        "      output aim: float[2] to e.ptz\n", "", 1)))
    for name, text in cases:
        path = tmp_path / name
        diags = await open_doc(client, path, text)
        errors = sum(d.severity == lsp.DiagnosticSeverity.Error for d in diags)
        actions = await client.text_document_code_action_async(lsp.CodeActionParams(
            text_document=_id(path), range=diags[-1].range,
            context=lsp.CodeActionContext(diagnostics=diags)))
        assert actions, name
        for action in actions:
            assert isinstance(action, lsp.CodeAction) and action.edit is not None
            assert action.edit.changes is not None
            new = apply_lsp_edits(text, list(action.edit.changes[path.as_uri()]))
            after = _analyze(path, new)
            assert _syntax(after) == 0, (name, action.title, after.diagnostics)
            assert sum(d.severity is Severity.ERROR for d in after.diagnostics) <= errors
            if action.is_preferred:
                assert action.diagnostics is not None
                assert _first_line(action.diagnostics[0]) not in {
                    _first_line(to_lsp(x, after.lines, UTF16, lambda s: None))
                    for x in after.diagnostics}
        close(client, path)


@pytestmark_client
async def test_rename_through_the_client(client: LanguageClient, tmp_path: Path) -> None:
    """A record field renamed through the client: its uses in the importing file and the
    module that declares it; a name of the same record refused with a JSON-RPC error."""
    helper = tmp_path / "E010_helper.rssm"
    main = tmp_path / "E010_import-cycle.rssm"
    helper_text = (DIAGNOSTICS / helper.name).read_text(encoding="utf-8")
    main_text = (DIAGNOSTICS / main.name).read_text(encoding="utf-8")
    helper.write_text(helper_text, encoding="utf-8")
    main.write_text(main_text, encoding="utf-8")
    await open_doc(client, main, main_text)
    pos = position_of(main_text, "cmd.vx", delta=5)
    prep = await client.text_document_prepare_rename_async(lsp.PrepareRenameParams(
        text_document=_id(main), position=pos))
    assert isinstance(prep, lsp.PrepareRenamePlaceholder) and prep.placeholder == "vx"
    edit = await client.text_document_rename_async(lsp.RenameParams(
        text_document=_id(main), position=pos, new_name="forward"))
    assert edit is not None and edit.changes is not None
    assert set(edit.changes) == {main.as_uri(), helper.as_uri()}
    new_main = apply_lsp_edits(main_text, list(edit.changes[main.as_uri()]))
    new_helper = apply_lsp_edits(helper_text, list(edit.changes[helper.as_uri()]))
    assert "  forward: float\n" in new_helper
    assert "{forward: max_speed, vy: 0.0, wz: 0.1}" in new_main
    assert "{forward: clamp(cmd.forward, -max_speed, max_speed)," in new_main
    assert not re.search(r"\bvx\b", new_main.split("import")[1])
    with pytest.raises(Exception, match="field 'wz' is already declared in record Twist2"):
        await client.text_document_rename_async(lsp.RenameParams(
            text_document=_id(main), position=pos, new_name="wz"))
    close(client, main)
