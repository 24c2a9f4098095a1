"""The value rules (docs/language.md, "Operators"; rssm_core/values.py) as one table of
expectations, run on the interpreter (a simulation of one control subsystem whose memory
update computes the expression) and on the code of the generated ROS 2 node (its data-case
function executed with the shipped rssm_core.values)."""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

import pytest

from rssm_dsl.interp.initial import InitialValues as SpecValues
from rssm_dsl.pipeline import compile_file
from rssm_dsl.pycode import var
from tests.interp.conftest import compile_text, run, single_control
from tests.ros2.test_pycode import generated_module, outcome

# variables the expressions read (memory, so nothing is folded at compile time)
MEMORY = """
      memory i7: int = 7
      memory im3: int = -3
      memory i0: int = 0
      memory half: int = 4611686018427387904
      memory imin: int = -9223372036854775807 - 1
      memory f75: float = -7.5
      memory f0: float = 0.0
      memory nan_: float = 0.0
      memory r: {type} = {zero}
"""
INITIAL = {"i7": 7, "im3": -3, "i0": 0, "half": 2**62, "imin": -(2**63), "f75": -7.5,
           "f0": 0.0, "nan_": 0.0, "r": 0}
ERR = "E802"

# (name, result type, expression, expected value or error code)
TABLE: list[tuple[str, str, str, Any]] = [
    ("int % keeps the divisor's sign (+,-)", "int", "i7 % im3", -2),
    ("int % keeps the divisor's sign (-,+)", "int", "-i7 % 3", 2),
    ("int % both positive", "int", "i7 % 3", 1),
    ("int % by zero stops", "int", "i7 % i0", ERR),
    ("float % keeps the divisor's sign", "float", "f75 % 2.0", 0.5),
    ("float % by zero stops", "float", "f75 % f0", ERR),
    ("int / int is float division", "float", "i7 / 2", 3.5),
    ("negative int / int is float division", "float", "-i7 / 2", -3.5),
    ("int / 0 stops", "float", "i7 / i0", ERR),
    ("float / 0.0 stops", "float", "1.0 / f0", ERR),
    ("int + overflowing 64 bits stops", "int", "half + half", ERR),
    ("int + up to the largest int", "int", "half - 1 + half", 2**63 - 1),
    ("int * overflowing 64 bits stops", "int", "half * 2", ERR),
    ("int - below the smallest int stops", "int", "imin - 1", ERR),
    ("negating the smallest int stops", "int", "-imin", ERR),
    ("abs of the smallest int stops", "int", "abs(imin)", ERR),
    ("the smallest int is an int", "int", "imin + 0", -(2**63)),
    ("int widens to float in mixed arithmetic", "float", "i7 + 0.5", 7.5),
    ("float overflow is inf", "float", "1.0e308 * 10.0", math.inf),
    ("min propagates NaN (first)", "float", "min(f0 * inf, 1.0)", math.nan),
    ("min propagates NaN (second)", "float", "min(1.0, f0 * inf)", math.nan),
    ("max propagates NaN", "float", "max(1.0, f0 * inf)", math.nan),
    ("clamp propagates NaN", "float", "clamp(f0 * inf, 0.0, 1.0)", math.nan),
    ("min of ints is an int", "int", "min(i7, im3)", -3),
    ("clamp of floats", "float", "clamp(f75, -1.0, 1.0)", -1.0),
    ("sqrt outside its domain stops", "float", "sqrt(f75)", ERR),
    ("floor rounds down", "float", "floor(f75)", -8.0),
    ("index out of range stops", "float", "[1.0, 2.0][i7]", ERR),
    ("comparison with NaN is false", "bool", "f0 * inf == f0 * inf", False),
]

ZERO = {"int": "0", "float": "0.0", "bool": "false"}


def _spec(tmp_path: Path, type_: str, expr: str) -> Path:
    text = single_control(f"          r := {expr}",
                          MEMORY.format(type=type_, zero=ZERO[type_]), frequency="@ 10 Hz")
    path = tmp_path / "arith.rssm"
    path.write_text(text, encoding="utf-8")
    return path


def _same(got: Any, want: Any) -> bool:
    if isinstance(want, float) and math.isnan(want):
        return isinstance(got, float) and math.isnan(got)
    return type(got) is type(want) and bool(got == want)


def interpreter(path: Path) -> tuple[str, Any]:
    comp = compile_text(path.parent, path.read_text(), path.name)
    rt, result = run(comp, max_steps=60)
    if result.reason == "error":
        return "error", result.diagnostics[0].code
    return "ok", rt.subsystems["a1.c"].vars["r"]


def generated_node(path: Path) -> tuple[str, Any]:
    comp = compile_file(path)
    assert comp.ok and comp.system is not None
    system = comp.system
    agent = system.agents[0]
    sub = agent.subsystems[0]
    values = SpecValues(system)
    assert comp.hpn is not None
    ns, _ = generated_module(system, comp.hpn, sub, agent.name, agent.designator, values, path.parent)
    st = ns["State"]()
    for name, value in INITIAL.items():
        setattr(st, var(name), value)
    _, fn = ns["CASES_1_1"][0]

    def case() -> Any:
        stage: dict[str, Any] = {}
        fn(st, stage)
        return stage[var("r")]
    kind, value = outcome(case)
    return kind, value


BACKENDS = {"interpreter": interpreter, "generated node": generated_node}


@pytest.mark.parametrize("backend", list(BACKENDS))
@pytest.mark.parametrize(("name", "type_", "expr", "want"), TABLE, ids=[r[0] for r in TABLE])
def test_value_rules(tmp_path: Path, backend: str, name: str, type_: str, expr: str,
                     want: Any) -> None:
    kind, got = BACKENDS[backend](_spec(tmp_path, type_, expr))
    if want == ERR:
        assert (kind, got) == ("error", ERR), f"{name}: {expr} gave {got!r}, not a failure"
    else:
        assert kind == "ok", f"{name}: {expr} failed with {got}"
        assert _same(got, want), f"{name}: {expr} = {got!r}, expected {want!r}"
