"""The language server on agents defined once and instantiated (examples/fleet.rssm): no
diagnostics, hover and go-to-definition from an instance's agent name, its definition and
its arguments, references of a definition and rename of it across its instance lines."""

from __future__ import annotations

from pathlib import Path

import pytest
from lsprotocol import types as lsp
from pytest_lsp import LanguageClient

from tests.lsp.helpers import ROOT, apply_edits, close, open_doc, position_of

pytestmark = pytest.mark.asyncio(loop_scope="module")
FLEET = (ROOT / "examples" / "fleet.rssm").read_text(encoding="utf-8")


def _id(path: Path) -> lsp.TextDocumentIdentifier:
    return lsp.TextDocumentIdentifier(uri=path.as_uri())


def _line(text: str, loc: lsp.Location) -> str:
    return text.splitlines()[loc.range.start.line]


async def _definition(client: LanguageClient, path: Path, pos: lsp.Position) -> lsp.Location:
    result = await client.text_document_definition_async(lsp.DefinitionParams(
        text_document=_id(path), position=pos))
    assert isinstance(result, list) and len(result) == 1, result
    assert isinstance(result[0], lsp.Location)
    return result[0]


async def _hover(client: LanguageClient, path: Path, pos: lsp.Position) -> str:
    h = await client.text_document_hover_async(lsp.HoverParams(text_document=_id(path),
                                                               position=pos))
    assert h is not None and isinstance(h.contents, lsp.MarkupContent)
    return h.contents.value


async def test_navigation_across_instances(client: LanguageClient, tmp_path: Path) -> None:
    path = tmp_path / "fleet.rssm"
    text = FLEET
    assert await open_doc(client, path, text) == []
    # `to r3.c` -> the indexed line that declares r3
    loc = await _definition(client, path, position_of(text, "to r3.c", delta=3))
    assert _line(text, loc).strip().startswith("agent r[1..6]: Robot")
    # `to r8.c` -> r8's own line
    loc = await _definition(client, path, position_of(text, "to r8.c", delta=3))
    assert _line(text, loc).strip().startswith("agent r8: Robot")
    # the definition named by an instance line, and a parameter it sets
    loc = await _definition(client, path, position_of(text, "r7: Robot", delta=5))
    assert _line(text, loc).startswith("agent Robot(")
    loc = await _definition(client, path, position_of(text, "shift = 3", delta=1))
    assert _line(text, loc).startswith("agent Robot(") and \
        loc.range.start.character == text.splitlines()[loc.range.start.line].index("shift")
    # an agent parameter's value is the agent
    loc = await _definition(client, path, position_of(text, "r7: Robot(boss = coord",
                                                      delta=17))
    assert _line(text, loc).strip() == "agent coord {"
    # inside the definition, its value parameter and its own names
    loc = await _definition(client, path, position_of(text, "done >= shift", delta=9))
    assert _line(text, loc).startswith("agent Robot(")
    loc = await _definition(client, path, position_of(text, "when hired", delta=6))
    assert "terminal hired" in _line(text, loc)
    said = await _hover(client, path, position_of(text, "r8: Robot", delta=5))
    assert "agent definition" in said and "Robot" in said
    said = await _hover(client, path, position_of(text, "to r3.c", delta=3))
    assert "r3" in said
    close(client, path)


async def test_references_and_rename_of_a_definition(client: LanguageClient,
                                                     tmp_path: Path) -> None:
    path = tmp_path / "fleet.rssm"
    text = FLEET
    assert await open_doc(client, path, text) == []
    pos = position_of(text, "agent Robot(", delta=7)
    refs = await client.text_document_references_async(lsp.ReferenceParams(
        text_document=_id(path), position=pos,
        context=lsp.ReferenceContext(include_declaration=True)))
    assert refs is not None     # (other files of the workspace may define a Robot too)
    lines = sorted(_line(text, r).strip() for r in refs if r.uri == path.as_uri())
    assert len(lines) == 4 and lines[0].startswith("agent Robot(")
    assert sum(x.startswith("agent r") for x in lines) == 3
    edit = await client.text_document_rename_async(lsp.RenameParams(
        text_document=_id(path), position=pos, new_name="Rover"))
    assert edit is not None and edit.changes is not None
    new = apply_edits(text, list(edit.changes[path.as_uri()]))
    assert "agent Rover(boss: agent" in new and new.count(": Rover(boss = coord") == 3
    assert "Robot(" not in new and "Robot " not in new
    close(client, path)
