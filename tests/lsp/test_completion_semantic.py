"""Completion, hover and navigation from the semantic model, through a real client, on a
two-file workspace: a library module (records, an alias, an enum, constants, an external
operation, device types) and a two-agent system that imports it.

Completion offers the fields of a record after `x.` (also `a.b.`, `a[i].`, `f(...).`), only
the names in scope in a behaviour, the behaviours after `switch`/`initial`/`->`, only the
peers the structure allows after `from`/`to`, and snippets of a behaviour and of the
subsystems where such a declaration may start (and what they insert parses). It does so
while the text is being typed: the analysis it answers from may be of an older text, whose
offsets are off. Hover shows the types of library declarations, `let` values and fields,
and go to definition and references follow them into the library."""

from __future__ import annotations

import re
import statistics
import time
from collections.abc import AsyncIterator
from dataclasses import dataclass
from pathlib import Path

import pytest
import pytest_asyncio
from lsprotocol import types as lsp
from pytest_lsp import LanguageClient

from rssm_dsl.lsp.analysis import SYNTAX_CODES
from rssm_dsl.lsp.positions import LineIndex
from rssm_dsl.pipeline import compile_file
from tests.lsp.helpers import ROOT, change, close, diagnostics_of, open_doc, position_of

pytestmark = pytest.mark.asyncio(loop_scope="module")

LIBRARY = """// shapes shared by the robots
import std.types

record Pose {
  position: Vec3
  yaw: float
}

record Target {
  pose: Pose
  weight: float
}

type Goal = Target

enum Grip { open, closed }

const gain = 2
const home: Pose = {position: [0.0, 0.0, 0.0], yaw: 0.0}

extern plan(p: Pose, k: int) -> Target = "geometry_ops:plan"

device effector Drive @ 10 Hz {
  input torque: float nonblocking
  binding "geometry_ops:Drive"
}

device receptor Cam @ 10 Hz {
  output raw: float nonblocking
  binding "geometry_ops:Cam"
}
"""

OPS = '''def plan(p, k):
    return {"pose": p, "weight": float(k)}


class Drive:
    def receive(self, name, value):
        pass


class Cam:
    def measure(self):
        return {"raw": 0.0}
'''

ROBOT = """import geometry

system robot {
  agent arm {
    control @ 10 Hz {
      param start: Pose = home
      memory goal: Goal
      memory poses: Pose[3]
      memory grip: Grip = Grip.open
      input seen: Target from r.eye
      output cmd: Pose to e.motor.cmd
      output note: float to base.c

      behaviour track {
        update cmd {
          let next = goal.pose
          cmd := {position: next.position, yaw: next.yaw}
        }
        update note {
          note := goal.weight * gain + poses[1].yaw + goal.pose.yaw + plan(start, gain).weight
        }
        update memory {
          goal := plan(seen.pose, gain)
          poses[0] := start
        }
        terminal done when seen.weight > 1.0 and grip == Grip.open
      }

      behaviour rest {
        update cmd {
          cmd := start
        }
        terminal rested when true
      }

      initial track
      switch track -> rest when done
      switch rest -> end when rested
    }

    effector motor @ 10 Hz {
      input cmd: Pose from c
      output torque: float to E.drive

      behaviour relay {
        update torque {
          torque := cmd.yaw
        }
        terminal never when false
      }

      initial relay
    }

    receptor eye @ 10 Hz {
      input raw: float from R.cam
      output seen: Target to c

      behaviour look {
        update seen {
          seen := {pose: {position: [raw, 0.0, 0.0], yaw: 0.0}, weight: 1.0}
        }
        terminal never when false
      }

      initial look
    }

    real effector drive: Drive
    real receptor cam: Cam
  }

  agent base {

    control @ 10 Hz {
      input note: float from arm.c
      memory total: float = 0.0

      behaviour sum {
        update memory {
          total := total + note
        }
        terminal full when total > 100.0
      }

      initial sum
      switch sum -> end when full
    }
  }
}
"""

