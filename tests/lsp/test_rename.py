"""Rename: record fields (every use, across files), behaviours, buffers, parameters, agents,
local values; names that clash in their scope, or would capture a use, are refused with a
message that names the clash."""

from __future__ import annotations

import re
from pathlib import Path

import pytest
from lsprotocol import types as lsp
from pytest_lsp import LanguageClient

from rssm_dsl.lsp.analysis import analyze_text
from rssm_dsl.lsp.rename import REQUEST_FAILED, RenameRefused, apply_edits, rename_in_program
from rssm_dsl.semantics.loader import display_path
from tests.lsp.helpers import ROOT, close, open_doc, position_of
from tests.lsp.helpers import apply_edits as apply_lsp_edits

GEOMETRY = """\
// Poses of a mobile base.
record Pose {
  x: float
  y: float
  heading: float
}

record Route {
  goal: Pose
  stops: Pose[2]
}

const home: Pose = {x: 0.0, y: 0.0, heading: 0.0}

extern plan(start: Pose, goal: Pose) -> Pose = "robots.base.plan:plan"

device effector Base @ 50 Hz {
  input target: Pose nonblocking
  input speed: float nonblocking
  param gain: float = 1.0
  binding "robots.base.driver:Base"
}
"""

ROVER = """\
import "geometry.rssm"

const limit: float = 5.0

system rover {
  agent base {
    control @ 10 Hz {
      param speed: float = 0.5
      memory route: Route = {goal: {x: 1.0, y: 2.0, heading: 0.0}, stops: [home, home]}
      memory at: Pose = home
      output goal: Pose to e.drive
      output status: float to tower.c

      behaviour drive {
        update goal {
          let next = plan(at, route.goal)
          goal := {x: next.x * speed, y: route.stops[0].y, heading: next.heading}
        }
        update status {
          status := at.x
        }
        update memory {
          at.x := at.x + speed
          route.goal.heading := at.heading
        }
        terminal arrived when at.x >= limit
        send goal; status
      }
      behaviour rest {
        update goal {
          goal := home
        }
        update status {
          status := 0.0
        }
        terminal never when false
        send goal; status
      }
      initial drive
      switch drive -> rest when arrived
    }

    effector drive @ 50 Hz {
      input goal: Pose from c
      output target: Pose to E.wheels
      output speed: float to E.wheels

      behaviour follow {
        update target {
          case new(goal):
            target := {x: goal.x, y: goal.y, heading: goal.heading}
          otherwise:
            skip
        }
        update speed {
          speed := 1.0
        }
        terminal never when false
        send target; speed
        receive goal
      }
      initial follow
    }

    real effector wheels: Base(gain = 2.0)
  }

  agent tower {
    control @ 10 Hz {
      input status: float from base.c
      memory last: float = 0.0

      behaviour watch {
        update memory {
          last := status
        }
        terminal never when false
        receive status
      }
      initial watch
    }
  }

  property stays_near: always base.c.at.x <= limit
  property leaves: whenever base.c in drive eventually base.c in rest
}
"""


def _write(tmp_path: Path) -> tuple[Path, Path]:
    lib, main = tmp_path / "geometry.rssm", tmp_path / "rover.rssm"
    lib.write_text(GEOMETRY, encoding="utf-8")
    main.write_text(ROVER, encoding="utf-8")
    return lib, main


def _codes(path: Path, text: str, overrides: dict[Path, str]) -> list[str]:
    a = analyze_text(path.as_uri(), path, display_path(path), text, 1, overrides, None)
    return sorted(d.code for d in a.diagnostics)


def _rename(tmp_path: Path, file: str, needle: str, delta: int, new: str, nth: int = 0
            ) -> tuple[str, str]:
    """Rename the name at `needle` (+ delta) of geometry.rssm or rover.rssm: the new texts
    of both, checked to give the same diagnostics as before."""
    lib, main = _write(tmp_path)
    texts = {lib: GEOMETRY, main: ROVER}
    where = lib if file == "geometry" else main
    at = -1
    for _ in range(nth + 1):
        at = texts[where].index(needle, at + 1)
    edits = rename_in_program(main, {}, at + delta, new) if where == main else \
        _rename_in_library(lib, main, at + delta, new)
    out = dict(texts)
    for f, fe in edits.items():
        p = Path(f).resolve()
        out[p] = apply_edits(texts[p], fe)
    overrides = {p.resolve(): t for p, t in out.items()}
    assert _codes(main, out[main], overrides) == _codes(main, ROVER, {})
    return out[lib], out[main]


