from __future__ import annotations

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from netkit import (
    NetBuilder,
    hpn_like,
    mode_pair,
    pipeline_ring,
    random_product,
    ring,
    send_send_deadlock,
    terminating_pipeline,
    unsafe_net,
)

from rssm_dsl.hpn.flat import FlatNet
from rssm_dsl.verify.invariants import place_invariants
from rssm_dsl.verify.netbits import NetBits, to_mask
from rssm_dsl.verify.progress import check_progress
from rssm_dsl.verify.statespace import explore_full
from rssm_dsl.verify.stubborn import _cycle_breakers, explore_reduced


def deadlock_set(net: FlatNet, reduced: bool, safe: int = 0) -> tuple[set[int], int, bool]:
    nb = NetBits.of(net)
    if reduced:
        r = explore_reduced(nb, safe, max_counterexamples=10**6)
    else:
        r = explore_full(nb, max_counterexamples=10**6)
    return {d.marking for d in r.deadlocks}, r.states, r.unsafe is not None


def check_same_verdicts(net: FlatNet) -> None:
    nb = NetBits.of(net)
    full = explore_full(nb, max_counterexamples=10**6)
    inv = place_invariants(net)
    flows = inv.token_flows()[0]
    for safe, nes in ((0, []), (to_mask(inv.safe_places), []), (to_mask(inv.safe_places), flows)):
        red = explore_reduced(nb, safe, max_counterexamples=10**6, semiflows=nes)
        assert (red.unsafe is None) == (full.unsafe is None), "safeness verdict differs"
        if full.unsafe is None:
            # deadlocks are preserved exactly: the same set of markings
            assert {d.marking for d in red.deadlocks} == {d.marking for d in full.deadlocks}
            assert red.deadlock_count == full.deadlock_count
            assert red.final_deadlock_count == full.final_deadlock_count
            assert red.states <= full.states
            assert red.complete
        else:
            assert red.unsafe is not None
            # the counterexample replays to an unsafe firing
            m = nb.initial
            for t in red.unsafe.steps[:-1]:
                assert m & nb.pre[t] == nb.pre[t] and not m & nb.produce[t]
                m = nb.fire(m, t)
            last = red.unsafe.steps[-1]
            assert m & nb.pre[last] == nb.pre[last] and m & nb.produce[last]


@pytest.mark.parametrize("net", [
    mode_pair(True, True), mode_pair(False, False), send_send_deadlock(),
    send_send_deadlock(True), terminating_pipeline(4), unsafe_net(), ring(5), ring(7),
    pipeline_ring(6, "BB"), pipeline_ring(4, "NN"), pipeline_ring(4, "BN"),
    hpn_like(2, 2, 2), hpn_like(3, 2, 2, producer_blocking=True),
    hpn_like(3, 2, 2, finish=True),
], ids=lambda n: n.system)
def test_reduced_and_full_agree(net: FlatNet) -> None:
    check_same_verdicts(net)


@pytest.mark.parametrize("seed", range(100))
def test_reduced_and_full_agree_random(seed: int) -> None:
    net = random_product(seed, machines=2 + seed % 3, states=3 + seed % 3,
                         shared=1 + seed % 3, raw=0.3 if seed % 3 == 0 else 0.0,
                         final=seed % 4 == 0)
    check_same_verdicts(net)


@settings(max_examples=60, deadline=None)
@given(seed=st.integers(0, 10**6), machines=st.integers(1, 5), states=st.integers(2, 5),
       shared=st.integers(0, 4), sync=st.sampled_from([0.3, 0.7, 1.0]),
       raw=st.sampled_from([0.0, 0.2, 0.5]), final=st.booleans())
def test_reduced_and_full_agree_hypothesis(seed: int, machines: int, states: int, shared: int,
                                           sync: float, raw: float, final: bool) -> None:
    check_same_verdicts(random_product(seed, machines, states, shared, sync, raw, final))


def test_reduction_is_effective_on_independent_work() -> None:
    nb = NetBits.of(pipeline_ring(8, "BB"))
    inv = place_invariants(nb.net)
    red = explore_reduced(nb, to_mask(inv.safe_places))
    full = explore_full(nb, keep_graph=False)
    assert red.deadlock_count == full.deadlock_count == 0
    assert full.states == 118098 and red.states < 200


def test_philosophers_deadlock_found_with_few_states() -> None:
    net = ring(10)
    nb = NetBits.of(net)
    red = explore_reduced(nb, to_mask(place_invariants(net).safe_places))
    assert red.deadlock_count == 1
    assert len(red.deadlocks[0].steps) == 10         # everybody took the left fork
    assert red.states < explore_full(nb, keep_graph=False).states / 10


def test_unsafe_found_through_the_up_set() -> None:
    # the doubled place is reachable only after independent work elsewhere
    b = NetBuilder("upset")
    b.place("s", marked=True)
    b.place("w0", marked=True)
    for i in range(6):
        b.transition(f"work{i}", [f"w{i}"], [f"w{i + 1}"])
    b.transition("fork", ["s"], ["a", "c"])
    b.transition("ta", ["a"], ["x"])
    b.transition("tc", ["c"], ["d"])
    b.transition("td", ["d"], ["x"])
    net = b.build()
    check_same_verdicts(net)
    nb = NetBits.of(net)
    assert explore_reduced(nb).unsafe is not None


def test_python_explorer_without_reduction_counts_every_state() -> None:
    nb = NetBits.of(ring(5))
    assert explore_reduced(nb, reduce=False).states == explore_full(nb).states