# a line of arm.c being typed: the parser loses the rest of the system after it (the
# subsystems motor and eye, the agent base), the last good semantic model still has them
BROKEN = ("      switch rest -> end when rested\n",
          "      switch rest -> end when rested\n      switch \n")
# a comment then written at the top: every offset of the last analysis is off by its length
NOTE = "// " + "the robot of the test, with a long comment that moves everything down " * 6 + "\n"


@dataclass
class Workspace:
    lib: Path
    main: Path


@pytest_asyncio.fixture(loop_scope="module")
async def ws(client: LanguageClient, tmp_path: Path) -> AsyncIterator[Workspace]:
    lib, main = tmp_path / "geometry.rssm", tmp_path / "robot.rssm"
    lib.write_text(LIBRARY, encoding="utf-8")
    (tmp_path / "geometry_ops.py").write_text(OPS, encoding="utf-8")
    main.write_text(ROBOT, encoding="utf-8")
    assert await open_doc(client, main, ROBOT) == []
    yield Workspace(lib, main)
    close(client, main)


def _id(path: Path) -> lsp.TextDocumentIdentifier:
    return lsp.TextDocumentIdentifier(uri=path.as_uri())


async def _items(client: LanguageClient, path: Path, pos: lsp.Position
                 ) -> list[lsp.CompletionItem]:
    result = await client.text_document_completion_async(lsp.CompletionParams(
        text_document=_id(path), position=pos))
    assert isinstance(result, lsp.CompletionList)
    return list(result.items)


async def _labels(client: LanguageClient, path: Path, pos: lsp.Position) -> list[str]:
    return [i.label for i in await _items(client, path, pos)]


async def _edit(client: LanguageClient, path: Path, text: str, version: int) -> None:
    """Replace the document's text and wait until the server has analysed it."""
    change(client, path, text, version)
    await diagnostics_of(client, path.as_uri(), version)


async def _typing(client: LanguageClient, ws: Workspace, version: int = 100) -> str:
    """The text being typed: a line of arm.c broken mid-typing (BROKEN), then a long
    comment written on top; each version analysed in turn."""
    old, new = BROKEN
    broken = ROBOT.replace(old, new, 1)
    await _edit(client, ws.main, ROBOT, version)
    await _edit(client, ws.main, broken, version + 1)
    await _edit(client, ws.main, NOTE + broken, version + 2)
    return NOTE + broken


# ---------------------------------------------------------------------- 1. fields
async def test_fields_of_a_record_after_a_dot(client: LanguageClient, ws: Workspace) -> None:
    main = ws.main
    # a memory variable whose type is an alias (Goal = Target) of an imported record
    items = await _items(client, main, position_of(ROBOT, "goal.pose\n", delta=5))
    assert [(i.label, i.detail, i.kind) for i in items] == [
        ("pose", "Pose", lsp.CompletionItemKind.Field),
        ("weight", "float", lsp.CompletionItemKind.Field)]
    # a chain, an indexed array of records, a call of an external operation, a `let` value,
    # an input buffer, a buffer of another subsystem (its own input `cmd`)
    for needle, delta in (("goal.pose.yaw", 10), ("poses[1].yaw", 9), ("next.position", 5),
                          ("next.yaw", 5), ("seen.pose,", 5)):
        labels = await _labels(client, main, position_of(ROBOT, needle, delta=delta))
        assert labels == (["pose", "weight"] if needle.startswith("seen") else
                          ["position", "yaw"]), needle
    position = (await _items(client, main, position_of(ROBOT, "next.position", delta=5)))[0]
    assert position.detail == "Vec3 = float[3]"
    assert await _labels(client, main, position_of(ROBOT, "plan(start, gain).weight",
                                                   delta=18)) == ["pose", "weight"]
    assert await _labels(client, main, position_of(ROBOT, "cmd.yaw", delta=4)) == [
        "position", "yaw"]
    # an enum's members (as before), and nothing after a number or a non-record
    assert await _labels(client, main, position_of(ROBOT, "Grip.open\n", delta=5)) == [
        "open", "closed"]
    assert await _labels(client, main, position_of(ROBOT, "seen.weight > 1.0", delta=16)) \
        == []