def _rename_in_library(lib: Path, main: Path, offset: int, new: str) -> dict[str, list[
        tuple[int, int, str]]]:
    """A declaration of the library renamed from its use in the program: the same edits."""
    from rssm_dsl.lsp.rename import check_program, plan

    checked = check_program(main, {})
    shown = display_path(lib)
    occ = checked.index.at(shown, offset)
    assert occ is not None
    return plan(main, {}, shown, offset, new)


def _words(text: str, word: str) -> int:
    return len(re.findall(rf"(?<![A-Za-z0-9_]){word}(?![A-Za-z0-9_])", text))


def test_rename_a_record_field_edits_every_use(tmp_path: Path) -> None:
    """`at.x` renamed: the declaration (geometry.rssm), the record literals of the constant
    and of the nested memory, `next.x` (a local value of an extern's result), the lvalue
    `at.x :=`, the property `base.c.at.x`; other fields named x are not records' (none)."""
    lib, main = _rename(tmp_path, "rover", "at.x >= limit", 3, "east")
    assert "  east: float\n" in lib and "{east: 0.0, y: 0.0, heading: 0.0}" in lib
    assert "{goal: {east: 1.0, y: 2.0, heading: 0.0}" in main
    assert "goal := {east: next.east * speed, y: route.stops[0].y," in main
    assert "at.east := at.east + speed" in main and "status := at.east" in main
    assert "target := {east: goal.east, y: goal.y, heading: goal.heading}" in main
    assert "always base.c.at.east <= limit" in main
    assert _words(main, "x") == 0 and _words(lib, "x") == 0


def test_rename_a_nested_record_field(tmp_path: Path) -> None:
    """`Route.goal`: in a nested literal, `route.goal` read and `route.goal.heading :=`
    written; the buffers named goal are not renamed."""
    lib, main = _rename(tmp_path, "geometry", "  goal: Pose", 2, "destination")
    assert "  destination: Pose\n" in lib
    assert "memory route: Route = {destination: {x: 1.0," in main
    assert "plan(at, route.destination)" in main
    assert "route.destination.heading := at.heading" in main
    assert "output goal: Pose to e.drive" in main and "send goal; status" in main


def test_rename_a_local_value(tmp_path: Path) -> None:
    """The span of a `let` was the whole statement: renaming it replaced `next = plan(...)`
    by the new name."""
    _, main = _rename(tmp_path, "rover", "let next", 4, "step")
    assert "let step = plan(at, route.goal)" in main
    assert "{x: step.x * speed, y: route.stops[0].y, heading: step.heading}" in main


def test_rename_an_agent_a_behaviour_and_a_device_parameter(tmp_path: Path) -> None:
    _, main = _rename(tmp_path, "rover", "agent base", 6, "rover_base")
    assert "input status: float from rover_base.c" in main
    assert "always rover_base.c.at.x <= limit" in main
    assert "whenever rover_base.c in drive eventually rover_base.c in rest" in main
    _, main = _rename(tmp_path, "rover", "behaviour drive", 10, "go")
    assert "initial go\n" in main and "switch go -> rest when arrived" in main
    assert "whenever base.c in go eventually" in main
    assert "effector drive @" in main        # the subsystem of that name is another thing
    # the argument of a device instance names the device type's parameter
    lib, main = _rename(tmp_path, "geometry", "param gain", 6, "stiffness")
    assert "param stiffness: float = 1.0" in lib
    assert "real effector wheels: Base(stiffness = 2.0)" in main


def test_rename_a_buffer_with_the_buffer_it_pairs_with_by_name() -> None:
    """head.e.ptz has two inputs from head.c, and head.c one output, `aim`: the name pairs
    them. Renamed alone, the output would match both (E306): its partner is renamed too."""
    path = ROOT / "examples" / "diagnostics" / "E304_unpaired-buffer.rssm"
    text = path.read_text(encoding="utf-8")
    edits = rename_in_program(path, {}, text.index("output aim") + 7, "pan_tilt")
    [(_, file_edits)] = edits.items()
    new = apply_edits(text, file_edits)
    assert "output pan_tilt: float[2] to e.ptz" in new and "input pan_tilt: float[2] from c" in new
    assert "pan_tilt := [pan, tilt]" in new and "angles := pan_tilt" in new
    assert _words(new, "aim") == 0
    assert _codes(path, new, {}) == _codes(path, text, {})


