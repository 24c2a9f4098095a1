from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from netkit import (
    NetBuilder,
    hpn_like,
    mode_pair,
    random_product,
    ring,
    send_send_deadlock,
    unsafe_net,
)

from rssm_dsl.hpn.flat import FlatNet
from rssm_dsl.verify.invariants import (
    InvariantResult,
    incidence_matrix,
    minimal_semiflows,
    place_invariants,
)


def texts(net: FlatNet, result: InvariantResult) -> list[str]:
    return sorted(i.render(net) for i in result.invariants)


@pytest.mark.parametrize("pb", [True, False])
@pytest.mark.parametrize("cb", [True, False])
def test_mode_pairs_are_covered_by_one_token_invariants(pb: bool, cb: bool) -> None:
    net = mode_pair(pb, cb)
    r = place_invariants(net)
    assert r.complete and r.message is None
    assert r.proves_safe(len(net.places))
    assert "ch.full + ch.empty + prod.snd.ch.op + cons.rcv.ch.op = 1" in texts(net, r)
    assert all(i.tokens == 1 for i in r.invariants)


def test_semiflows_are_invariant_and_minimal() -> None:
    net = send_send_deadlock(third=True)
    c = incidence_matrix(net)
    flows, complete, _ = minimal_semiflows(c)
    assert complete
    supports = [frozenset(np.flatnonzero(f)) for f in flows]
    for f in flows:
        assert not (np.array(f) @ c).any()
        assert min(f) >= 0 and max(f) > 0
    for a in supports:
        for b in supports:
            assert a == b or not a < b, "a support strictly contains another"
    assert len(set(supports)) == len(supports)


def test_weighted_invariant_and_partial_cover() -> None:
    net = unsafe_net()
    r = place_invariants(net)
    assert texts(net, r) == ["2*s + a + b + x + y = 2"]
    # 2*s with 2 tokens bounds s by 1; a, b, x, y only by 2
    assert r.safe_places == {net.place("s").index}
    assert not r.proves_safe(len(net.places))
    assert set(r.uncovered(len(net.places))) == {1, 2, 3, 4}


def test_place_without_arcs_is_its_own_invariant() -> None:
    b = NetBuilder()
    b.place("lonely", marked=True)
    b.place("a", marked=True)
    b.transition("t", ["a"], ["a"])          # a test arc only: incidence 0
    net = b.build()
    r = place_invariants(net)
    assert texts(net, r) == ["a = 1", "lonely = 1"]


def test_ring_invariants() -> None:
    net = ring(6)
    r = place_invariants(net)
    assert r.complete and r.proves_safe(len(net.places))
    assert len(r.invariants) == 12      # one per philosopher, one per fork


def test_blow_up_stops_with_a_clear_message_and_keeps_finished_invariants() -> None:
    net = hpn_like(subsystems=3, behaviours=3, branches=3)
    full = place_invariants(net)
    assert full.complete
    small = place_invariants(net, max_rows=20)
    assert not small.complete
    assert small.message is not None and "more than 20" in small.message
    finished = {i.weights for i in small.invariants}
    assert finished <= {i.weights for i in full.invariants}


def test_time_limit() -> None:
    net = hpn_like(subsystems=3, behaviours=3, branches=3)
    r = place_invariants(net, time_limit=0.0)
    assert not r.complete and r.message is not None and "time limit" in r.message


@settings(max_examples=40, deadline=None)
@given(seed=st.integers(0, 10**6), machines=st.integers(1, 4), states=st.integers(2, 5),
       shared=st.integers(0, 3))
def test_random_semiflows_are_exactly_the_minimal_ones(
        seed: int, machines: int, states: int, shared: int) -> None:
    net = random_product(seed, machines, states, shared, raw=0.2)
    c = incidence_matrix(net)
    flows, complete, _ = minimal_semiflows(c)
    assert complete
    for f in flows:
        assert not (np.array(f) @ c).any()
    supports = [frozenset(np.flatnonzero(f)) for f in flows]
    assert all(not (a < b) for a in supports for b in supports)
    # every state machine's places form an invariant carrying one token
    r = place_invariants(net)
    for m in range(machines):
        own = {p.index for p in net.places if p.subsystem == f"m{m}"}
        assert any(own <= inv.support for inv in r.invariants)
