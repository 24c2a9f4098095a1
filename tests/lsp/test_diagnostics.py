"""Diagnostics: every compiler diagnostic, with its code and documentation link, at the right
place in the client's position encoding; broken edits keep the rest."""

from __future__ import annotations

from pathlib import Path

import pytest
from lsprotocol import types as lsp
from pytest_lsp import LanguageClient

from tests.lsp.helpers import change, close, diagnostics_of, open_doc
from tests.lsp.specs import BROKEN_CW, GOOD, MISSING_CASE

pytestmark = pytest.mark.asyncio(loop_scope="module")


async def test_the_example_is_clean(client: LanguageClient, tmp_path: Path) -> None:
    diags = await open_doc(client, tmp_path / "good.rssm", GOOD)
    close(client, tmp_path / "good.rssm")
    assert diags == []


async def test_missing_case_has_code_link_and_range(client: LanguageClient,
                                                    tmp_path: Path) -> None:
    path = tmp_path / "case.rssm"
    diags = await open_doc(client, path, MISSING_CASE)
    close(client, path)
    [d] = [d for d in diags if d.code == "E501"]
    assert d.severity == lsp.DiagnosticSeverity.Error
    assert d.source == "rssmc"
    assert d.code_description is not None
    assert d.code_description.href.endswith("/docs/diagnostics.md#e501")
    assert "new(setpoint) and not new(state)" in d.message
    line = MISSING_CASE.splitlines()[d.range.start.line]
    assert line[d.range.start.character:d.range.end.character] == "torque"
    assert "update torque" in line


async def test_positions_count_utf16_code_units(client: LanguageClient, tmp_path: Path) -> None:
    """A name after astral-plane and accented characters on the same line."""
    original = "param radius: float = 0.05"
    edited = 'param radius: float = /* 😀 émoji 🤖 */ 0.05 + nowhere'
    text = GOOD.replace(original, edited, 1)
    path = tmp_path / "utf16.rssm"
    diags = await open_doc(client, path, text)
    close(client, path)
    [d] = [d for d in diags if d.code == "E102"]
    line = text.splitlines()[d.range.start.line]
    col = line.index("nowhere")
    assert d.range.start.character == len(line[:col].encode("utf-16-le")) // 2
    assert d.range.start.character == col + 2  # two astral characters, two code units each
    assert d.range.end.character == d.range.start.character + len("nowhere")


async def test_a_broken_edit_keeps_the_outline_and_the_other_diagnostics(
        client: LanguageClient, tmp_path: Path) -> None:
    path = tmp_path / "broken.rssm"
    before = await open_doc(client, path, MISSING_CASE)
    assert [d.code for d in before] == ["E501"]
    change(client, path, BROKEN_CW, 2)
    after = await diagnostics_of(client, path.as_uri(), 2)
    codes = [d.code for d in after]
    assert "E005" in codes            # the new syntax error ...
    assert "E501" in codes            # ... and the error elsewhere in the file, still there
    e501 = next(d for d in after if d.code == "E501")
    assert e501.range == next(d for d in before if d.code == "E501").range
    symbols = await client.text_document_document_symbol_async(lsp.DocumentSymbolParams(
        text_document=lsp.TextDocumentIdentifier(uri=path.as_uri())))
    assert symbols is not None
    [system] = symbols
    [agent] = system.children or []
    names = {s.name: [b.name for b in (s.children or []) if b.kind == lsp.SymbolKind.Method]
             for s in agent.children or [] if s.kind == lsp.SymbolKind.Class}
    assert names == {"c": ["cw", "ccw"], "lwr": ["move"]}
    change(client, path, MISSING_CASE, 3)
    assert [d.code for d in await diagnostics_of(client, path.as_uri(), 3)] == ["E501"]
    close(client, path)


async def test_unsaved_text_of_an_imported_document_is_used(client: LanguageClient,
                                                           tmp_path: Path) -> None:
    lib = tmp_path / "mylib.rssm"
    main = tmp_path / "main.rssm"
    lib_text = "record Gain {\n  k: float\n}\n"
    lib.write_text(lib_text, encoding="utf-8")
    main_text = GOOD.replace("import lwr4plus\n", "import lwr4plus\nimport mylib\n").replace(
        "param period: float = 2.0", "param period: float = 2.0\n      memory g: Gain2")
    await open_doc(client, lib, lib_text)
    diags = await open_doc(client, main, main_text)
    assert [d.code for d in diags if d.code == "E202"] == ["E202"]   # Gain2 is unknown
    # add Gain2 to the library without saving it: the importer is analysed again
    change(client, lib, lib_text + "record Gain2 {\n  k: float\n}\n", 2)
    for _ in range(100):
        diags = list(client.diagnostics.get(main.as_uri(), []))
        if not any(d.code == "E202" for d in diags):
            break
        await __import__("asyncio").sleep(0.05)
    assert not any(d.code == "E202" for d in diags)
    close(client, main)
    close(client, lib)


async def test_library_files_are_not_asked_for_a_system(client: LanguageClient,
                                                        tmp_path: Path) -> None:
    path = tmp_path / "types_only.rssm"
    diags = await open_doc(client, path, "type V = float[3]\nrecord R { v: V2 }\n")
    close(client, path)
    assert [d.code for d in diags] == ["E202"]
