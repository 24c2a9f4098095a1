"""new(x) tracked in the net the verifier explores (rssm_dsl/verify/datanet.py).

Against the flat net with every condition a free choice (what the verifier explored before,
``free``): the same verdicts, deadlocks and losses of progress (which data case runs decides
no control flow: every case of a partial function ends in the same place), the tracked
state space is the free one without the data cases the receives rule out, and what the
verifier reports is in the flat net's own transitions and places. Then what changes: a
data case that cannot happen is a dead transition, a counterexample's data cases are those
of its receives (it replays without forcing a condition), and the report lists the
conditions that stay free choices."""

from __future__ import annotations

import dataclasses
import json
from pathlib import Path

import pytest
from conftest import requires_spin
from netkit import mode_pair, pipeline_ring, send_send_deadlock

from rssm_dsl.commands.simulate import forced_firings
from rssm_dsl.hpn.flat import FlatNet, NewSites, Role
from rssm_dsl.hpn.flatten import flatten
from rssm_dsl.interp import SimOptions, Simulator
from rssm_dsl.interp.program import build_runtime
from rssm_dsl.interp.replay import judge, load_counterexample, resolve_steps
from rssm_dsl.pipeline import Compilation, compile_file
from rssm_dsl.verify import Verdict, VerifyOptions, VerifyReport, render_text, verify
from rssm_dsl.verify.datanet import combination, track_new, tracked_hpn, varpi_of
from rssm_dsl.verify.netbits import NetBits, bits
from rssm_dsl.verify.promela import run_spin
from rssm_dsl.verify.statespace import explore_full

ROOT = Path(__file__).resolve().parents[2]
HERE = Path(__file__).resolve().parent
FALLBACK = HERE / "specs" / "fallback_never_runs.rssm"
HANDSHAKE = HERE / "specs" / "handshake_cases.rssm"
UNSPLIT = [ROOT / "examples" / "verify" / "deadlock_pair.rssm",
           ROOT / "examples" / "verify" / "progress_triple.rssm",
           ROOT / "tests" / "interp" / "specs" / "handshake_deadlock.rssm"]
SPLIT = [ROOT / "examples" / "relay_blocking.rssm", HANDSHAKE,
         ROOT / "tests" / "interp" / "specs" / "starve.rssm", FALLBACK]
SPECS = SPLIT + UNSPLIT


def _compiled(path: Path) -> Compilation:
    comp = compile_file(path)
    assert comp.ok and comp.hpn is not None, [d.message for d in comp.diagnostics]
    return comp


def _net(path: Path) -> FlatNet:
    comp = _compiled(path)
    assert comp.hpn is not None
    return flatten(comp.hpn)


def free(net: FlatNet) -> FlatNet:
    """The flat net as the verifier explored it before: new(x) a free choice."""
    return dataclasses.replace(net, new_sites=NewSites())


def _verify(net: FlatNet) -> VerifyReport:
    return verify(net, VerifyOptions(reduction="off", time_limit=120.0))


def _markings(net: FlatNet) -> list[int]:
    result = explore_full(NetBits.of(net), max_states=1_000_000)
    assert result.complete and result.graph is not None
    return [result.graph.marking(s) for s in range(result.graph.size)]


@pytest.mark.parametrize("path", SPECS, ids=lambda p: p.stem)
def test_same_verdicts_as_with_free_choices(path: Path) -> None:
    net = _net(path)
    tracked, before = _verify(net), _verify(free(net))
    assert tracked.verdict is before.verdict
    assert tracked.safe is before.safe and tracked.safe_by == "place invariants"
    assert tracked.deadlock_count == before.deadlock_count
    assert {tuple(sorted(c.marking)) for c in tracked.deadlocks} == \
        {tuple(sorted(c.marking)) for c in before.deadlocks}
    assert {c.subsystem for c in tracked.progress} == {c.subsystem for c in before.progress}
    assert tracked.unreachable_behaviours == before.unreachable_behaviours
    # a data case the receives rule out is dead now; nothing else changes
    assert tracked.dead_transitions is not None and before.dead_transitions is not None
    newly_dead = set(tracked.dead_transitions) - set(before.dead_transitions)
    assert set(before.dead_transitions) <= set(tracked.dead_transitions)
    cases = {t for t in net.transitions if t.role is Role.CASE}
    after_case = {u for t in cases for u in net.transitions if set(u.pre) & set(t.post)}
    assert newly_dead <= cases | after_case
    # counterexamples are firing sequences of the flat net, in its names, to its markings
    for c in (*tracked.deadlocks, *tracked.progress):
        assert all(net.transitions[t.index] == t for t in (*c.steps, *c.to_cycle, *c.cycle))
        firings = net.rule.run(net.initial, [t.index for t in c.steps])
        reached = firings[-1].marking if firings else net.initial
        assert sorted(c.marking) == sorted(net.places[p].label for p in reached)


