"""What happens to a violation found in a slice (rssm_dsl/verify/sliced.py): it is lifted to
a firing sequence of the whole net (with the values tracked when the slices tracked them),
or reported as what it is, found in a slice and not confirmed, never as a violation.

The mobile manipulator of tests/verify/specs/ (a base and an arm agent whose controllers
iterate in lockstep over a blocking channel, a camera and a gripper behind free channels):
its buggy version's loss of progress is only reachable when the camera really reports a
failed grasp, which the slice's environment gives at once and the whole net only after the
camera and its virtual receptor have run."""

from __future__ import annotations

import dataclasses
import json
import re
from pathlib import Path

from rssm_dsl.hpn.flat import FlatNet
from rssm_dsl.hpn.flatten import flatten
from rssm_dsl.interp import SimOptions, Simulator, build_runtime
from rssm_dsl.interp.replay import judge, load_counterexample, resolve_steps
from rssm_dsl.pipeline import Compilation, compile_file
from rssm_dsl.verify import VerifyOptions, verify
from rssm_dsl.verify.budget import Budget
from rssm_dsl.verify.dataplan import ValuePlan, value_plan
from rssm_dsl.verify.report import Verdict, VerifyReport, render_text
from rssm_dsl.verify.sliced import verify_sliced
from rssm_dsl.verify.slicing import blocking_groups

SPECS = Path(__file__).resolve().parent / "specs"
EXPECTED = re.compile(r"Expected verdict of `rssmc verify`:\s*([A-Z]+)")


def _compiled(name: str) -> tuple[Compilation, FlatNet, ValuePlan | None]:
    comp = compile_file(SPECS / f"{name}.rssm")
    assert comp.ok and comp.hpn is not None
    net = flatten(comp.hpn)
    return comp, net, value_plan(comp, net)


def _verify(name: str) -> tuple[Compilation, VerifyReport]:
    """As `rssmc verify` does: the values planned, the default engines."""
    comp, net, plan = _compiled(name)
    return comp, verify(net, VerifyOptions(time_limit=240, values=plan))


def _sliced(net: FlatNet, plan: ValuePlan | None) -> VerifyReport:
    """The slices alone, the values tracked (the pass `verify` makes once the conditions as
    free choices gave a violation)."""
    budget = Budget(120.0)
    opts = VerifyOptions(reduction="on", slicing=False, budget=budget, values=plan,
                         values_first=False)
    return verify_sliced(net, blocking_groups(net), opts, budget, verify)  # type: ignore[arg-type]


def test_headers_state_the_verdicts() -> None:
    for name, verdict in (("mobile_manipulator_buggy", "VIOLATED"),
                          ("mobile_manipulator", "VERIFIED"), ("spurious_slice", "VERIFIED")):
        text = (SPECS / f"{name}.rssm").read_text(encoding="utf-8")
        found = EXPECTED.search(text)
        assert found is not None and found.group(1) == verdict, name


def test_buggy_mobile_manipulator_loses_progress_of_arm_c_and_the_lasso_replays(
        tmp_path: Path) -> None:
    comp, report = _verify("mobile_manipulator_buggy")
    assert report.verdict is Verdict.VIOLATED and report.exit_code == 1
    assert report.deadlock_free is True, "the effectors, the receptor and the devices run on"
    assert not report.unconfirmed
    lost = {c.subsystem: c for c in report.progress}
    assert set(lost) == {"arm.c"}, "base.c ends: it is not stuck"
    cx = lost["arm.c"]
    # arm.c waits in its blocking receive of arrived, nobody left to send it
    assert cx.stuck_at() == (
        "arm.c (wait) receives arrived (blocking): start",
        "channel base.c.arrived -> arm.c.arrived (blocking/blocking): empty")
    path = SPECS / "mobile_manipulator_buggy.rssm"
    lines = path.read_text(encoding="utf-8").splitlines()
    where = cx.stuck_where()
    assert "input arrived: Where from base.c blocking" in lines[
        int(where[0].rpartition(":")[2]) - 1]
    assert all(w.rpartition(":")[0].endswith(path.name) for w in where)
    # base.c ended after backing off: the bug's switch is in the steps
    assert any(t.label == "base.c switches from back_off to the end [away]" for t in cx.steps)
    # the camera really reported a failed grasp (the whole net's steps, not the slice's
    # environment): its device and receptor moved before arm.c judged
    assert any(t.subsystem == "arm.R.camera" for t in cx.steps)
    assert not any("environment of the slice" in t.label
                   for t in (*cx.steps, *cx.to_cycle, *cx.cycle))
    out = tmp_path / "report.json"
    out.write_text(json.dumps(report.to_json()), encoding="utf-8")
    loaded = load_counterexample(out)
    rt = build_runtime(comp)
    steps, bad = resolve_steps(rt.net, loaded.sequence(), str(out))
    assert not bad
    sim = Simulator(rt, SimOptions(forced=steps, record_markings=True))
    verdict = judge(loaded, steps, sim.run(), sim)
    assert verdict.reproduced, verdict.message