async def test_fields_in_a_property(client: LanguageClient, ws: Workspace) -> None:
    prop = "  property heavy: always not (arm.c in rest and arm.c.goal.weight > 2.0)\n"
    text = ROBOT[:ROBOT.rindex("}")] + prop + "}\n"
    await _edit(client, ws.main, text, 60)
    assert await _labels(client, ws.main, position_of(text, "arm.c.goal.weight", delta=11)) \
        == ["pose", "weight"]
    labels = await _labels(client, ws.main, position_of(text, "arm.c.goal.weight", delta=6))
    assert "goal" in labels and "seen" in labels


async def test_fields_while_typing(client: LanguageClient, ws: Workspace) -> None:
    text = await _typing(client, ws)
    assert await _labels(client, ws.main, position_of(text, "goal.pose\n", delta=5)) == [
        "pose", "weight"]
    # in a subsystem the text's AST lost (after the broken line): from the semantic model
    assert await _labels(client, ws.main, position_of(text, "cmd.yaw", delta=4)) == [
        "position", "yaw"]


# ---------------------------------------------------------------------- 2. scope
async def test_only_the_names_in_scope_in_a_behaviour(client: LanguageClient,
                                                      ws: Workspace) -> None:
    main = ws.main
    items = await _items(client, main, position_of(ROBOT, "goal := plan(", delta=8))
    labels = [i.label for i in items]
    for name in ("goal", "poses", "grip", "start", "seen", "cmd", "note", "gain", "home",
                 "plan", "sin", "pi", "Grip"):
        assert name in labels, name
    # other subsystems' buffers and memory, conditions (not in scope in an update), the
    # `let` value of another update
    for name in ("torque", "raw", "total", "done", "rested", "next", "Drive"):
        assert name not in labels, name
    detail = {i.label: i.detail for i in items}
    assert detail["goal"] == "memory: Target" and detail["seen"] == "input: Target"
    assert detail["gain"] == "constant: int"
    # the `let` value of this case, with its type
    items = await _items(client, main, position_of(ROBOT, "{position: next.", delta=11))
    assert ("next", "let: Pose") in [(i.label, i.detail) for i in items]
    # in a switch condition: the conditions of its source behaviour only
    labels = await _labels(client, main, position_of(ROBOT, "rest when done", delta=10))
    assert "done" in labels and "rested" not in labels and "goal" in labels


async def test_names_in_scope_while_typing(client: LanguageClient, ws: Workspace) -> None:
    text = await _typing(client, ws)
    items = await _items(client, ws.main, position_of(text, "[raw, 0.0", delta=1))
    labels = [i.label for i in items]
    assert "raw" in labels and "seen" in labels and "gain" in labels
    assert ("raw", "input: float") in [(i.label, i.detail) for i in items]
    for name in ("goal", "cmd", "torque", "note", "total", "done"):
        assert name not in labels, name


# ---------------------------------------------------------------------- 3. behaviours
async def test_behaviours_after_switch_initial_and_arrow(client: LanguageClient,
                                                         ws: Workspace) -> None:
    main = ws.main
    assert await _labels(client, main, position_of(ROBOT, "initial track", delta=8)) == [
        "track", "rest"]
    assert await _labels(client, main, position_of(ROBOT, "switch track", delta=7)) == [
        "track", "rest"]
    assert await _labels(client, main, position_of(ROBOT, "-> rest when", delta=3)) == [
        "track", "rest", "end"]
    assert await _labels(client, main, position_of(ROBOT, "initial relay", delta=8)) == [
        "relay"]


async def test_behaviours_after_switch_while_typing(client: LanguageClient,
                                                    ws: Workspace) -> None:
    text = await _typing(client, ws)
    assert await _labels(client, ws.main, position_of(text, "switch \n", delta=7)) == [
        "track", "rest"]
    assert await _labels(client, ws.main, position_of(text, "initial relay", delta=8)) == [
        "relay"]
    assert await _labels(client, ws.main, position_of(text, "initial sum", delta=8)) == [
        "sum"]
    assert await _labels(client, ws.main, position_of(text, "-> end when full", delta=3)) \
        == ["sum", "end"]


