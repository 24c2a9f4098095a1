"""The language server on properties (examples/verify/handover.rssm): hover on a property,
go to definition and completion on its subsystems, behaviours and variables, the outline,
rename, diagnostics, and the incremental analysis of a system with properties."""

from __future__ import annotations

from collections.abc import AsyncIterator
from pathlib import Path

import pytest
import pytest_asyncio
from lsprotocol import types as lsp
from pytest_lsp import LanguageClient

from rssm_dsl.lsp.analysis import analyze_text
from rssm_dsl.lsp.symbols import document_symbols
from rssm_dsl.semantics.loader import display_path
from tests.lsp.helpers import ROOT, apply_edits, change, close, diagnostics_of, open_doc, position_of

pytestmark = pytest.mark.asyncio(loop_scope="module")
ALWAYS = "property no_stale_clamp: always not (base.c in unload and base.c.clamped)"
RESPONSE = "property delivered: whenever arm.c in release eventually base.c in deliver"
# the handover example with two properties (examples/verify/lockstep.rssm states its own)
HANDOVER = (ROOT / "examples" / "verify" / "handover.rssm").read_text(
    encoding="utf-8").rstrip().removesuffix("}") + f"""
  // The base never reports a clamped part while unloading.
  {ALWAYS}
  // Every part the arm lets go of at the handover pose is carried off.
  {RESPONSE}
}}
"""


@pytest_asyncio.fixture(loop_scope="module")
async def doc(client: LanguageClient, tmp_path: Path) -> AsyncIterator[tuple[Path, str]]:
    path = tmp_path / "handover.rssm"
    assert await open_doc(client, path, HANDOVER) == []
    yield path, HANDOVER
    close(client, path)


def _id(path: Path) -> lsp.TextDocumentIdentifier:
    return lsp.TextDocumentIdentifier(uri=path.as_uri())


async def _hover(client: LanguageClient, path: Path, pos: lsp.Position) -> str:
    h = await client.text_document_hover_async(lsp.HoverParams(text_document=_id(path),
                                                               position=pos))
    assert h is not None and isinstance(h.contents, lsp.MarkupContent)
    return h.contents.value


async def _definition_line(client: LanguageClient, path: Path, text: str,
                           pos: lsp.Position) -> str:
    result = await client.text_document_definition_async(lsp.DefinitionParams(
        text_document=_id(path), position=pos))
    assert isinstance(result, list) and len(result) == 1
    loc = result[0]
    assert isinstance(loc, lsp.Location) and loc.uri == path.as_uri()
    line = text.splitlines()[loc.range.start.line]
    return line[loc.range.start.character:]


async def _labels(client: LanguageClient, path: Path, pos: lsp.Position) -> list[str]:
    result = await client.text_document_completion_async(lsp.CompletionParams(
        text_document=_id(path), position=pos))
    assert isinstance(result, lsp.CompletionList)
    return [i.label for i in result.items]


async def test_the_example_states_the_properties_the_tests_use() -> None:
    assert ALWAYS in HANDOVER and RESPONSE in HANDOVER


async def test_hover_on_a_property_gives_its_kind_text_and_atoms(
        client: LanguageClient, doc: tuple[Path, str]) -> None:
    path, text = doc
    response = await _hover(client, path, position_of(text, "property delivered", delta=11))
    assert "**property** `delivered`" in response
    assert f"```rssm\n{RESPONSE}\n```" in response
    assert "**whenever ... eventually ...**: a response property" in response
    assert "atoms: `arm.c in release` (page `P^B[arm,c,release]`), `base.c in deliver`" \
        in response
    always = await _hover(client, path, position_of(text, "property no_stale_clamp", delta=11))
    assert f"```rssm\n{ALWAYS}\n```" in always
    assert "**always**: a state invariant" in always
    assert "`base.c.clamped` (output, bool)" in always
    assert "abstracted" not in always
    # the subsystem and the behaviour of an atom hover as they do elsewhere
    sub = await _hover(client, path, position_of(text, "arm.c in release", delta=4))
    assert "control subsystem" in sub and "`arm.c`" in sub
    beh = await _hover(client, path, position_of(text, "in release eventually", delta=5))
    assert "**behaviour** `release`" in beh


async def test_definition_of_the_names_in_a_property(client: LanguageClient,
                                                     doc: tuple[Path, str]) -> None:
    path, text = doc
    at = text.index(RESPONSE)

    def pos(needle: str, delta: int) -> lsp.Position:
        return position_of(text, needle, nth=text[:at].count(needle), delta=delta)

    assert (await _definition_line(client, path, text, pos("arm.c in release", 1))
            ).startswith("arm {")
    assert (await _definition_line(client, path, text, pos("arm.c in release", 4))
            ).startswith("c @ 50 Hz {")
    assert (await _definition_line(client, path, text, pos("in release", 5))
            ).startswith("release {")
    assert (await _definition_line(client, path, text, pos("base.c in deliver", 12))
            ).startswith("deliver {")
    got = await _definition_line(client, path, text,
                                 position_of(text, "base.c.clamped)", delta=9))
    assert got.startswith("clamped: bool to arm.c nonblocking")


