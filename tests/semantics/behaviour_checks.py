"""The switching and ending rows as checks of one neutral record of a subsystem's run, which
each runner fills from what it observes (the interpreter's trace and memory, the generated
node code's driver, the ROS 2 node's trace and exit code)."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

from tests.semantics.expectations import (
    SWITCH_ITERATIONS,
    SWITCH_SEQUENCE,
    EndingRow,
    SwitchRow,
)

Switch = tuple[str, str | None, dict[str, bool]]     # (from, to: None = end, conditions)


@dataclass
class BehaviourRun:
    iterations: dict[str, int]                 # per behaviour that ran
    switches: list[Switch]
    errors: list[tuple[str, bool]]             # (code, handled by an error condition)
    ended: bool                                # the subsystem switched to `end`
    stopped: str | None                        # the code that stopped it (unhandled failure)
    i: int | None = None                       # its discrete time at the end, when known
    memory: dict[str, Any] | None = None       # its memory at the end, when observable
    notes: list[str] = field(default_factory=list)


def check_switch_row(row: SwitchRow, run: BehaviourRun) -> None:
    """Agent `sw` (systems.switching_agent)."""
    pairs = [(f, t) for f, t, _ in run.switches]
    expected = [(f, t) for f, t, _ in SWITCH_SEQUENCE]
    if row.id == "iterate-until-terminal":
        assert run.iterations.get("first") == SWITCH_ITERATIONS["first"], run.iterations
    elif row.id == "switch-after-terminal":
        assert run.iterations.get("never_taken", 0) == 0, run.iterations
        assert pairs[:1] == [("first", "second")], pairs
    elif row.id == "switch-by-condition-name":
        second = [s for s in run.switches if s[0] == "second"]
        assert second == [("second", "third", {"odd": True, "even": False})], second
    elif row.id == "first-declared-wins":
        assert run.iterations.get("shadowed", 0) == 0, run.iterations
        assert pairs[:1] == [("first", "second")], pairs
    elif row.id == "otherwise":
        third = [s for s in run.switches if s[0] == "third"]
        assert third == [("third", None, {"stop": True})], third
    elif row.id == "memory-kept":
        # n is not reset by a switch: second starts at n = 3 and ends at n = 5 after two
        # iterations (from n = 0 it would take five)
        assert {k: v for k, v in run.iterations.items() if v} == SWITCH_ITERATIONS
        if run.i is not None:
            assert run.i == sum(SWITCH_ITERATIONS.values()), run.i
        if run.memory is not None:
            assert run.memory["n"] == 5 and run.memory["total"] == 6, run.memory
    else:
        assert row.id == "end"
        assert run.ended and run.stopped is None, (run.ended, run.stopped)
    # every row: the sequence of behaviours, each ended by the expected condition
    assert pairs == expected, pairs
    for (_, _, conds), (_, _, cond) in zip(run.switches, SWITCH_SEQUENCE, strict=True):
        assert conds.get(cond) is True, conds
    assert not run.errors and run.stopped is None


def check_ending_row(row: EndingRow, run: BehaviourRun) -> None:
    """Agent `errh` (error-condition-path), `errv` (error-condition-by-value), `errt`
    (failing-condition-is-an-error) or `erru` (unhandled-failure-stops)."""
    if row.id == "error-condition-path":
        assert run.errors == [("E802", True)], run.errors
        assert run.switches == [("divide", "check", {"never": False, "failed": True}),
                                ("check", None, {"kept": True, "changed": False})], run.switches
        assert run.iterations == {"divide": 3, "check": 1}, run.iterations
        if run.memory is not None:
            assert run.memory["d"] == 0 and run.memory["q"] == 12.0, run.memory
        assert run.ended and run.stopped is None
    elif row.id == "error-condition-by-value":
        assert not run.errors
        assert run.switches[0] == ("watch", "alarm", {"done": False, "too_far": True}), \
            run.switches
        assert run.iterations == {"watch": 3, "alarm": 1}, run.iterations
        assert run.ended and run.stopped is None
    elif row.id == "failing-condition-is-an-error":
        assert run.errors == [("E802", True)], run.errors
        assert run.switches == [("divide", "check", {"done": False, "failed": True}),
                                ("check", None, {"kept": True})], run.switches
        assert run.iterations == {"divide": 2, "check": 1}, run.iterations
        assert run.ended and run.stopped is None
    else:
        assert row.id == "unhandled-failure-stops"
        assert run.errors == [("E802", False)], run.errors
        assert run.stopped == "E802", run.stopped
        assert not run.switches and not run.ended
        # the third iteration fails: it is not completed
        assert run.iterations == {"divide": 2}, run.iterations


ENDING_AGENTS = {"error-condition-path": "errh", "error-condition-by-value": "errv",
                 "failing-condition-is-an-error": "errt", "unhandled-failure-stops": "erru"}
