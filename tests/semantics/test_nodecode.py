"""The switching and ending rows on the Python of the generated ROS 2 nodes, run without ROS
(nodecode_runner.py: the node module as generated, with stand-ins for its rclpy parts). The
same rows run over real DDS in test_ros2.py; this is the quick check of the generated code."""

from __future__ import annotations

import inspect
from pathlib import Path

import pytest

from tests.semantics import systems
from tests.semantics.behaviour_checks import (
    ENDING_AGENTS,
    BehaviourRun,
    check_ending_row,
    check_switch_row,
)
from tests.semantics.expectations import ENDING_ROWS, SWITCH_ROWS, EndingRow, SwitchRow
from tests.semantics.nodecode_runner import NodeRun, node_module, run_node

AGENTS = {"sw": systems.switching_agent(), "errh": systems.error_agent("errh", True),
          "erru": systems.error_agent("erru", False), "errv": systems.error_value_agent(),
          "errt": systems.failing_condition_agent(), "solo": systems.solo_agent()}


def _node(tmp_path: Path, agent: str) -> dict[str, object]:
    spec = systems.write(tmp_path, "nc", systems.system("nc", AGENTS[agent]))
    return node_module(spec, tmp_path / "ws", f"nc_{agent}/nc_{agent}/node_c.py")


def behaviour_run(run: NodeRun) -> BehaviourRun:
    return BehaviourRun(
        iterations=dict(run.iterations), switches=list(run.switches),
        errors=[(code, run.stopped is None) for code in run.errors],
        ended=bool(run.switches) and run.switches[-1][1] is None, stopped=run.stopped,
        memory={name[2:]: getattr(run.state, name) for name in type(run.state).__slots__})


@pytest.mark.parametrize("row", SWITCH_ROWS, ids=lambda r: r.id)
def test_switch_row(tmp_path: Path, row: SwitchRow) -> None:
    check_switch_row(row, behaviour_run(run_node(_node(tmp_path, "sw"))))


@pytest.mark.parametrize("row", ENDING_ROWS, ids=lambda r: r.id)
def test_ending_row(tmp_path: Path, row: EndingRow) -> None:
    check_ending_row(row, behaviour_run(run_node(_node(tmp_path, ENDING_AGENTS[row.id]))))


def test_iteration_functions_are_generators(tmp_path: Path) -> None:
    """The runtime drives every iteration function as a generator (it yields while an
    operation waits), a subsystem without channels too."""
    ns = _node(tmp_path, "solo")
    spec = ns["SPEC"].kwargs  # type: ignore[attr-defined]
    for name, beh in spec["behaviours"].items():
        assert inspect.isgeneratorfunction(beh.args[1]), name
