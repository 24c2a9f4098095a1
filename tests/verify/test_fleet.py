"""A coordinator and N robots, written as a new user writes them from the docs
(tests/verify/specs/fleet{2,3,4,7}.rssm, the acceptance spec and its cut-down copies; a
planted bug: fleet3_bug.rssm): the verdicts their headers work out by hand.

What makes them decidable (docs/verify.md, "How values are tracked" and "Progress"):

- the cone of influence follows each partial function's own reads: the coordinator's
  ``busy`` counter, computed from the robots' status beside the job flags the robots test,
  no longer drags the status channels into the tracked values;
- the whole net is one blocking group that stalls together, so its deadlock check decides
  progress (no per-subsystem composition, no cycle proviso);
- the pass with the conditions as free choices gets a share of the time; when that cuts it
  short, the values are tracked with the rest instead of returning INCONCLUSIVE.

No test asserts a wall-clock bound (bench/verify_fleet.py measures them)."""

from __future__ import annotations

from pathlib import Path

import pytest

from rssm_dsl.hpn.flatten import flatten
from rssm_dsl.pipeline import Compilation, compile_file
from rssm_dsl.verify import VerifyOptions, verifier, verify
from rssm_dsl.verify.datanet import track_new
from rssm_dsl.verify.dataplan import value_plan
from rssm_dsl.verify.report import Verdict, VerifyReport
from rssm_dsl.verify.slicing import blocking_groups
from rssm_dsl.verify.stalls import stall_together
from rssm_dsl.verify.valuenet import track_values

SPECS = Path(__file__).parent / "specs"


def _compiled(name: str) -> Compilation:
    comp = compile_file(SPECS / f"{name}.rssm")
    assert comp.ok and comp.hpn is not None
    return comp


def _verify(name: str, time_limit: float | None = None) -> VerifyReport:
    comp = _compiled(name)
    assert comp.hpn is not None
    net = flatten(comp.hpn)
    return verify(net, VerifyOptions(values=value_plan(comp, net), time_limit=time_limit))


def test_the_cone_leaves_out_what_only_the_operator_counter_reads() -> None:
    comp = _compiled("fleet2")
    assert comp.hpn is not None
    net = flatten(comp.hpn)
    tracked = track_values(track_new(net), value_plan(comp, net))
    values = set(tracked.values)
    # what the switches test, and what it is computed from
    assert {"coord.c.ack1", "coord.c.job1", "r1.c.job", "r1.c.count", "r2.c.ack"} <= values
    assert "channel coord.c.job1->r1.c.job" in values
    # the status reports feed only `busy` (and `rounds` only itself): nobody tests them
    assert not {v for v in values if "status" in v or ".st" in v}
    assert "coord.c.busy" not in values and "coord.c.rounds" not in values


def test_every_subsystem_of_the_fleet_stalls_together() -> None:
    comp = _compiled("fleet3")
    assert comp.hpn is not None
    net = flatten(comp.hpn)
    [group] = blocking_groups(net)
    assert set(group) == {"coord.c", "r1.c", "r2.c", "r3.c"}
    assert stall_together(net, group)


@pytest.mark.parametrize("name", ["fleet2", "fleet3"])
def test_fleet_is_verified(name: str) -> None:
    r = _verify(name)
    assert r.verdict is Verdict.VERIFIED, (r.why_undecided, r.notes)
    assert r.safe and r.deadlock_free and r.progress_ok
    assert set(r.progress_checked) >= {"coord.c", "r1.c", "r2.c"}
    assert any("progress follows from deadlock freedom" in n for n in r.notes)


def test_fleet_verified_with_the_values_when_the_free_choices_are_cut_short(
        monkeypatch: pytest.MonkeyPatch) -> None:
    # the free-choice pass gets (almost) no time: the values are tracked with the rest
    monkeypatch.setattr(verifier, "ABSTRACT_SHARE", 1e-9)
    r = _verify("fleet2", time_limit=3600.0)
    assert r.verdict is Verdict.VERIFIED, (r.why_undecided, r.notes)
    assert any("verified again with the values tracked" in n for n in r.notes)
    assert r.method == "stubborn"


def test_planted_bug_robot_ends_after_its_first_job() -> None:
    # as `rssmc verify` runs it, with the random runs beside the engines (the engines alone
    # take a minute: they find it too, see bench/verify_fleet.py)
    from rssm_dsl.falsify.orchestrate import verify_with_simulation
    from rssm_dsl.verify.budget import Budget

    comp = _compiled("fleet3_bug")
    assert comp.hpn is not None
    net = flatten(comp.hpn)
    r = verify_with_simulation(net, comp, VerifyOptions(values=value_plan(comp, net),
                                                        budget=Budget(600.0)))
    assert r.verdict is Verdict.VIOLATED, (r.why_undecided, r.notes)
    assert r.deadlock_free is False
    [cx, *_] = r.deadlocks
    assert cx.steps
    # the end of r2 is on the way: its switch to `end` after acknowledging
    assert any(s.subsystem == "r2.c" and "end" in s.name for s in cx.steps) or any(
        "r2.c" in label for label in cx.marking)


def test_seven_robots_are_verified_from_the_place_invariants() -> None:
    """No marking the one-token semiflows allow is dead (deadmarking.py: a robot waits only
    while its acknowledgement's channel is full, the coordinator only while it is empty), so
    the fleet is deadlock-free without a state explored, and progress follows from deadlock
    freedom (one group that stalls together)."""
    r = _verify("fleet7")
    assert r.verdict is Verdict.VERIFIED, (r.why_undecided, r.notes)
    assert r.safe and r.deadlock_free and r.progress_ok
    assert r.method == "invariants" and r.states == 0
    assert any("deadlock freedom proved from the place invariants" in n for n in r.notes)
    assert any("progress follows from deadlock freedom" in n for n in r.notes)


def test_reduction_off_explores_instead() -> None:
    """`--reduction off` is the plain full exploration: it never takes the invariants'
    word for deadlock freedom (the soundness harness compares it with auto)."""
    from netkit import pipeline_ring

    net = pipeline_ring(8, "BB")       # the invariants alone show it deadlock-free (auto)
    proved = "deadlock freedom proved from the place invariants"
    assert any(proved in n for n in verify(net, VerifyOptions(check_progress=False)).notes)
    r = verify(net, VerifyOptions(reduction="off", check_progress=False))
    assert r.method == "full"
    assert not any(proved in n for n in r.notes)
