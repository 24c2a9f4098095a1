"""The properties stated in the spec (verify/userprops.py) under every reduction, and the
stubborn-set conditions they rest on (verify/stubborn.py): each test below fails when one
condition is dropped (bench/mutants.py names the mutants: stubborn-*).

* specs with hand-worked verdicts (their header comments), under `--reduction off`, `on`,
  `auto` and `compositional` (which checks properties as `auto` does), equal verdicts;
* nets where a reduction without the visibility condition (V), without the cycle proviso
  (L), without the key condition of an enabled transition (D1/D2: its conflicting
  transitions) or without the scapegoat of a disabled one (its producers) loses a reachable
  combination of the atoms, or a violation of a response property.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from netkit import NetBuilder, random_product

from rssm_dsl.hpn.flat import FlatNet
from rssm_dsl.hpn.flatten import flatten
from rssm_dsl.pipeline import compile_file
from rssm_dsl.semantics.model import System
from rssm_dsl.semantics.properties import InBehaviour
from rssm_dsl.source import Span
from rssm_dsl.verify import VerifyOptions, verify
from rssm_dsl.verify.dataplan import ValuePlan, value_plan
from rssm_dsl.verify.invariants import place_invariants
from rssm_dsl.verify.netbits import NetBits, to_mask
from rssm_dsl.verify.progress import backward_closure
from rssm_dsl.verify.report import Verdict
from rssm_dsl.verify.statespace import Graph, explore_full
from rssm_dsl.verify.stubborn import explore_reduced
from rssm_dsl.verify.userprops import visible_transitions

SPECS = Path(__file__).parent / "specs"
ROOT = Path(__file__).resolve().parents[2]
SPAN = Span("<test>", 1, 1, 1, 1)

# spec -> verdict, {property: holds}; worked out by hand in each spec's header
TABLE = {
    "mobile_manipulator_props.rssm": (Verdict.VIOLATED, {
        "no_grasp_while_driving": True, "retries_bounded": False,
        "grasp_answered": True, "stow_then_grasp": False}),
    "two_subsystems_props.rssm": (Verdict.VIOLATED, {
        "never_open_and_lit": False, "lamp_goes_out": True, "door_locks": True}),
    "../../../examples/verify/lockstep.rssm": (Verdict.VERIFIED, {
        "flag_is_memory": True, "alternates": True}),
}


def _compiled(name: str) -> tuple[FlatNet, object]:
    comp = compile_file(SPECS / name)
    assert comp.ok and comp.hpn is not None, comp.diagnostics
    net = flatten(comp.hpn)
    return net, value_plan(comp, net)


@pytest.mark.parametrize("reduction", ["off", "on", "auto", "compositional"])
@pytest.mark.parametrize("name", sorted(TABLE))
def test_property_verdicts_under_every_reduction(name: str, reduction: str) -> None:
    net, plan = _compiled(name)
    r = verify(net, VerifyOptions(time_limit=120, values=plan,
                                  reduction=reduction))
    verdict, expected = TABLE[name]
    assert {p.name: p.holds for p in r.user_properties} == expected, \
        [p.why for p in r.user_properties]
    assert r.verdict is verdict
    # "auto" and "compositional": the full search up to its share, then stubborn sets
    engines = {"on": ("stubborn sets",), "off": ("full exploration",)}.get(
        reduction, ("full exploration", "stubborn sets"))
    for p in r.user_properties:
        assert any(e in p.why for e in engines), p.why
        if reduction == "compositional":
            assert "the compositional check does not check properties" in p.why
        if p.holds is False:
            cx = p.counterexample
            assert cx is not None
            marking = set(net.initial)         # a firing sequence of the whole net
            for t in (*cx.steps, *cx.to_cycle):
                assert marking >= set(t.pre), t.label
                marking = (marking - set(t.pre)) | set(t.post)
            if p.kind == "response":           # a lasso: a cycle back to where it starts
                assert cx.cycle
                start = set(marking)
                for t in cx.cycle:
                    assert marking >= set(t.pre), t.label
                    marking = (marking - set(t.pre)) | set(t.post)
                assert marking == start


def test_the_violation_needs_both_agents_interleaved() -> None:
    """The two-subsystem spec's `always` violation is found by stubborn sets only with the
    atoms' transitions visible (with none visible they run one agent through its window)."""
    net, plan = _compiled("two_subsystems_props.rssm")
    r = verify(net, VerifyOptions(time_limit=60, values=plan,
                                  reduction="on"))
    holds = {p.name: p.holds for p in r.user_properties}
    assert holds["never_open_and_lit"] is False
    cx = next(p.counterexample for p in r.user_properties if p.name == "never_open_and_lit")
    assert cx is not None
    assert any(m.startswith("lamp.c") and " on" in m for m in cx.marking), cx.marking
    assert any(m.startswith("door.c") and " open" in m for m in cx.marking), cx.marking


