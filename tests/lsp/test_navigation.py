"""Hover, go to definition, find references, completion, document symbols and rename."""

from __future__ import annotations

from collections.abc import AsyncIterator
from pathlib import Path

import pytest
import pytest_asyncio
from lsprotocol import types as lsp
from pytest_lsp import LanguageClient

from rssm_dsl.lsp.positions import LineIndex
from tests.lsp.helpers import ROOT, apply_edits, close, open_doc, position_of
from tests.lsp.specs import GOOD

pytestmark = pytest.mark.asyncio(loop_scope="module")
STDLIB = ROOT / "stdlib"


@pytest_asyncio.fixture(loop_scope="module")
async def doc(client: LanguageClient, tmp_path: Path) -> AsyncIterator[tuple[Path, str]]:
    path = tmp_path / "circle.rssm"
    assert await open_doc(client, path, GOOD) == []
    yield path, GOOD
    close(client, path)


def _id(path: Path) -> lsp.TextDocumentIdentifier:
    return lsp.TextDocumentIdentifier(uri=path.as_uri())


async def _hover(client: LanguageClient, path: Path, pos: lsp.Position) -> str:
    h = await client.text_document_hover_async(lsp.HoverParams(text_document=_id(path),
                                                               position=pos))
    assert h is not None and isinstance(h.contents, lsp.MarkupContent)
    return h.contents.value


async def test_hover_gives_kind_type_and_hpn_place(client: LanguageClient,
                                                   doc: tuple[Path, str]) -> None:
    path, text = doc
    beh = await _hover(client, path, position_of(text, "behaviour cw", delta=10))
    assert "**behaviour** `cw`" in beh
    assert "`P^B[1,c,cw]`" in beh and "`P^f[1,c,cw,2]` (memory)" in beh
    assert "`t[1,c,1]` -> ccw" in beh
    buf = await _hover(client, path, position_of(text, "input setpoint", delta=7))
    assert "**input buffer** `setpoint`" in buf
    assert "`CartesianSetpoint` = record {position: float[3], velocity: float[3]}" in buf
    assert "`P^B[1,lwr,move,rcv,1]`" in buf
    assert "p^fusion[(1,1),(c,lwr),(snd,rcv),(1,1),1]" in buf
    upd = await _hover(client, path, position_of(text, "update torque", delta=8))
    assert "**partial function** for `torque` in behaviour `move`" in upd
    assert "varpi = 3: new(setpoint) and not new(state) -> `p[1,lwr,move,1,3]` (void)" in upd
    sub = await _hover(client, path, position_of(text, "effector lwr @", delta=10))
    assert "virtual effector e_{1,lwr}" in sub and "`P[1,lwr]`" in sub
    dev = await _hover(client, path, position_of(text, "real effector lwr", delta=15))
    assert "`P^E[1,lwr]`" in dev
    cond = await _hover(client, path, position_of(text, "when full_circle", delta=6))
    assert "terminal condition" in cond and "`t[1,c,cw,out]`" in cond


async def test_hover_outside_names_is_empty(client: LanguageClient,
                                            doc: tuple[Path, str]) -> None:
    path, text = doc
    h = await client.text_document_hover_async(lsp.HoverParams(
        text_document=_id(path), position=position_of(text, "// The paper", delta=3)))
    assert h is None


async def _definition(client: LanguageClient, path: Path, pos: lsp.Position) -> lsp.Location:
    result = await client.text_document_definition_async(lsp.DefinitionParams(
        text_document=_id(path), position=pos))
    assert isinstance(result, list) and len(result) == 1
    loc = result[0]
    assert isinstance(loc, lsp.Location)
    return loc


async def test_definition_of_peers_behaviours_conditions_and_imports(
        client: LanguageClient, doc: tuple[Path, str]) -> None:
    path, text = doc
    lines = text.splitlines()
    # `to e.lwr` -> the virtual effector lwr
    loc = await _definition(client, path, position_of(text, "to e.lwr", delta=6))
    assert loc.uri == path.as_uri() and "effector lwr @ 1 kHz" in lines[loc.range.start.line]
    # `from E.lwr` -> the real effector instance
    loc = await _definition(client, path, position_of(text, "from E.lwr", delta=8))
    assert "real effector lwr" in lines[loc.range.start.line]
    # `switch cw -> ccw` -> behaviour ccw
    loc = await _definition(client, path, position_of(text, "-> ccw", delta=4))
    assert "behaviour ccw" in lines[loc.range.start.line]
    # `when full_circle` in a switch from cw -> cw's terminal condition
    loc = await _definition(client, path, position_of(text, "switch cw -> ccw when full_circle",
                                                       delta=24))
    assert loc.range.start.line == text[:text.index("terminal full_circle")].count("\n")
    # new(setpoint) -> the input buffer
    loc = await _definition(client, path, position_of(text, "new(setpoint)", delta=5))
    assert "input setpoint" in lines[loc.range.start.line]
    # an extern in the standard library (another file)
    loc = await _definition(client, path, position_of(text, "circle_setpoint(", delta=3))
    lib = STDLIB / "lwr4plus" / "lwr4plus.rssm"
    assert loc.uri == lib.as_uri()
    lib_lines = lib.read_text(encoding="utf-8").splitlines()
    assert lib_lines[loc.range.start.line][loc.range.start.character:].startswith(
        "circle_setpoint(")
    # a type imported through std.types
    loc = await _definition(client, path, position_of(text, ": JointVec7", delta=3))
    assert loc.uri == (STDLIB / "std" / "types.rssm").as_uri()
    # the module of an import
    loc = await _definition(client, path, position_of(text, "import std.types", delta=9))
    assert loc.uri == (STDLIB / "std" / "types.rssm").as_uri()