@pytest.mark.parametrize("path", UNSPLIT, ids=lambda p: p.stem)
def test_without_case_clauses_there_is_nothing_to_track(path: Path) -> None:
    """No case clause reads new(x): each partial function has one data case, no condition
    to decide (rssm_dsl/semantics/cases.py), and the net explored is the flat net."""
    net = _net(path)
    assert not any(c.kind == "case" for c in net.conditions)
    assert any(t.role is Role.CASE for t in net.transitions)
    t = track_new(net)
    assert not t.tracked and all(o is not None for o in t.place_origin)


@pytest.mark.parametrize("path", SPLIT, ids=lambda p: p.stem)
def test_the_tracked_state_space_is_the_free_one_without_ruled_out_cases(path: Path) -> None:
    """Every tracked marking, without new(x)'s places, is a marking of the free net; every
    marking of the free net with no data case running is one of the tracked net's."""
    net = _net(path)
    t = track_new(net)
    assert t.changed
    origin = t.place_origin

    def project(m: int) -> int:
        out = 0
        for p in bits(m):
            if origin[p] is not None:
                out |= 1 << origin[p]       # type: ignore[operator]
        return out

    mine = {project(m) for m in _markings(t.net)}
    theirs = set(_markings(free(net)))
    assert mine <= theirs
    case_places = 0
    for tr in net.transitions:
        if tr.role is Role.CASE:
            for p in tr.post:
                case_places |= 1 << p
    assert {m for m in theirs if not m & case_places} <= mine
    assert len(mine) < len(theirs)


def test_a_data_case_that_cannot_happen_is_dead() -> None:
    """fallback_never_runs.rssm: `track`'s input is blocking, so its fallback for missing
    data never runs; before, new(x) was a free choice and the fallback one of the runs."""
    net = _net(FALLBACK)
    tracked, before = _verify(net), _verify(free(net))
    assert tracked.verdict is Verdict.VERIFIED and before.verdict is Verdict.VERIFIED

    def cases(r: VerifyReport) -> set[str]:
        return {t.label for t in r.dead_transitions or () if t.role is Role.CASE}

    assert cases(before) == set()
    # `wait` reads no new(x): its one case runs whatever the data
    assert cases(tracked) == {"a2.c (track) computes memory when not new(sample)"}
    text = render_text(tracked)
    assert "new(x): tracked in the state; 2 data case(s)" in text
    assert "a2.c switches from wait to behaviour track [started] (" in text


def test_counterexample_data_cases_follow_the_receives(tmp_path: Path) -> None:
    """The deadlock of handshake_cases.rssm happens in the first iteration, before any
    receive: its data cases say `not new(answer)`, and the interpreter replays it without
    forcing a condition (with new(x) a free choice the shortest sequence took `new(answer)`).
    The memory functions read no new(x): their one case each is no choice."""
    comp = _compiled(HANDSHAKE)
    assert comp.hpn is not None
    net = flatten(comp.hpn)
    for report, forced in ((verify(net, VerifyOptions(check_progress=False)), 0),
                           (verify(free(net), VerifyOptions(check_progress=False)), 2)):
        assert report.deadlocks
        labels = [t.label for t in report.deadlocks[0].steps if t.role is Role.CASE]
        cases = [c for c in labels if not c.endswith("when any data")]
        assert len(labels) == 4 and len(cases) == 2
        assert all(c.endswith("when not new(answer)") for c in cases) == (forced == 0)
        path = tmp_path / "report.json"
        path.write_text(json.dumps(report.to_json()), encoding="utf-8")
        cx = load_counterexample(path)
        rt = build_runtime(comp)
        steps, bad = resolve_steps(rt.net, cx.sequence(), str(path))
        assert not bad
        sim = Simulator(rt, SimOptions(forced=steps))
        result = sim.run()
        verdict = judge(cx, steps, result, sim)
        assert verdict.reproduced and "differs" not in verdict.message, verdict.message
        assert result.forced == forced
        # which firings were forced: the two cases the free net chose against the data
        named = forced_firings(rt.net, result)
        assert [f["step"] for f in named] == [s for s, _ in result.forced_at]
        assert len(named) == forced and all(
            rt.net.transitions[t].role is Role.CASE and steps[s] == t
            for s, t in result.forced_at)
        assert [(f["condition"], f["span"].split(":")[0]) for f in named] == [
            ("new(answer)", "tests/verify/specs/handshake_cases.rssm")] * forced


