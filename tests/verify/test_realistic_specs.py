"""The realistic specifications of examples/verify/: they compile clean, simulate,
and the buggy handover's two control subsystems freeze in a simulation while the corrected
one's keep going: the simulation stops there with E809 naming both (with the stall watch
off, it runs on and shows the effectors and devices still running). Their verdicts:
tests/verify/test_slicing.py; time to verdict: bench/verify_realistic.py."""

from __future__ import annotations

from pathlib import Path

import pytest

from rssm_dsl.diagnostics.render import render_text
from rssm_dsl.interp import RunConfig, SimOptions, Simulator, build_runtime
from rssm_dsl.interp.summary import Snapshot
from rssm_dsl.pipeline import Compilation, compile_file

EXAMPLES = Path(__file__).resolve().parents[2] / "examples" / "verify"
SPECS = ["handover_buggy", "handover", "rover", "palletizer"]
CONTROLLERS = ("arm.c", "base.c")


def _compiled(name: str) -> Compilation:
    comp = compile_file(EXAMPLES / f"{name}.rssm")
    assert comp.ok, render_text(comp.diagnostics, comp.program.line)
    return comp


def _simulate(comp: Compilation, until: float, stall_periods: int = 5) -> Snapshot:
    rt = build_runtime(comp, RunConfig(base_dir=comp.path.parent))
    result = Simulator(rt, SimOptions(seed=0, until=until, stall_periods=stall_periods)).run()
    assert result.reason == "until", (result.reason, result.message)
    assert result.summary is not None
    return result.summary


@pytest.mark.parametrize("name", SPECS)
def test_compiles_without_diagnostics(name: str) -> None:
    comp = _compiled(name)
    assert not comp.diagnostics, render_text(comp.diagnostics, comp.program.line)
    assert comp.hpn is not None


@pytest.mark.parametrize("name", [s for s in SPECS if s != "handover_buggy"])
def test_simulates_three_seconds(name: str) -> None:
    summary = _simulate(_compiled(name), 3.0)
    assert all(s.i > 0 for s in summary.subsystems)


def test_buggy_handover_stops_on_its_stalled_controllers() -> None:
    comp = _compiled("handover_buggy")
    rt = build_runtime(comp, RunConfig(base_dir=comp.path.parent))
    result = Simulator(rt, SimOptions(seed=0, until=10.0)).run()
    assert result.reason == "stalled", result.message
    [diag] = result.diagnostics
    assert diag.code == "E809"
    assert {b.owner for b in result.blocked} == set(CONTROLLERS)
    assert "arm.c" in diag.message and "base.c" in diag.message
    assert 2.0 < result.time < 3.0


def test_buggy_handover_freezes_both_controllers_but_not_the_rest() -> None:
    comp = _compiled("handover_buggy")
    early, late = _simulate(comp, 3.0, 0), _simulate(comp, 5.0, 0)
    for c in CONTROLLERS:
        assert early.subsystem(c).i > 50, "the controllers ran before the base docked"
        assert late.subsystem(c).i == early.subsystem(c).i, f"{c} should be stuck"
    assert late.subsystem("base.c").behaviour == "clamp"
    # the effectors and devices keep running: loss of progress, not a global deadlock
    for e in ("arm.e.motion", "base.e.drive"):
        assert late.subsystem(e).i > early.subsystem(e).i
    pose = late.channel("arm.c.part_pose->base.c.part_pose")
    assert pose.sent == pose.received + 1, "arm.c waits in its blocking send of part_pose"


def test_corrected_handover_keeps_both_controllers_going() -> None:
    comp = _compiled("handover")
    early, late = _simulate(comp, 3.0), _simulate(comp, 5.0)
    for c in CONTROLLERS:
        assert late.subsystem(c).i > early.subsystem(c).i + 50, f"{c} should keep iterating"
    assert late.subsystem("base.c").behaviour == "clamp"