def test_rename_a_buffer_that_pairs_without_its_name(tmp_path: Path) -> None:
    """e.drive sends `target` and `speed` to the device, whose inputs have those names:
    `speed` takes the device's speed, so `target` pairs with the other one whatever its name
    (the device type's buffer, in the library, is left alone). So do `status` and its peer."""
    lib, main = _rename(tmp_path, "rover", "output target", 7, "pose")
    assert lib == GEOMETRY
    assert "output pose: Pose to E.wheels" in main and "pose := {x: goal.x" in main
    assert "update pose {" in main and "send pose; speed" in main
    lib, main = _rename(tmp_path, "rover", "output status", 7, "progress")
    assert "output progress: float to tower.c" in main and "send goal; progress" in main
    assert "input status: float from base.c" in main and "receive status" in main


@pytest.mark.parametrize(("file", "needle", "delta", "new", "message"), [
    ("geometry", "  x: float", 2, "heading", "field 'heading' is already declared in "
     "record Pose"),
    ("rover", "param speed", 6, "at", "memory 'at' is already declared in subsystem base.c"),
    ("rover", "behaviour drive", 10, "rest", "behaviour 'rest' is already declared"),
    ("rover", "agent base", 6, "tower", "agent 'tower' is already declared"),
    ("rover", "const limit", 6, "home", "constant 'home' is already declared"),
    ("geometry", "record Pose", 7, "Route", "record 'Route' is already declared"),
    ("geometry", "input target", 6, "gain", "device parameter 'gain' is already declared"),
    ("rover", "terminal arrived", 9, "speed", "parameter 'speed' is already declared"),
    ("rover", "let next", 4, "route", "memory 'route' is already declared"),
    ("rover", "behaviour drive", 10, "end", "'end' names the end of the subsystem"),
])
def test_rename_to_a_name_of_the_same_scope_is_refused(
        tmp_path: Path, file: str, needle: str, delta: int, new: str, message: str) -> None:
    with pytest.raises(RenameRefused, match=re.escape(message)):
        _rename(tmp_path, file, needle, delta, new)


def test_rename_that_would_capture_a_use_is_refused(tmp_path: Path) -> None:
    """base.c reads the constant `limit`: a parameter of base.c renamed `limit` would hide
    it there, and the constant renamed `speed` would be hidden by the parameter."""
    with pytest.raises(RenameRefused, match=r"cannot rename parameter 'speed' to 'limit': "
                       r"it would hide constant 'limit' \(.*geometry|rover.rssm:3\)"):
        _rename(tmp_path, "rover", "param speed", 6, "limit")
    with pytest.raises(RenameRefused, match=r"'limit' at .*rover.rssm:\d+ would refer to "
                       r"parameter 'speed' .* instead of constant 'limit'"):
        _rename(tmp_path, "rover", "const limit", 6, "speed")


pytestmark_client = pytest.mark.asyncio(loop_scope="module")


@pytestmark_client
async def test_rename_clash_through_the_client(client: LanguageClient, tmp_path: Path) -> None:
    """A refused rename is a RequestFailed error whose message names the clash; an accepted
    one edits both files."""
    lib, main = _write(tmp_path)
    await open_doc(client, main, ROVER)
    uri = lsp.TextDocumentIdentifier(uri=main.as_uri())
    pos = position_of(ROVER, "at.x >= limit", delta=3)
    with pytest.raises(Exception, match="field 'y' is already declared in record Pose") as e:
        await client.text_document_rename_async(lsp.RenameParams(
            text_document=uri, position=pos, new_name="y"))
    assert getattr(e.value, "code", None) == REQUEST_FAILED
    with pytest.raises(Exception, match="it would hide constant 'limit'"):
        await client.text_document_rename_async(lsp.RenameParams(
            text_document=uri, position=position_of(ROVER, "param speed", delta=6),
            new_name="limit"))
    edit = await client.text_document_rename_async(lsp.RenameParams(
        text_document=uri, position=pos, new_name="east"))
    assert edit is not None and edit.changes is not None
    assert set(edit.changes) == {main.as_uri(), lib.as_uri()}
    new = apply_lsp_edits(ROVER, list(edit.changes[main.as_uri()]))
    assert "at.east := at.east + speed" in new and "base.c.at.east <= limit" in new
    close(client, main)
