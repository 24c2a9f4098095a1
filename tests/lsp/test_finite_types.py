"""The language server on enumerations and ranges: hover shows the enum (and its members) and
the type of a range-typed variable, `Phase.` completes the members, go to definition leads
from a member's use to its declaration, the outline lists the enum and its members."""

from __future__ import annotations

from collections.abc import AsyncIterator
from pathlib import Path

import pytest
import pytest_asyncio
from lsprotocol import types as lsp
from pytest_lsp import LanguageClient

from tests.lsp.helpers import close, open_doc, position_of

pytestmark = pytest.mark.asyncio(loop_scope="module")

SPEC = """enum Phase { idle, approach, grasp }

system s {
  agent a1 {
    control c {
      memory phase: Phase = Phase.idle
      memory retries: 0..3 = 0

      behaviour b {
        update memory {
          retries := retries + 1
          phase := if retries > 1 then Phase.grasp else Phase.approach
        }
        terminal t when phase == Phase.grasp
      }
      initial b
      switch b -> end when t
    }
  }
}
"""


@pytest_asyncio.fixture(loop_scope="module")
async def doc(client: LanguageClient, tmp_path: Path) -> AsyncIterator[Path]:
    path = tmp_path / "phases.rssm"
    assert await open_doc(client, path, SPEC) == []
    yield path
    close(client, path)


def _id(path: Path) -> lsp.TextDocumentIdentifier:
    return lsp.TextDocumentIdentifier(uri=path.as_uri())


async def _hover(client: LanguageClient, path: Path, pos: lsp.Position) -> str:
    h = await client.text_document_hover_async(lsp.HoverParams(text_document=_id(path),
                                                               position=pos))
    assert h is not None and isinstance(h.contents, lsp.MarkupContent)
    return h.contents.value


async def test_hover_on_enums_members_and_ranges(client: LanguageClient, doc: Path) -> None:
    enum = await _hover(client, doc, position_of(SPEC, "Phase.grasp", delta=2))
    assert "**enum** `Phase`" in enum and "`Phase` = enum {idle, approach, grasp}" in enum
    member = await _hover(client, doc, position_of(SPEC, "Phase.grasp", delta=8))
    assert "**enum member** `grasp`" in member and "Phase.grasp" in member
    retries = await _hover(client, doc, position_of(SPEC, "memory retries", delta=8))
    assert "**memory** `retries`" in retries and "type `0..3`" in retries


async def test_completion_after_an_enum_name_offers_its_members(client: LanguageClient,
                                                                doc: Path) -> None:
    result = await client.text_document_completion_async(lsp.CompletionParams(
        text_document=_id(doc), position=position_of(SPEC, "Phase.grasp else", delta=6)))
    assert isinstance(result, lsp.CompletionList)
    assert [i.label for i in result.items] == ["idle", "approach", "grasp"]
    assert {i.kind for i in result.items} == {lsp.CompletionItemKind.EnumMember}


async def test_definition_of_a_member(client: LanguageClient, doc: Path) -> None:
    result = await client.text_document_definition_async(lsp.DefinitionParams(
        text_document=_id(doc), position=position_of(SPEC, "Phase.approach", delta=7)))
    [loc] = result if isinstance(result, list) else [result]
    assert isinstance(loc, lsp.Location)
    assert loc.range.start == position_of(SPEC, "approach")


async def test_document_symbols_show_the_enum(client: LanguageClient, doc: Path) -> None:
    symbols = await client.text_document_document_symbol_async(lsp.DocumentSymbolParams(
        text_document=_id(doc)))
    assert symbols is not None
    enum = symbols[0]
    assert isinstance(enum, lsp.DocumentSymbol) and enum.name == "Phase"
    assert enum.kind == lsp.SymbolKind.Enum
    assert [m.name for m in enum.children or []] == ["idle", "approach", "grasp"]