# ------------------------------------------------------------------ the conditions, on nets

def _atoms(net: FlatNet, behaviours: list[tuple[str, str]]) -> list[InBehaviour]:
    return [InBehaviour(s, b, SPAN) for s, b in behaviours]


def _marks(graph: Graph, net: FlatNet, atom: InBehaviour) -> np.ndarray:  # type: ignore[type-arg]
    out = np.zeros(graph.size, dtype=np.bool_)
    for p in net.places:
        if p.subsystem == atom.subsystem_id and p.behaviour == atom.behaviour:
            out |= (graph.states[:, p.index // 64] >> np.uint64(p.index % 64)) & np.uint64(1) == 1
    return out


def _valuations(graph: Graph, net: FlatNet, atoms: list[InBehaviour]) -> set[tuple[bool, ...]]:
    cols = [_marks(graph, net, a) for a in atoms]
    return {tuple(bool(c[i]) for c in cols) for i in range(graph.size)}


def _reduced(net: FlatNet, atoms: list[InBehaviour]) -> Graph:
    """The stubborn-set graph as userprops.py explores it: the places the invariants prove
    safe need no up-set (which would otherwise hide a missing condition by adding the
    producers of every unmarked place)."""
    safe = to_mask(place_invariants(net).safe_places)
    r = explore_reduced(NetBits.of(net), safe, for_progress=True,
                        visible=visible_transitions(net, atoms))
    assert r.complete and r.graph is not None
    return r.graph


def _full(net: FlatNet) -> Graph:
    r = explore_full(NetBits.of(net))
    assert r.complete and r.graph is not None
    return r.graph


def _one_shot(b: NetBuilder, sub: str, steps: int, loop_at_end: bool = True) -> None:
    """A subsystem running through behaviours b0 .. b{steps} once, looping in the last."""
    for k in range(steps + 1):
        b.place(f"{sub}.s{k}", marked=k == 0, subsystem=sub, behaviour=f"b{k}")
    for k in range(steps):
        b.transition(f"{sub}.t{k}", [f"{sub}.s{k}"], [f"{sub}.s{k + 1}"], subsystem=sub)
    if loop_at_end:
        b.place(f"{sub}.idle", subsystem=sub, behaviour=f"b{steps}")
        b.transition(f"{sub}.go", [f"{sub}.s{steps}"], [f"{sub}.idle"], subsystem=sub)
        b.transition(f"{sub}.back", [f"{sub}.idle"], [f"{sub}.s{steps}"], subsystem=sub)


def test_visibility_keeps_two_independent_windows() -> None:
    """V: two subsystems that never interact, each passing once through a window (b1);
    "both in b1" is reachable. A set with one enabled visible transition must hold them
    all: otherwise the lone transitions of one subsystem run it past its window first."""
    b = NetBuilder("windows")
    _one_shot(b, "A", 2)
    _one_shot(b, "B", 2)
    net = b.build()
    atoms = _atoms(net, [("A", "b1"), ("B", "b1")])
    assert (True, True) in _valuations(_full(net), net, atoms)
    assert _valuations(_reduced(net, atoms), net, atoms) == _valuations(_full(net), net, atoms)


def test_proviso_keeps_the_ignored_subsystem() -> None:
    """L (the cycle proviso): A loops for ever on its own, B moves once; "B in b1" is
    reachable. The lone transitions of A's loop are a stubborn set in every state of it
    (invisible: they change no atom), so without a fully expanded state on each cycle B's
    move is put off for ever."""
    b = NetBuilder("ignoring")
    b.place("A.x", marked=True, subsystem="A", behaviour="b0")
    b.place("A.y", subsystem="A", behaviour="b0")
    b.transition("A.there", ["A.x"], ["A.y"], subsystem="A")
    b.transition("A.back", ["A.y"], ["A.x"], subsystem="A")
    _one_shot(b, "B", 1, loop_at_end=False)
    net = b.build()
    atoms = _atoms(net, [("B", "b1")])
    assert _valuations(_reduced(net, atoms), net, atoms) == {(False,), (True,)}


def test_key_condition_keeps_the_choice() -> None:
    """D1/D2 for an enabled transition: its conflicting transitions come with it. A chooses
    between two branches (sharing its input place), invisible at first; only the second
    leads to the visible window. Without the conflict the set holds the first branch only."""
    b = NetBuilder("choice")
    b.place("A.s", marked=True, subsystem="A", behaviour="b0")
    b.place("A.l", subsystem="A", behaviour="b0")
    b.place("A.r", subsystem="A", behaviour="b0")
    b.place("A.win", subsystem="A", behaviour="b1")
    b.transition("A.left", ["A.s"], ["A.l"], subsystem="A")
    b.transition("A.right", ["A.s"], ["A.r"], subsystem="A")
    b.transition("A.enter", ["A.r"], ["A.win"], subsystem="A")
    net = b.build()
    atoms = _atoms(net, [("A", "b1")])
    assert _valuations(_reduced(net, atoms), net, atoms) == {(False,), (True,)}


def test_scapegoat_brings_what_can_enable_a_disabled_transition() -> None:
    """D1 for a disabled transition: the producers of one of its unmarked input places come
    with it. A may leave (invisible) or, once B has signalled, enter its window (visible;
    it shares A's place with the leave). B's signal is in conflict with another move of B,
    so no transition is alone. The set grown from A's leave holds the disabled entry; without
    its scapegoat (B's signal) that set fires the leave alone and the window is lost."""
    b = NetBuilder("scapegoat")
    b.place("A.s", marked=True, subsystem="A", behaviour="b0")
    b.place("A.l", subsystem="A", behaviour="b0")
    b.place("A.win", subsystem="A", behaviour="b1")
    b.place("go")
    b.place("B.s", marked=True, subsystem="B", behaviour="b0")
    b.place("B.t", subsystem="B", behaviour="b0")
    b.place("B.u", subsystem="B", behaviour="b0")
    b.transition("A.leave", ["A.s"], ["A.l"], subsystem="A")
    b.transition("A.enter", ["A.s", "go"], ["A.win"], subsystem="A")
    b.transition("B.signal", ["B.s"], ["B.t", "go"], subsystem="B")
    b.transition("B.other", ["B.s"], ["B.u"], subsystem="B")
    net = b.build()
    atoms = _atoms(net, [("A", "b1")])
    assert _valuations(_full(net), net, atoms) == {(False,), (True,)}
    assert _valuations(_reduced(net, atoms), net, atoms) == {(False,), (True,)}


def _response_bad(graph: Graph, net: FlatNet, p: InBehaviour, q: InBehaviour) -> bool:
    """Is `whenever p eventually q` violated in the graph (a p-state reaching no q-state)?"""
    pm, qm = _marks(graph, net, p), _marks(graph, net, q)
    return bool((pm & ~backward_closure(graph, qm)).any())


def _check_random(seed: int, machines: int, states: int, shared: int, sync: float) -> None:
    net = random_product(seed, machines, states, shared, sync)
    full = explore_full(NetBits.of(net))
    if full.unsafe is not None or full.graph is None:
        return
    subs = [f"m{k}" for k in range(machines)]
    atoms = _atoms(net, [(subs[seed % machines], f"m{seed % machines}.b1"),
                         (subs[-1], f"{subs[-1]}.b0")])
    red = _reduced(net, atoms)
    # every reachable combination of the atoms, and no other, in the reduced graph
    assert _valuations(red, net, atoms) == _valuations(full.graph, net, atoms)
    # and the same verdict for a response property over them
    assert _response_bad(red, net, *atoms) == _response_bad(full.graph, net, *atoms)


@pytest.mark.parametrize("seed", range(60))
def test_reduced_keeps_the_atoms_random(seed: int) -> None:
    _check_random(seed, 2 + seed % 3, 3 + seed % 3, seed % 3, 0.5)


@settings(max_examples=60, deadline=None)
@given(seed=st.integers(0, 10**6), machines=st.integers(1, 4), states=st.integers(2, 5),
       shared=st.integers(0, 3), sync=st.sampled_from([0.0, 0.3, 0.7]))
def test_reduced_keeps_the_atoms_hypothesis(seed: int, machines: int, states: int,
                                            shared: int, sync: float) -> None:
    _check_random(seed, machines, states, shared, sync)


def test_a_capped_try_that_cuts_the_whole_net_recheck_says_its_cap_was_hit() -> None:
    """device_reading's property is violated on the slice of a.c, whose environment (the
    receptor) may send any value: it is checked again on the whole net, for a share of the
    run's time. Inside a short capped first try (the falsifier's first second), that share
    is cut by the try's cap, and the try's caller must see its cap hit (and try again with
    the rest of the run's time); a share of the try's own time, cut by itself, left the
    property undecided with the caller's cap not hit, and `rssmc verify` ended INCONCLUSIVE
    on a loaded machine."""
    from rssm_dsl.verify.budget import Budget
    from rssm_dsl.verify.userprops import check_properties

    path = Path(__file__).resolve().parents[1] / "interp" / "specs" / "device_reading.rssm"
    comp = compile_file(path)
    assert comp.hpn is not None and comp.system is not None
    net = flatten(comp.hpn)
    plan = value_plan(comp, net)
    budget = Budget(300.0)
    with budget.capped(0.02) as cap:
        [low] = check_properties(net, comp.system, plan, budget, 5_000_000)
    assert low.holds is False or cap.hit, low.why
    [low] = check_properties(net, comp.system, plan, budget, 5_000_000)
    assert low.holds is False and low.counterexample is not None


@pytest.mark.parametrize("reduction", ["auto", "off", "on"])
def test_a_response_holding_on_a_slice_fed_from_outside_is_checked_on_the_whole_net(
        reduction: str) -> None:
    """response_fed_slice: a.c leaves `wait` only on go = true, which b.c never sends. On the
    slice of a.c alone the environment may send true, so `done` stayed within reach and the
    property held there; the property is now checked where b.c is (the value it sends is
    tracked: the test below), here the whole net, which violates it."""
    comp = compile_file(SPECS / "response_fed_slice.rssm")
    assert comp.hpn is not None
    net = flatten(comp.hpn)
    r = verify(net, VerifyOptions(values=value_plan(comp, net), reduction=reduction))
    [leaves] = r.user_properties
    assert leaves.holds is False, leaves.why
    assert "whole net" in leaves.why and r.verdict is Verdict.VIOLATED
    assert r.deadlock_free and r.progress_ok


def test_a_property_is_checked_on_what_its_subsystems_wait_on() -> None:
    """hub_stops: r1.c waits on hub.c (a blocking receive) and log.c (a blocking send),
    hub.c on k.c, k.c on hub.c; r2.c waits on hub.c too, but nothing r1's properties
    mention waits on r2.c, so r1's are checked on the slice of k.c, hub.c, r1.c and log.c.
    Once k.c ends, hub.c waits for ever and stops sending: both response properties are
    violated, which a slice without k.c (its environment sending `go` for ever) would
    report as holding; the hub sends before it receives, so the invariant is violated as
    well. The verdicts equal the whole net's."""
    from rssm_dsl.semantics.properties import Formula
    from rssm_dsl.verify.budget import Budget
    from rssm_dsl.verify.userprops import check_properties, property_subsystems

    comp = compile_file(SPECS / "hub_stops.rssm")
    assert comp.hpn is not None and comp.system is not None
    net = flatten(comp.hpn)
    plan = value_plan(comp, net)
    where = {p.name: set(property_subsystems(net, p, [Formula(comp.system, e)
                                                      for e in p.expressions], plan))
             for p in comp.system.properties}
    assert where == {"r1_works": {"k.c", "hub.c", "r1.c", "log.c"},
                     "r2_works": {"k.c", "hub.c", "r2.c"},
                     "no_work_before_go": {"k.c", "hub.c", "r1.c", "log.c"}}
    expected = {"r1_works": False, "r2_works": False, "no_work_before_go": False}
    for sliced in (True, False):
        got = check_properties(net, comp.system, plan, Budget(60, None), 2_000_000,
                               sliced=sliced)
        assert {p.name: p.holds for p in got} == expected, [p.why for p in got]
        assert all(p.counterexample is not None for p in got)
        if sliced:
            # r1_works: the slice's lasso replayed in the whole net with the values, to
            # a state from which r1.c can never reach `work` (hub.c waits for ever)
            [r1] = [p for p in got if p.name == "r1_works"]
            assert "the slice of" in r1.why, r1.why
            cx = r1.counterexample
            assert cx is not None and cx.to_cycle
            assert any("k.c switches from run to the end" in t.label for t in
                       (*cx.steps, *cx.to_cycle))
    r = verify(net, VerifyOptions(values=plan, time_limit=60))
    assert {p.name: p.holds for p in r.user_properties} == expected
    assert r.verdict is Verdict.VIOLATED and r.deadlock_free     # log.c runs on
    assert {c.subsystem for c in r.progress} | set(r.progress_lost) == {"hub.c", "r1.c",
                                                                          "r2.c"}


def test_the_border_a_slice_needs_not_read_is_dropped() -> None:
    """slicing.slice_net(quiet=...): a channel across the border on which the slice's end
    never waits and whose value nothing reads has no places and no environment in the
    slice (hub_stops: r2.c's `seen` into hub.c and hub.c's `job2` out to r2.c); one whose
    end in the slice waits (`go`, were k.c outside) is kept whatever ``quiet`` says."""
    from rssm_dsl.verify.slicing import channels, slice_net

    net, _ = _compiled("hub_stops.rssm")
    names = [c.name for c in channels(net)]
    loud = slice_net(net, ["hub.c", "r1.c"])
    quiet = slice_net(net, ["hub.c", "r1.c"], quiet=names)
    gone = {c.name for c in channels(net)} - {p.channel for p in quiet.net.places
                                              if p.subsystem is None}
    assert gone == {"r2.c.seen->hub.c.seen", "hub.c.job2->r2.c.job"}
    assert len(quiet.net.places) == len(loud.net.places) - 4
    assert not any(t.channel in gone for t in quiet.net.transitions if t.name.startswith("env"))
    assert any(t.name == "env[k.c.go->hub.c.go,write]" for t in quiet.net.transitions)


def test_a_property_slice_holds_the_producers_of_the_values_it_tracks() -> None:
    """response_fed_slice: a.c leaves `wait` on the value of `go`, which b.c sends it
    non-blocking (a.c does not wait on b.c): the value is tracked, so b.c is in the slice
    (its environment would send any value), and the property is decided there."""
    from rssm_dsl.semantics.properties import Formula
    from rssm_dsl.verify.userprops import property_subsystems

    comp = compile_file(SPECS / "response_fed_slice.rssm")
    assert comp.hpn is not None and comp.system is not None
    net = flatten(comp.hpn)
    [prop] = comp.system.properties
    keep = property_subsystems(net, prop, [Formula(comp.system, e) for e in prop.expressions],
                               value_plan(comp, net))
    assert set(keep) == {"a.c", "b.c"}


def test_q_is_lost_for_good_only_when_nothing_it_reads_can_move() -> None:
    """userprops._lost_for_good, which confirms a response violation found on a slice: at
    the start of hub_stops, r1.c is idle but can still reach `work` (k.c has not ended):
    `r1.c in work` is not lost; with every subsystem taken as standing still it would be."""
    from rssm_dsl.semantics.properties import Formula
    from rssm_dsl.verify.sliced import _Whole
    from rssm_dsl.verify.userprops import _lost_for_good

    comp = compile_file(SPECS / "hub_stops.rssm")
    assert comp.hpn is not None and comp.system is not None
    net = flatten(comp.hpn)
    whole = _Whole(net, value_plan(comp, net))
    assert whole.net is not None
    [prop] = [p for p in comp.system.properties if p.name == "r1_works"]
    goal = Formula(comp.system, prop.expressions[1])
    start = frozenset(whole.net.initial)
    assert _lost_for_good(net, whole.net, start, whole.raw(start), goal) is False


def test_the_states_line_counts_the_properties_explorations() -> None:
    """The report's `states:` line gives the largest exploration a property needed (a
    trial's report said "none explored" beside 591,851 property states); each property's
    JSON has its own count."""
    from rssm_dsl.verify import render_text

    net, plan = _compiled("hub_stops.rssm")
    r = verify(net, VerifyOptions(values=plan, time_limit=60))
    most = max(p.states for p in r.user_properties)
    assert most > 0 and all(p.to_json()["states"] == p.states for p in r.user_properties)
    [line] = [x for x in render_text(r).splitlines() if x.startswith("  states:")]
    assert f"the properties: {most:,} states at most" in line


def _flags_own() -> tuple[FlatNet, ValuePlan, System]:
    comp = compile_file(SPECS / "flags_own.rssm")
    assert comp.hpn is not None and comp.system is not None
    net = flatten(comp.hpn)
    return net, value_plan(comp, net), comp.system


FLAGS_OWN = {"r1_gets_work": True, "r2_gets_work": False}


def test_a_property_slice_holds_only_the_producers_its_own_conditions_need() -> None:
    """flags_own: hub.c reads a flag of each robot; the job it sends r1.c is computed from
    r1's flag, the one it sends r2.c from r3's. r1's property is checked on hub.c and r1.c
    (hub.c's own conditions read no flag, and r2's and r3's flags feed only values sent
    outside the slice), r2's on hub.c, r2.c and r3.c (r2.c's condition reads a value
    computed from r3's flag): a slice with every robot is what the whole net's conditions
    would ask, one without r3.c would let its environment give r2 work. The verdicts are
    the author's: r1 gets work, r2 (once r3's flag is in) never again (the whole net's
    too: the long case below)."""
    from rssm_dsl.semantics.properties import Formula
    from rssm_dsl.verify.budget import Budget
    from rssm_dsl.verify.userprops import check_properties, property_subsystems

    net, plan, system = _flags_own()
    where = {p.name: set(property_subsystems(net, p, [Formula(system, e)
                                                      for e in p.expressions], plan))
             for p in system.properties}
    assert where == {"r1_gets_work": {"hub.c", "r1.c"},
                     "r2_gets_work": {"hub.c", "r2.c", "r3.c"}}
    got = check_properties(net, system, plan, Budget(120, None), 2_000_000)
    assert {p.name: p.holds for p in got} == FLAGS_OWN, [p.why for p in got]
    assert all("the slice of" in p.why for p in got), [p.why for p in got]


@pytest.mark.long
def test_flags_own_on_the_whole_net() -> None:
    """The whole net of flags_own (1.4 M states under stubborn sets, about a minute)
    gives the verdicts its slices give."""
    from rssm_dsl.verify.budget import Budget
    from rssm_dsl.verify.userprops import check_properties

    net, plan, system = _flags_own()
    got = check_properties(net, system, plan, Budget(600, None), 4_000_000,
                           sliced=False)
    assert {p.name: p.holds for p in got} == FLAGS_OWN, [p.why for p in got]


def test_a_slice_tracks_new_of_what_its_environment_feeds() -> None:
    """beam_relay: the relay copies a reading only under `case new(blocked)`. In the
    property's slice (the conveyor and the relay; the light barrier its environment)
    new(blocked) is set by the relay's receive, as in the whole net, so the slice's lasso
    (hold -> end) is one the whole net takes: the relay receives before it copies, and the
    violation is confirmed on the slice (a free new(blocked) let the slice copy a reading
    never received, whose path the whole net cannot take)."""
    from rssm_dsl.verify.slicing import slice_net

    net, plan = _compiled("beam_relay.rssm")
    keep = ["conveyor.c", "conveyor.r.beam"]
    inputs = dict(slice_net(net, keep).net.new_sites.inputs)
    k = inputs["conveyor.r.beam"].index("blocked")
    assert ("conveyor.r.beam", k) in slice_net(net, keep).net.new_sites.free
    assert not slice_net(net, keep, env_new=True).net.new_sites.free
    r = verify(net, VerifyOptions(values=plan))  # type: ignore[arg-type]
    [p] = r.user_properties
    assert p.holds is False and "the slice of conveyor.c, conveyor.r.beam" in p.why, p.why
    cx = p.counterexample
    assert cx is not None
    labels = [t.label for t in (*cx.steps, *cx.to_cycle)]
    took = next(i for i, x in enumerate(labels) if "takes new blocked" in x)
    copied = next(i for i, x in enumerate(labels) if "computes part_here when new(blocked)" in x)
    assert took < copied < next(i for i, x in enumerate(labels) if "ends [present]" in x)


def test_the_properties_keep_their_share_of_the_time(monkeypatch: pytest.MonkeyPatch) -> None:
    """Safeness, deadlocks and progress that would take the whole run (here: a pass that
    waits out every second it is given) leave the properties PROPERTIES_SHARE of it: they
    are checked, not reported "not checked" (a fleet of the trial of issue 32 had its
    progress check take all 60 s and none of its three properties checked)."""
    import time

    from rssm_dsl.verify import verifier

    real = verifier._abstraction_first

    def slow(net: FlatNet, opts: VerifyOptions) -> object:
        assert opts.budget is not None
        while (opts.budget.remaining() or 0.0) > 0.05:
            time.sleep(0.05)
        return real(net, opts)

    monkeypatch.setattr(verifier, "_abstraction_first", slow)
    net, plan = _compiled("coin_toss.rssm")
    r = verify(net, VerifyOptions(values=plan, time_limit=20))  # type: ignore[arg-type]
    assert {p.name: p.holds for p in r.user_properties} == {"returns": False,
                                                             "tossed": True}
    assert r.verdict is Verdict.VIOLATED
