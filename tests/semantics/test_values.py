"""Value semantics (the VALUE_ROWS of expectations.py): each expression is computed by one
iteration of a subsystem, in the interpreter and in the Python of the generated ROS 2 node
(run without ROS, nodecode_runner.py). A failing expression must stop the run with E802."""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

import pytest

from tests.semantics import systems
from tests.semantics.expectations import VALUE_ROWS, ValueRow
from tests.semantics.interp_runner import simulate
from tests.semantics.nodecode_runner import node_module, run_node


def _spec(tmp_path: Path, row: ValueRow) -> Path:
    return systems.write(tmp_path, "val", systems.system("val", systems.value_agent(
        row.expr, row.type)))


def _same(got: Any, row: ValueRow) -> bool:
    want = row.value
    if isinstance(want, tuple):
        return [float(x) for x in got] == list(want) and all(isinstance(float(x), float)
                                                              for x in got)
    if isinstance(want, float) and math.isnan(want):
        return type(got) is float and math.isnan(got)
    # the type too: 7 % -3 is the int -2, 7 / 2 the float 3.5, 1 == 1 the bool true
    return type(got) is type(want) and got == want


@pytest.mark.parametrize("row", VALUE_ROWS, ids=lambda r: r.id)
def test_value_in_interpreter(tmp_path: Path, row: ValueRow) -> None:
    run = simulate(_spec(tmp_path, row), steps=500)
    if row.error is not None:
        assert run.reason == "error" and run.codes == [row.error], (run.reason, run.codes)
        return
    assert run.reason == "finished", run.message
    got = run.memory["v.c"]["r"]
    assert _same(got, row), f"{row.expr} = {got!r}, expected {row.value!r} ({row.why})"


@pytest.mark.parametrize("row", VALUE_ROWS, ids=lambda r: r.id)
def test_value_in_generated_node(tmp_path: Path, row: ValueRow) -> None:
    ns = node_module(_spec(tmp_path, row), tmp_path / "ws", "val_v/val_v/node_c.py")
    run = run_node(ns)
    if row.error is not None:
        assert run.stopped == row.error, (run.stopped, run.errors)
        return
    assert run.stopped is None and not run.errors, run.errors
    assert run.switches == [("b", None, {"done": True})]
    got = run.var("r")
    assert _same(got, row), f"{row.expr} = {got!r}, expected {row.value!r} ({row.why})"