def test_report_lists_the_free_conditions() -> None:
    r = verify(_net(ROOT / "examples" / "relay_blocking.rssm"))
    data = r.to_json()["conditions"]
    assert data["new_tracked_cases"] == 2       # the two cases of `update reply` of a2.c
    free_choices = {(c["kind"], c["where"], c["condition"]) for c in data["free_choices"]}
    assert ("terminal/error", "a1.c (down)", "low") in free_choices
    assert ("terminal/error", "a1.c (up)", "high") in free_choices
    assert all(c["file"].endswith("relay_blocking.rssm") and c["line"] > 0
               for c in data["free_choices"])
    assert "abstracted as free choices (every outcome explored): " in render_text(r)


def test_the_net_explored_is_its_own_tracked_net() -> None:
    net = _net(FALLBACK)
    t = track_new(net)
    assert t.changed and track_new(t.net).net is t.net
    # new(sample), not new(sample), and a second start place for the partial function
    # of `track` (one input: two combinations); `wait`'s reads no new(x): one case
    assert len(t.net.places) == len(net.places) + 2 + 1
    for made in (mode_pair(True, False), send_send_deadlock(), pipeline_ring(3, "BN")):
        assert track_new(made).net is made          # no data cases: nothing to track
    free_net = free(net)
    u = track_new(free_net)
    assert not u.tracked and u.free == net.conditions and not u.net.conditions


@pytest.mark.parametrize("path", SPECS, ids=lambda p: p.stem)
def test_the_hpn_with_new_x_flattens_to_the_tracked_net(path: Path) -> None:
    """tracked_hpn (what cpncheck explores): new(x)'s places are fusion sets of the pages
    using them, and flattening gives the tracked net, element for element by name."""
    comp = _compiled(path)
    assert comp.hpn is not None
    mine = track_new(flatten(comp.hpn)).net
    theirs = flatten(tracked_hpn(comp.hpn))

    def shape(net: FlatNet) -> tuple[set[tuple[str, tuple[str, ...], tuple[str, ...]]],
                                      set[str]]:
        names = [p.name for p in net.places]
        return ({(t.name, tuple(sorted(names[p] for p in t.pre)),
                  tuple(sorted(names[p] for p in t.post))) for t in net.transitions},
                {names[p] for p in net.initial})

    assert shape(theirs) == shape(mine)
    assert len(theirs.places) == len(mine.places)


@pytest.mark.parametrize("n", [1, 2, 3])
def test_combinations_are_numbered_as_the_data_cases(n: int) -> None:
    from rssm_dsl.semantics.cases import combinations

    for varpi, new in enumerate(combinations(range(n), n), start=1):
        assert varpi_of(new) == varpi and combination(varpi, n) == new
    # over some of the inputs: numbered over those, the others not split
    for varpi, new in enumerate(combinations([n], n + 2), start=1):
        assert varpi_of(new) == varpi and new[n] == (varpi == 1)


def test_the_compositional_check_and_stubborn_sets_agree() -> None:
    net = _net(FALLBACK)
    full = _verify(net)
    for reduction in ("on", "compositional"):
        r = verify(net, VerifyOptions(reduction=reduction, time_limit=120.0))
        assert r.verdict is full.verdict and r.deadlock_free is full.deadlock_free


@requires_spin
@pytest.mark.parametrize("path", [FALLBACK, HANDSHAKE], ids=lambda p: p.stem)
def test_spin_explores_the_tracked_net(path: Path) -> None:
    net = _net(path)
    ours = verify(net, VerifyOptions(reduction="off", check_progress=False))
    spin = run_spin(net, separate=True)
    assert spin.ran, spin.message
    assert spin.deadlock == (ours.deadlock_free is False)
    assert spin.states_stored == ours.states + 1