async def test_completion_in_a_property(client: LanguageClient,
                                        doc: tuple[Path, str]) -> None:
    path, text = doc
    # after `arm.c in `: the behaviours of arm.c
    assert await _labels(client, path, position_of(text, "in release eventually", delta=3)) \
        == ["pick", "present", "release", "retreat"]
    assert await _labels(client, path, position_of(text, "in deliver\n", delta=3)) \
        == ["dock", "clamp", "deliver", "unload"]
    # after `base.`: its subsystems; after `base.c.`: the variables of base.c
    subs = await _labels(client, path, position_of(text, "base.c in unload", delta=5))
    assert subs == ["c", "drive", "fixture"]
    variables = await _labels(client, path, position_of(text, "base.c.clamped)", delta=7))
    assert variables[:1] == ["waited"] and "clamped" in variables and "odom" in variables
    assert "dock_tol" in variables and "release" not in variables
    # elsewhere in a property: the agents, the keywords, the constants
    anywhere = await _labels(client, path, position_of(text, "always not (", delta=7))
    assert {"arm", "base", "always", "in", "not"} <= set(anywhere)


async def test_the_outline_lists_the_properties(client: LanguageClient,
                                                doc: tuple[Path, str]) -> None:
    path, _ = doc
    symbols = await client.text_document_document_symbol_async(lsp.DocumentSymbolParams(
        text_document=_id(path)))
    assert symbols is not None
    system = next(s for s in symbols if s.name == "handover")
    assert isinstance(system, lsp.DocumentSymbol)
    kids = [(k.name, k.kind, k.detail) for k in system.children or []]
    assert kids == [("arm", lsp.SymbolKind.Module, "agent"),
                    ("base", lsp.SymbolKind.Module, "agent"),
                    ("no_stale_clamp", lsp.SymbolKind.Property, "always property"),
                    ("delivered", lsp.SymbolKind.Property,
                     "response property (whenever ... eventually ...)")]


async def test_renaming_a_behaviour_renames_it_in_the_properties(
        client: LanguageClient, doc: tuple[Path, str]) -> None:
    path, text = doc
    edit = await client.text_document_rename_async(lsp.RenameParams(
        text_document=_id(path), position=position_of(text, "behaviour deliver", delta=11),
        new_name="carry"))
    assert edit is not None and edit.changes is not None
    new = apply_edits(text, list(edit.changes[path.as_uri()]))
    assert new == (text.replace("behaviour deliver {", "behaviour carry {")
                   .replace("clamp -> deliver when", "clamp -> carry when")
                   .replace("switch deliver -> unload", "switch carry -> unload")
                   .replace("eventually base.c in deliver\n", "eventually base.c in carry\n"))


async def test_property_diagnostics_reach_the_editor(client: LanguageClient,
                                                     tmp_path: Path) -> None:
    path = tmp_path / "handover_typo.rssm"
    text = HANDOVER.replace("eventually base.c in deliver", "eventually base.c in delivr")
    diags = await open_doc(client, path, text)
    assert [(d.code, d.message.splitlines()[0]) for d in diags] == [
        ("E621", "base.c has no behaviour 'delivr'")]
    assert "did you mean 'deliver'?" in diags[0].message
    [d] = diags
    line = text.splitlines()[d.range.start.line]
    assert line[d.range.start.character:d.range.end.character] == "delivr"
    change(client, path, HANDOVER, 2)
    assert await diagnostics_of(client, path.as_uri(), 2) == []
    close(client, path)


async def test_an_edit_inside_an_agent_keeps_the_properties() -> None:
    path = Path("/tmp/rssm-incremental-test/handover.rssm")
    shown = display_path(path)
    text = HANDOVER.replace("eventually base.c in deliver", "eventually base.c in delivr")
    first = analyze_text("file:///handover", path, shown, text, 1, {}, None)
    assert [d.code for d in first.diagnostics] == ["E621"]
    edited = text.replace("param patience: int = 500", "param patience: int = 600")
    step = analyze_text("file:///handover", path, shown, edited, 2, {}, first)
    full = analyze_text("file:///handover", path, shown, edited, 2, {}, None)
    assert step.how == "incremental"
    assert [(d.code, d.span) for d in step.diagnostics] == \
        [(d.code, d.span) for d in full.diagnostics]
    outline = document_symbols(step.module, step.lines, "utf-16")
    assert outline == document_symbols(full.module, full.lines, "utf-16")
    assert [k.name for k in outline[-1].children or []][-2:] == ["no_stale_clamp", "delivered"]