async def test_references_of_a_memory_variable_and_a_buffer(
        client: LanguageClient, doc: tuple[Path, str]) -> None:
    path, text = doc
    refs = await client.text_document_references_async(lsp.ReferenceParams(
        text_document=_id(path), position=position_of(text, "memory phase", delta=8),
        context=lsp.ReferenceContext(include_declaration=True)))
    assert refs is not None
    lines = text.splitlines()
    found = sorted((r.range.start.line, r.range.start.character) for r in refs)
    expected = sorted((i, m) for i, line in enumerate(lines) for m in
                      [j for j in range(len(line)) if line.startswith("phase", j)
                       and (j == 0 or not line[j - 1].isalnum())
                       and not line[j + 5:j + 6].isalnum()])
    assert found == expected and len(found) == 10
    refs = await client.text_document_references_async(lsp.ReferenceParams(
        text_document=_id(path), position=position_of(text, "input setpoint", delta=7),
        context=lsp.ReferenceContext(include_declaration=False)))
    assert refs is not None and len(refs) == 6   # 3 new(), 2 reads, 1 receive


async def test_completion_offers_keywords_names_and_peers(client: LanguageClient,
                                                          doc: tuple[Path, str]) -> None:
    path, text = doc

    async def labels(pos: lsp.Position) -> list[str]:
        result = await client.text_document_completion_async(lsp.CompletionParams(
            text_document=_id(path), position=pos))
        assert isinstance(result, lsp.CompletionList)
        return [i.label for i in result.items]

    inside_cw = await labels(position_of(text, "cmd := circle_setpoint", delta=7))
    for name in ("radius", "period", "phase", "cmd", "circle_setpoint", "impedance", "pi",
                 "sin", "CartesianSetpoint", "behaviour", "update", "nonblocking"):
        assert name in inside_cw
    assert "stiffness" not in inside_cw          # a parameter of another subsystem
    peers = await labels(position_of(text, "from c nonblocking", delta=5))
    assert peers == ["c", "E.lwr"]
    behaviours = await labels(position_of(text, "initial cw", delta=8))
    assert behaviours == ["cw", "ccw"]
    new_args = await labels(position_of(text, "new(setpoint)", delta=4))
    assert new_args == ["setpoint", "state"]
    types = await labels(position_of(text, "memory last: ", delta=13))
    assert "LwrState" in types and "float" in types and "radius" not in types


async def test_document_symbols_outline(client: LanguageClient, doc: tuple[Path, str]) -> None:
    path, _ = doc
    symbols = await client.text_document_document_symbol_async(lsp.DocumentSymbolParams(
        text_document=_id(path)))
    assert symbols is not None
    [system] = symbols
    assert isinstance(system, lsp.DocumentSymbol) and system.name == "lwr4_circle"
    [agent] = system.children or []
    assert agent.name == "a1" and agent.kind == lsp.SymbolKind.Module
    kids = agent.children or []
    assert [(k.name, k.kind) for k in kids] == [("c", lsp.SymbolKind.Class),
                                                ("lwr", lsp.SymbolKind.Class),
                                                ("lwr", lsp.SymbolKind.Object)]
    c = kids[0]
    assert [x.name for x in c.children or []] == ["radius", "period", "phase", "cmd", "cw",
                                                   "ccw"]
    cw = next(x for x in c.children or [] if x.name == "cw")
    assert [x.name for x in cw.children or []] == ["update cmd", "update memory", "full_circle"]