# ---------------------------------------------------------------------- 4. peers
async def test_only_the_peers_the_structure_allows(client: LanguageClient,
                                                   ws: Workspace) -> None:
    main = ws.main
    # control: its virtual effectors and receptors, the other agents' control subsystems
    assert await _labels(client, main, position_of(ROBOT, "to e.motor.cmd", delta=3)) == [
        "e.motor", "r.eye", "base.c"]
    # a virtual effector: c and its agent's real effectors; a virtual receptor: c and real
    # receptors; another agent's control subsystem: the control subsystems of the others
    assert await _labels(client, main, position_of(ROBOT, "to E.drive", delta=3)) == [
        "c", "E.drive"]
    assert await _labels(client, main, position_of(ROBOT, "from R.cam", delta=5)) == [
        "c", "R.cam"]
    assert await _labels(client, main, position_of(ROBOT, "from arm.c", delta=5)) == [
        "arm.c"]
    # the rest of a peer, then the peer's buffers of the other direction
    assert await _labels(client, main, position_of(ROBOT, "to e.motor.cmd", delta=5)) == [
        "motor"]
    assert await _labels(client, main, position_of(ROBOT, "from arm.c", delta=9)) == ["c"]
    assert await _labels(client, main, position_of(ROBOT, "to e.motor.cmd", delta=11)) == [
        "cmd"]
    assert await _labels(client, main, position_of(ROBOT, "to E.drive", delta=5)) == [
        "drive"]


async def test_peers_while_typing(client: LanguageClient, ws: Workspace) -> None:
    text = await _typing(client, ws)
    assert await _labels(client, ws.main, position_of(text, "to e.motor.cmd", delta=3)) == [
        "e.motor", "r.eye", "base.c"]
    assert await _labels(client, ws.main, position_of(text, "to E.drive", delta=3)) == [
        "c", "E.drive"]
    assert await _labels(client, ws.main, position_of(text, "from arm.c", delta=5)) == [
        "arm.c"]
    assert await _labels(client, ws.main, position_of(text, "to E.drive", delta=5)) == [
        "drive"]


# ---------------------------------------------------------------------- 5. snippets
def _expand(snippet: str) -> str:
    """The text a snippet inserts when every placeholder keeps its default."""
    text = re.sub(r"\$\{\d+:([^}]*)\}", r"\1", snippet)
    return re.sub(r"\$\{?\d+\}?", "", text)


def _syntax_errors(path: Path, text: str) -> list[str]:
    path.write_text(text, encoding="utf-8")
    comp = compile_file(path, {path.resolve(): text}, build=False)
    return [f"{d.code} {d.message}" for d in comp.diagnostics if d.code in SYNTAX_CODES]


async def test_snippets_where_a_declaration_may_start(client: LanguageClient,
                                                      ws: Workspace, tmp_path: Path) -> None:
    main = ws.main
    snippet = lsp.CompletionItemKind.Snippet

    def snippets(items: list[lsp.CompletionItem]) -> dict[str, lsp.CompletionItem]:
        return {i.label: i for i in items if i.kind == snippet}

    # in a subsystem, between its declarations: a behaviour
    at = ROBOT.index("\n\n      behaviour rest") + 1
    found = snippets(await _items(client, main, position_of(ROBOT, "\n\n      behaviour rest",
                                                            delta=1)))
    assert set(found) == {"behaviour"}
    beh = found["behaviour"]
    assert beh.insert_text_format == lsp.InsertTextFormat.Snippet and beh.insert_text
    assert _syntax_errors(tmp_path / "b.rssm", ROBOT[:at] + _expand(beh.insert_text) +
                          ROBOT[at:]) == []
    # in an agent that has a control subsystem: a virtual effector or receptor
    found = snippets(await _items(client, main, position_of(ROBOT, "agent base {\n",
                                                            delta=13)))
    assert set(found) == {"effector", "receptor"}
    # in an agent without one: a control subsystem too; each inserted text parses
    text = ROBOT.replace("  agent base {", "  agent spare {\n    \n  }\n\n  agent base {")
    await _edit(client, main, text, 50)
    found = snippets(await _items(client, main, position_of(text, "spare {\n    ", delta=12)))
    assert set(found) == {"control", "effector", "receptor"}
    at = text.index("spare {\n    ") + 12
    for label, item in found.items():
        assert item.insert_text_format == lsp.InsertTextFormat.Snippet and item.insert_text
        inserted = text[:at] + _expand(item.insert_text) + text[at:]
        assert _syntax_errors(tmp_path / f"{label}.rssm", inserted) == [], label
    # nowhere else: not in a behaviour, not mid-line, not after a word that goes on
    text = ROBOT.replace("end when rested", "end when\n        rested")
    await _edit(client, main, text, 51)
    for needle, delta in (("goal := plan(", 8), ("initial track", 8), ("terminal done", 9),
                          ("real effector drive: ", 21), ("when\n        rested", 13)):
        assert snippets(await _items(client, main, position_of(text, needle, delta=delta))
                        ) == {}, needle


