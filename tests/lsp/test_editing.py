"""Formatting and quick fixes through the server."""

from __future__ import annotations

from pathlib import Path

import pytest
from lsprotocol import types as lsp
from pytest_lsp import LanguageClient

from rssm_dsl.pipeline import compile_file
from rssm_dsl.syntax.format import format_text
from tests.lsp.helpers import apply_edits, close, open_doc
from tests.lsp.specs import GOOD, MISSING_BUFFER, MISSING_CASE, MISSING_NAMED_BUFFER, MISSING_SWITCH

pytestmark = pytest.mark.asyncio(loop_scope="module")


def _id(path: Path) -> lsp.TextDocumentIdentifier:
    return lsp.TextDocumentIdentifier(uri=path.as_uri())


async def test_formatting_returns_the_canonical_text(client: LanguageClient,
                                                     tmp_path: Path) -> None:
    messy = GOOD.replace("  agent a1 {", "agent   a1{").replace(
        "phase := phase + 0.01 * 2.0 * pi / period", "phase:=phase+0.01*2.0*pi/period  // ü")
    path = tmp_path / "messy.rssm"
    await open_doc(client, path, messy)
    edits = await client.text_document_formatting_async(lsp.DocumentFormattingParams(
        text_document=_id(path), options=lsp.FormattingOptions(tab_size=2,
                                                                insert_spaces=True)))
    assert edits
    formatted = apply_edits(messy, list(edits))
    assert formatted == format_text(messy).text
    assert formatted == GOOD.replace("phase := phase + 0.01 * 2.0 * pi / period",
                                     "phase := phase + 0.01 * 2.0 * pi / period  // ü")
    close(client, path)


async def test_formatting_leaves_text_with_syntax_errors_alone(client: LanguageClient,
                                                               tmp_path: Path) -> None:
    path = tmp_path / "broken.rssm"
    await open_doc(client, path, "system s { agent a1 { control {")
    edits = await client.text_document_formatting_async(lsp.DocumentFormattingParams(
        text_document=_id(path), options=lsp.FormattingOptions(tab_size=2,
                                                                insert_spaces=True)))
    assert not edits
    close(client, path)


async def _fix(client: LanguageClient, tmp_path: Path, text: str, code: str,
               title_part: str) -> str:
    """Open `text`, ask for the code actions of its `code` diagnostic, apply the one whose
    title contains `title_part`, and return the new text (checked by the compiler)."""
    path = tmp_path / f"fix_{code}.rssm"
    diags = await open_doc(client, path, text)
    wanted = [d for d in diags if d.code == code]
    assert wanted, diags
    actions = await client.text_document_code_action_async(lsp.CodeActionParams(
        text_document=_id(path), range=wanted[0].range,
        context=lsp.CodeActionContext(diagnostics=wanted)))
    assert actions
    chosen = [a for a in actions if isinstance(a, lsp.CodeAction) and title_part in a.title]
    assert len(chosen) == 1, [a.title for a in actions]
    action = chosen[0]
    assert action.kind == lsp.CodeActionKind.QuickFix and action.edit is not None
    assert action.edit.changes is not None
    new = apply_edits(text, list(action.edit.changes[path.as_uri()]))
    close(client, path)
    return new


async def test_quick_fix_adds_the_missing_data_availability_cases(
        client: LanguageClient, tmp_path: Path) -> None:
    new = await _fix(client, tmp_path, MISSING_CASE, "E501", "missing data-availability")
    assert ("          case new(setpoint) and not new(state):\n            skip\n"
            "          case not new(setpoint) and not new(state):\n            skip\n"
            "        }\n") in new
    (tmp_path / "fixed.rssm").write_text(new, encoding="utf-8")
    assert compile_file(tmp_path / "fixed.rssm").diagnostics == ()


async def test_quick_fix_adds_an_otherwise_case(client: LanguageClient,
                                                tmp_path: Path) -> None:
    new = await _fix(client, tmp_path, MISSING_CASE, "E501", "`otherwise:`")
    assert new == GOOD


async def test_quick_fix_adds_the_missing_otherwise_switch(client: LanguageClient,
                                                           tmp_path: Path) -> None:
    new = await _fix(client, tmp_path, MISSING_SWITCH, "E603", "switch ccw -> end otherwise")
    assert "      switch cw -> ccw when full_circle\n      switch ccw -> end otherwise\n" in new
    (tmp_path / "fixed.rssm").write_text(new, encoding="utf-8")
    assert compile_file(tmp_path / "fixed.rssm").ok


async def test_quick_fix_declares_the_missing_buffer(client: LanguageClient,
                                                     tmp_path: Path) -> None:
    new = await _fix(client, tmp_path, MISSING_BUFFER, "E304", "Declare")
    assert ("      output torque: JointVec7 to E.lwr nonblocking\n"
            "      output fb: float to c blocking\n") in new
    (tmp_path / "fixed.rssm").write_text(new, encoding="utf-8")
    codes = {d.code for d in compile_file(tmp_path / "fixed.rssm").diagnostics}
    assert "E304" not in codes
    new = await _fix(client, tmp_path, MISSING_NAMED_BUFFER, "E304", "Declare")
    assert ("      output torque: JointVec7 to E.lwr nonblocking\n"
            "      input gain: float from c\n") in new
    (tmp_path / "fixed.rssm").write_text(new, encoding="utf-8")
    codes = {d.code for d in compile_file(tmp_path / "fixed.rssm").diagnostics}
    assert "E304" not in codes