def check_same_progress(net: FlatNet, semiflows: bool = False) -> None:
    nb = NetBits.of(net)
    full = explore_full(nb)
    assert full.graph is not None
    expected = [v.subsystem for v in check_progress(nb, full.graph).violations]
    inv = place_invariants(net)
    safe = to_mask(inv.safe_places)
    red = explore_reduced(nb, safe, for_progress=True,
                          semiflows=inv.token_flows()[0] if semiflows else ())
    assert red.graph is not None and red.complete
    found = check_progress(nb, red.graph).violations
    assert [v.subsystem for v in found] == expected
    assert red.deadlock_count == full.deadlock_count
    for v in found:                      # the lasso is made of real firings
        m = nb.initial
        for t in v.prefix + v.to_cycle:
            assert m & nb.pre[t] == nb.pre[t]
            m = nb.fire(m, t)
        assert m == v.cycle_marking
        for t in v.cycle:
            assert m & nb.pre[t] == nb.pre[t]
            m = nb.fire(m, t)
        assert m == v.cycle_marking


@pytest.mark.parametrize("net", [
    mode_pair(True, True), mode_pair(False, True), send_send_deadlock(True),
    terminating_pipeline(3), ring(5), pipeline_ring(6, "BB"), pipeline_ring(4, "NN"),
    hpn_like(2, 2, 2), hpn_like(3, 2, 2, finish=True),
], ids=lambda n: n.system)
def test_reduced_progress_agrees(net: FlatNet) -> None:
    check_same_progress(net)


@pytest.mark.parametrize("seed", range(60))
def test_reduced_progress_agrees_random(seed: int) -> None:
    check_same_progress(random_product(seed, machines=2 + seed % 3, states=3 + seed % 3,
                                       shared=1 + seed % 3, sync=0.7, final=seed % 4 == 0))


@pytest.mark.parametrize("seed", range(80))
def test_reduced_and_full_agree_with_reads_and_semiflows(seed: int) -> None:
    """Transitions that only test a shared place (take it and put it back, as a tracked
    value is read) do not depend on one another: the sets leave them out of each other's
    closure, but not a transition that empties the place; a disabled transition's necessary
    enabling set may be the transitions that move the token of a one-token semiflow out of
    its marked place. Deadlocks, safeness and progress as the full search finds them."""
    net = random_product(seed, machines=2 + seed % 4, states=3 + seed % 3,
                         shared=1 + seed % 3, sync=0.8, read=0.5, final=seed % 5 == 0)
    check_same_verdicts(net)
    check_same_progress(net, semiflows=True)


def test_reads_keep_the_sets_small() -> None:
    """Machines that only read a shared flag are independent: the reduced search walks
    one interleaving of their steps, not the product."""
    from netkit import NetBuilder as B

    b = B("readers")
    b.place("flag", marked=True)
    for m in range(6):
        for s in range(4):
            b.place(f"m{m}.s{s}", marked=s == 0, subsystem=f"m{m}")
        for s in range(4):
            pre: list[int | str] = [f"m{m}.s{s}"]
            post: list[int | str] = [f"m{m}.s{(s + 1) % 4}"]
            if s == 1:
                pre.append("flag")
                post.append("flag")
            b.transition(f"m{m}.t{s}", pre, post, subsystem=f"m{m}")
    nb = NetBits.of(b.build(subsystems=[f"m{m}" for m in range(6)]))
    inv = place_invariants(nb.net)
    full = explore_full(nb, keep_graph=False)
    red = explore_reduced(nb, to_mask(inv.safe_places))
    assert full.states == 4 ** 6 and red.deadlock_count == full.deadlock_count == 0
    assert red.states <= 4 * 6 + 1


def test_cycle_proviso_expands_one_marking_per_cycle() -> None:
    # 0 -> 1 -> 2 -> 0 and 3 <-> 4, 5 alone; 4 is fully expanded already
    src = [0, 1, 2, 3, 4, 5]
    dst = [1, 2, 0, 4, 3, 5]
    partial = [True, True, True, True, False, True]
    assert sorted(_cycle_breakers(6, src, dst, partial)) == [0, 5]


def test_proviso_makes_the_reduced_graph_see_the_ignored_process() -> None:
    # C loops on its own; without the proviso the reduced graph may fire only C's loop
    net = send_send_deadlock(third=True)
    nb = NetBits.of(net)
    plain = explore_reduced(nb, to_mask(place_invariants(net).safe_places))
    with_proviso = explore_reduced(nb, to_mask(place_invariants(net).safe_places),
                                   for_progress=True)
    assert with_proviso.states >= plain.states
    assert with_proviso.graph is not None and plain.graph is None


def test_up_set_finds_an_unsafe_firing_only_an_interleaving_reaches() -> None:
    # A marks x and takes it back; B marks x after a first step of its own. x is doubled
    # only when B's second step comes while A holds x: lone transitions fired one at a time
    # (A's first, being lower) run A past it unless the up-set brings x's producers
    b = NetBuilder("upset2")
    b.place("a0", marked=True)
    b.place("b0", marked=True)
    b.transition("A.mark", ["a0"], ["a1", "x"])
    b.transition("A.take", ["a1", "x"], ["a2"])
    b.transition("B.step", ["b0"], ["b1"])
    b.transition("B.mark", ["b1"], ["b2", "x"])
    net = b.build()
    nb = NetBits.of(net)
    assert explore_full(nb).unsafe is not None
    assert explore_reduced(nb, to_mask(place_invariants(net).safe_places)).unsafe is not None
    check_same_verdicts(net)