def test_corrected_mobile_manipulator_is_verified() -> None:
    _, report = _verify("mobile_manipulator")
    assert report.verdict is Verdict.VERIFIED, (report.why_undecided, report.notes)
    assert report.progress_ok is True and not report.unconfirmed
    # its slice first cut the report channel (values free there): three stuck groups the
    # whole net does not confirm, then the slice again with that channel whole proved it
    assert any("verified again with the free channels inside the group whole" in n
               for n in report.notes)


def test_slices_without_values_lift_past_the_plumbing_that_waits_for_the_rest() -> None:
    """Without values the stuck group of the buggy spec is lifted too; its slice's steps
    include `agent base ends`, which waits in the whole net for base's effector as well
    (it never ends): the replay passes over it."""
    _, net, _ = _compiled("mobile_manipulator_buggy")
    report = _sliced(net, None)
    assert report.verdict is Verdict.VIOLATED
    assert {c.subsystem for c in report.progress} == {"arm.c"}
    assert not any(t.label == "agent base ends" for c in report.progress for t in c.steps)


def test_a_spurious_slice_violation_is_reported_unconfirmed_not_violated() -> None:
    """The slice's environment sends `ok = false`, the real probe never does: the stuck
    group of the slice is no violation of the whole net."""
    _, net, plan = _compiled("spurious_slice")
    report = _sliced(net, plan)
    assert report.verdict is Verdict.INCONCLUSIVE
    assert report.progress_ok is None and not report.progress and not report.deadlocks
    assert len(report.unconfirmed) == 1
    u = report.unconfirmed[0]
    assert (u.kind, u.what, u.group) == ("deadlock", "a stuck group", ("a.c", "b.c"))
    assert "a.c (run) ends [failed]" in u.why and "values tracked" in u.why
    assert "other subsystems' moves" in u.tried and "values tracked" in u.tried
    # the slice's own firing sequence, with the environment's move that made it possible
    cx = u.counterexample
    assert cx is not None
    assert any(t.label.startswith("a.e.probe sends (environment of the slice")
               for t in cx.steps)
    assert all(t.span.file.endswith("spurious_slice.rssm") for t in cx.steps
               if t.subsystem is not None)
    assert report.why_undecided == ("a stuck group found in the slice of a.c, b.c was not "
                                    "confirmed in the whole net")
    text = render_text(report)
    assert ("a stuck group found in the slice of a.c, b.c, not confirmed in the whole net ("
            in text)
    assert "    tried: " in text and "    the slice's firing sequence:" in text
    data = report.to_json()
    assert data["verdict"] == "inconclusive"
    (entry,) = data["unconfirmed"]
    assert set(entry) == {"kind", "what", "group", "why", "tried", "counterexample"}
    assert entry["group"] == ["a.c", "b.c"] and entry["counterexample"]["kind"] == "deadlock"
    # the whole verification decides it on the whole net
    whole = verify(net, VerifyOptions(time_limit=120, values=plan))
    assert whole.verdict is Verdict.VERIFIED


def test_a_report_without_slices_has_no_unconfirmed_violations() -> None:
    _, net, plan = _compiled("spurious_slice")
    r = verify(net, VerifyOptions(reduction="off", slicing=False, values=plan))
    assert r.unconfirmed == () and r.to_json()["unconfirmed"] == []
    assert "not confirmed" not in render_text(dataclasses.replace(r))


def test_a_slice_finding_without_a_firing_sequence_is_unconfirmed_not_violated() -> None:
    """A slice's compositional check can show a stuck group or a loss of progress with no
    firing sequence (the stubborn sets found none within their limits): nothing to lift,
    so the verdict stays open and the report names them; no deadlock freedom is concluded
    from slices none of which is deadlock-free."""
    from rssm_dsl.verify.sliced import _combine
    from rssm_dsl.verify.slicing import slice_net

    _, net, _ = _compiled("spurious_slice")
    groups = blocking_groups(net)
    budget = Budget(60.0)
    parts = []
    for g in groups:
        sl = slice_net(net, g)
        r = verify(sl.net, VerifyOptions(reduction="off", slicing=False, budget=budget))
        if "a.c" in g:      # as the compositional check reports it: no trace
            r = dataclasses.replace(r, deadlocks=(), progress=(), deadlock_free=False,
                                    progress_ok=False, progress_lost=("b.c",))
        else:
            r = dataclasses.replace(r, deadlock_free=None)
        parts.append((sl, r))
    report = _combine(net, groups, parts, budget, 0.0, True)
    assert report.verdict is Verdict.INCONCLUSIVE
    assert report.deadlock_free is None and report.progress_ok is None
    assert report.progress_lost == ()
    assert [(u.kind, u.what, u.counterexample) for u in report.unconfirmed] == [
        ("deadlock", "a stuck group", None), ("progress", "a loss of progress of b.c", None)]
    assert report.to_json()["unconfirmed"][0]["counterexample"] is None
    assert "no firing sequence" in render_text(report)