# ---------------------------------------------------------------------- 6. across files
async def _hover(client: LanguageClient, path: Path, pos: lsp.Position) -> str:
    h = await client.text_document_hover_async(lsp.HoverParams(text_document=_id(path),
                                                               position=pos))
    assert h is not None and isinstance(h.contents, lsp.MarkupContent)
    return h.contents.value


async def _definition(client: LanguageClient, path: Path, pos: lsp.Position
                      ) -> lsp.Location:
    result = await client.text_document_definition_async(lsp.DefinitionParams(
        text_document=_id(path), position=pos))
    assert isinstance(result, list) and len(result) == 1 and isinstance(result[0],
                                                                        lsp.Location)
    return result[0]


async def _references(client: LanguageClient, ws: Workspace, path: Path, pos: lsp.Position,
                      include: bool = True) -> list[tuple[str, str]]:
    """The references as (file name, the text of their range)."""
    refs = await client.text_document_references_async(lsp.ReferenceParams(
        text_document=_id(path), position=pos,
        context=lsp.ReferenceContext(include_declaration=include)))
    assert refs is not None
    files = {p.as_uri(): p for p in (ws.lib, ws.main)}
    out = []
    for r in refs:
        line = files[r.uri].read_text(encoding="utf-8").splitlines()[r.range.start.line]
        out.append((files[r.uri].name, line[r.range.start.character:r.range.end.character]))
    return sorted(out)


def _line(path: Path, loc: lsp.Location) -> str:
    return path.read_text(encoding="utf-8").splitlines()[loc.range.start.line][
        loc.range.start.character:]


async def test_hover_on_library_declarations(client: LanguageClient, ws: Workspace) -> None:
    main, lib = ws.main, ws.lib
    const = await _hover(client, main, position_of(ROBOT, "* gain", delta=3))
    assert "**constant** `gain`" in const and "type `int`" in const
    alias = await _hover(client, main, position_of(ROBOT, ": Goal", delta=3))
    assert "`Target` = record {pose: Pose, weight: float}" in alias
    ext = await _hover(client, main, position_of(ROBOT, "plan(seen", delta=1))
    assert "**external operation** `plan`" in ext and "bound to `geometry_ops:plan`" in ext
    assert "(p: Pose, k: int) -> `Target` = record {pose: Pose, weight: float}" in ext
    local = await _hover(client, main, position_of(ROBOT, "let next", delta=5))
    assert "**local value** `next`" in local and "`Pose` = record {position: float[3], " \
        "yaw: float}" in local
    field = await _hover(client, main, position_of(ROBOT, "goal.pose\n", delta=6))
    assert "**field** `pose`" in field and "field of record `Target`" in field
    assert "type `Pose`" in field
    # in the library itself (no system): the record's fields, the constant's type
    assert await open_doc(client, lib, LIBRARY) == []
    try:
        record = await _hover(client, lib, position_of(LIBRARY, "record Target", delta=8))
        assert "`Target` = record {pose: Pose, weight: float}" in record
        const = await _hover(client, lib, position_of(LIBRARY, "const gain", delta=7))
        assert "type `int`" in const
        field = await _hover(client, lib, position_of(LIBRARY, "  weight: float", delta=3))
        assert "field of record `Target`" in field and "type `float`" in field
    finally:
        close(client, lib)


