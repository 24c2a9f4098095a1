"""The DSL's expressions and statements, compiled to closures, evaluated by running a
subsystem one iteration."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
import pytest

from tests.interp.conftest import compile_text, run, single_control


def memory_after(tmp_path: Path, body: str, memory: str, extra: str = "",
                 steps: int = 60) -> dict[str, Any]:
    comp = compile_text(tmp_path, single_control(body, memory, extra))
    rt, result = run(comp, max_steps=steps)
    assert result.reason == "steps", result.message
    return rt.subsystems["a1.c"].vars


def test_arithmetic_widening_and_builtins(tmp_path: Path) -> None:
    v = memory_after(tmp_path, """
          a := 7 / 2
          b := 7 % 3
          c := 2 + 3 * 4
          d := max(1, 2.5)
          e := min(1, 2.5)
          f := clamp(5, 0, 3)
          g := sqrt(16.0) + floor(2.7) + abs(-2)
          h := if 1 < 2 then 1 else 2.5
          k := atan2(0.0, -1.0)
          m := -(3 - 5)
    """, """
      memory a: float = 0.0
      memory b: int = 0
      memory c: int = 0
      memory d: float = 0.0
      memory e: float = 0.0
      memory f: int = 0
      memory g: float = 0.0
      memory h: float = 0.0
      memory k: float = 0.0
      memory m: int = 0
    """)
    assert v["a"] == 3.5 and v["b"] == 1 and v["c"] == 14
    assert v["d"] == 2.5 and v["e"] == 1.0 and isinstance(v["e"], float)
    assert v["f"] == 3 and v["g"] == 8.0 and v["h"] == 1.0 and isinstance(v["h"], float)
    assert v["k"] == pytest.approx(np.pi) and v["m"] == 2


def test_arrays_records_and_partial_assignment(tmp_path: Path) -> None:
    v = memory_after(tmp_path, """
          let base = [1, 2, 3]
          u := base * 2.0 + [0.5, 0.5, 0.5]
          w := cross([1.0, 0.0, 0.0], [0.0, 1.0, 0.0])
          n := norm([3.0, 4.0, 0.0]) + dot(base, base)
          p := {position: [1, 2, 3], ok: true}
          p.position[1] := 9.0
          q := {position: [1.0, 9.0, 3.0], ok: true}
          same := p == q
          idx := [4, 5, 6][2]
    """, """
      memory u: float[3]
      memory w: float[3]
      memory n: float = 0.0
      memory p: P
      memory q: P
      memory same: bool = false
      memory idx: int = 0
    """, extra="record P { position: float[3], ok: bool }")
    assert list(v["u"]) == [2.5, 4.5, 6.5] and not v["u"].flags.writeable
    assert list(v["w"]) == [0.0, 0.0, 1.0]
    assert v["n"] == 19.0
    assert list(v["p"]["position"]) == [1.0, 9.0, 3.0] and v["p"]["ok"] is True
    assert v["same"] is True and v["idx"] == 6


def test_statements_see_their_own_writes_partial_functions_see_the_pre_state(
        tmp_path: Path) -> None:
    """Within one partial function statements run in order; every partial function of one
    transition function reads s^i (the output's function sees the memory before the memory
    function's writes of the same iteration)."""
    text = """
system t {
  agent a1 {
    control c {
      memory a: int = 0
      memory b: int = 0
      output seen: int to e.x nonblocking
      behaviour run {
        update seen { seen := a }
        update memory {
          a := a + 1
          b := a * 10
        }
        terminal never when false
      }
      initial run
    }
    effector x {
      input seen: int from c nonblocking
      memory got: int = 0
      behaviour take {
        update memory {
          case new(seen): got := seen
          otherwise: skip
        }
        terminal never when got < 0
      }
      initial take
      switch take -> take when never
    }
  }
}
"""
    comp = compile_text(tmp_path, text)
    rt, _ = run(comp, max_steps=40, eager=False)
    c = rt.subsystems["a1.c"]
    assert c.vars["b"] == c.vars["a"] * 10             # b read the a of its own statement
    assert c.vars["seen"] == c.vars["a"] - 1           # seen read a before the commit


def test_runtime_errors_name_the_expression(tmp_path: Path) -> None:
    text = single_control("          i := i + 1\n          x := 1.0 / (2.0 - i)\n",
                          "      memory i: float = 0.0\n      memory x: float = 0.0\n")
    comp = compile_text(tmp_path, text)
    _, result = run(comp, max_steps=200)
    assert result.reason == "error"
    (d,) = result.diagnostics
    assert d.code == "E802" and "division by zero" in d.message
    line = next(n for n, s in enumerate(text.splitlines(), 1) if "1.0 / (2.0 - i)" in s)
    assert d.span.line == line and d.span.file.endswith("spec.rssm")
    assert comp.program.line(d.span.file, d.span.line).strip() == "x := 1.0 / (2.0 - i)"


def test_index_out_of_range_is_reported(tmp_path: Path) -> None:
    comp = compile_text(tmp_path, single_control(
        "          i := i + 1\n          x := [1.0, 2.0, 3.0][i]\n",
        "      memory i: int = 0\n      memory x: float = 0.0\n"))
    _, result = run(comp, max_steps=200)
    assert result.reason == "error"
    assert "index 3 is out of range (indices run from 0 to 2)" in result.diagnostics[0].message


@pytest.mark.parametrize(("body", "memory"), [
    # an item below 0 is out of range on assignment too (not counted from the end)
    ("a[k - 1] := 9", "memory a: int[3] = [1, 2, 3]\n      memory k: int = 0"),
    # a value of a wider range stored into a narrower one is checked where it is stored
    ("r := s", "memory r: 0..3 = 0\n      memory s: 0..10 = 7"),
], ids=["item-below-0", "wider-range-into-narrower"])
def test_stores_that_must_fail(tmp_path: Path, body: str, memory: str) -> None:
    comp = compile_text(tmp_path, single_control(body, memory))
    _, result = run(comp, max_steps=60)
    assert result.reason == "error", result.message
    assert [d.code for d in result.diagnostics] == ["E802"], result.message