async def test_rename_a_behaviour_and_a_buffer(client: LanguageClient,
                                               doc: tuple[Path, str]) -> None:
    path, text = doc
    pos = position_of(text, "behaviour cw", delta=10)
    prep = await client.text_document_prepare_rename_async(lsp.PrepareRenameParams(
        text_document=_id(path), position=pos))
    assert prep is not None
    edit = await client.text_document_rename_async(lsp.RenameParams(
        text_document=_id(path), position=pos, new_name="clockwise"))
    assert edit is not None and edit.changes is not None
    new = apply_edits(text, list(edit.changes[path.as_uri()]))
    assert new == (text.replace("behaviour cw {", "behaviour clockwise {")
                   .replace("initial cw", "initial clockwise")
                   .replace("switch cw -> ccw", "switch clockwise -> ccw")
                   .replace("switch ccw -> cw", "switch ccw -> clockwise"))
    # a buffer: its declaration, the peer's `e.lwr`-side buffer is separate
    pos = position_of(text, "output torque", delta=8)
    edit = await client.text_document_rename_async(lsp.RenameParams(
        text_document=_id(path), position=pos, new_name="tau"))
    assert edit is not None and edit.changes is not None
    new = apply_edits(text, list(edit.changes[path.as_uri()]))
    assert "torque" not in new.split("effector lwr @")[1].split("real effector")[0]
    assert new.count("tau") == text.count("tau") + 5


async def test_rename_refuses_keywords_and_library_names(client: LanguageClient,
                                                          doc: tuple[Path, str]) -> None:
    path, text = doc
    with pytest.raises(Exception, match="not a name that can be declared"):
        await client.text_document_rename_async(lsp.RenameParams(
            text_document=_id(path), position=position_of(text, "behaviour cw", delta=10),
            new_name="behaviour"))
    prep = await client.text_document_prepare_rename_async(lsp.PrepareRenameParams(
        text_document=_id(path), position=position_of(text, "circle_setpoint(", delta=3)))
    assert prep is None   # declared in the standard library


async def test_rename_across_files(client: LanguageClient, tmp_path: Path) -> None:
    lib = tmp_path / "gains.rssm"
    main = tmp_path / "robot.rssm"
    lib_text = "// gains\nrecord Gain {\n  k: float\n}\n"
    lib.write_text(lib_text, encoding="utf-8")
    main_text = GOOD.replace("import lwr4plus\n", "import lwr4plus\nimport gains\n").replace(
        "param period: float = 2.0", "param period: float = 2.0\n      memory g: Gain")
    main.write_text(main_text, encoding="utf-8")
    await open_doc(client, main, main_text)
    loc = await _definition(client, main, position_of(main_text, ": Gain", delta=3))
    assert loc.uri == lib.as_uri() and loc.range.start.line == 1
    edit = await client.text_document_rename_async(lsp.RenameParams(
        text_document=_id(main), position=position_of(main_text, ": Gain", delta=3),
        new_name="Gains"))
    assert edit is not None and edit.changes is not None
    assert set(edit.changes) == {lib.as_uri(), main.as_uri()}
    assert apply_edits(lib_text, list(edit.changes[lib.as_uri()])) == lib_text.replace(
        "record Gain ", "record Gains ")
    close(client, main)


async def _hovers(client: LanguageClient, path: Path, positions: list[lsp.Position]
                  ) -> list[tuple[str, lsp.Range | None] | None]:
    """Hovers at every position, all asked at once."""
    import asyncio

    got = await asyncio.gather(*(client.text_document_hover_async(lsp.HoverParams(
        text_document=_id(path), position=pos)) for pos in positions))
    return [None if h is None else (str(h.contents), h.range) for h in got]


async def _definitions(client: LanguageClient, path: Path, positions: list[lsp.Position]
                       ) -> list[object]:
    import asyncio

    return list(await asyncio.gather(*(client.text_document_definition_async(
        lsp.DefinitionParams(text_document=_id(path), position=pos)) for pos in positions)))


async def test_hover_and_definition_right_after_an_edit_are_those_of_the_whole_text(
        client: LanguageClient, tmp_path: Path) -> None:
    """Asked with the edit (answered from the agent under the cursor, before anything is
    built at idle time, and an index made from the previous one), hover and go to
    definition give what they give once the whole edited text is analysed from scratch,
    everywhere (agent a3, after the edited a2, first: its positions moved)."""
    import re

    from tests.lsp.helpers import change, diagnostics_of
    from tests.lsp.test_incremental import spec

    text = spec(3)
    path = tmp_path / "edited.rssm"
    await open_doc(client, path, text)
    at = text.index("agent a2 {")
    edited = text[:at] + text[at:].replace("memory phase", "// a note\n      memory phase", 1)
    lines = LineIndex(edited)
    start = edited.index("system many")
    a3 = edited.index("agent a3 {")
    positions = [lines.position(start + m.start() + 1, "utf-16")
                 for m in sorted(re.finditer(r"\b[A-Za-z_]\w*", edited[start:]),
                                 key=lambda m: start + m.start() < a3)[::2]]
    change(client, path, edited, 2)
    after_edit = await _hovers(client, path, positions)
    await diagnostics_of(client, path.as_uri(), 2)
    change(client, path, text, 3)
    change(client, path, edited, 4)
    defs_after_edit = await _definitions(client, path, positions)
    close(client, path)
    await open_doc(client, path, edited, 5)
    assert await _hovers(client, path, positions) == after_edit
    assert await _definitions(client, path, positions) == defs_after_edit
    assert sum(h is not None for h in after_edit) > 50
    close(client, path)