async def test_definition_and_references_across_files(client: LanguageClient,
                                                      ws: Workspace) -> None:
    main, lib = ws.main, ws.lib
    # from the system into the library: a constant, an external operation, a field
    loc = await _definition(client, main, position_of(ROBOT, "* gain", delta=3))
    assert loc.uri == lib.as_uri() and _line(lib, loc).startswith("gain = 2")
    loc = await _definition(client, main, position_of(ROBOT, "plan(seen", delta=1))
    assert loc.uri == lib.as_uri() and _line(lib, loc).startswith("plan(p: Pose")
    loc = await _definition(client, main, position_of(ROBOT, "goal.pose\n", delta=6))
    assert loc.uri == lib.as_uri() and _line(lib, loc).startswith("pose: Pose")
    loc = await _definition(client, main, position_of(ROBOT, "next.yaw", delta=6))
    assert loc.uri == lib.as_uri() and _line(lib, loc).startswith("yaw: float")
    # references from a use of a field and from its declaration in the library: its
    # declaration, and its uses `goal.pose`, `seen.pose`, `goal.pose.yaw` (and maybe the
    # field named in the record literal `{pose: ...}`)
    refs = await _references(client, ws, main, position_of(ROBOT, "seen.pose", delta=6))
    assert {text for _, text in refs} == {"pose"}
    assert [f for f, _ in refs].count("geometry.rssm") == 1
    assert [f for f, _ in refs].count("robot.rssm") in (3, 4)
    assert await open_doc(client, lib, LIBRARY) == []
    try:
        assert await _references(client, ws, lib, position_of(LIBRARY, "  pose: Pose",
                                                              delta=3), include=False) \
            == [r for r in refs if r[0] == "robot.rssm"]
        gain = await _references(client, ws, lib, position_of(LIBRARY, "const gain", delta=7))
        assert gain == [("geometry.rssm", "gain")] + [("robot.rssm", "gain")] * 3
    finally:
        close(client, lib)


# ---------------------------------------------------------------------- latency
def _large_spec(agents: int) -> str:
    """The paper's agent repeated (as bench/lsp.py makes it): about 5,700 lines for 75."""
    text = (ROOT / "examples" / "lwr4_circle.rssm").read_text(encoding="utf-8")
    head, _, rest = text.partition("system lwr4_circle {\n")
    agent = rest[: rest.rindex("}")]
    body = "".join(agent.replace("agent a1 {", f"agent a{i} {{") for i in range(1, agents + 1))
    return f"{head}system big {{\n{body}}}\n"


async def test_completion_and_hover_are_fast_on_a_large_spec(client: LanguageClient,
                                                             tmp_path: Path) -> None:
    """Under 20 ms (median, the client's round trip) on a spec of about 5,700 lines: they
    are computed from the analysis, which is not redone for a request."""
    text = _large_spec(75)
    assert text.count("\n") > 5600
    path = tmp_path / "big.rssm"
    assert await open_doc(client, path, text) == []
    lines = LineIndex(text)
    mid = text.index("agent a40 {")
    spots = [("completion", text.index("last.velocity", mid) + 5),
             ("completion", text.index("last := setpoint", mid)),
             ("completion", text.index("from c ", mid) + 5),
             ("hover", text.index("last := setpoint", mid) + 1),
             ("hover", text.index("last.velocity", mid) + 7)]
    times: dict[str, list[float]] = {}
    try:
        for _ in range(6):
            for what, offset in spots:
                pos = lines.position(offset, "utf-16")
                t0 = time.perf_counter()
                if what == "completion":
                    assert await _items(client, path, pos)
                else:
                    assert await _hover(client, path, pos)
                times.setdefault(what, []).append(time.perf_counter() - t0)
    finally:
        close(client, path)
    for what, t in times.items():
        assert statistics.median(t) < 0.020, (what, statistics.median(t))
