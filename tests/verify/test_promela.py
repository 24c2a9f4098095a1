from __future__ import annotations

import pytest
from conftest import requires_spin
from netkit import (
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
from rssm_dsl.verify.netbits import NetBits
from rssm_dsl.verify.promela import parse_pan, run_spin, to_promela
from rssm_dsl.verify.statespace import explore_full

PAN_OK = """
(Spin Version 6.5.2 -- 6 December 2019)
	+ Breadth-First Search
Full statespace search for:
	assertion violations	+
	invalid end states	+

State-vector 92 byte, depth reached 115, errors: 0
   118099 states, stored
   539947 states, matched
   658046 transitions (= stored+matched)
pan: elapsed time 0.21 seconds
pan: rate 562376.19 states/second
"""

PAN_DEADLOCK = """pan:1: invalid end state (at depth 5)
pan: wrote net.pml.trail
Warning: Search not completed
Full statespace search for:
	invalid end states	+
State-vector 28 byte, depth reached 5, errors: 1
       10 states, stored
"""


def test_promela_model_shape() -> None:
    text = to_promela(terminating_pipeline(2))
    assert "bit m[" in text and "active proctype net()" in text
    assert "d_step { m[0] = 1 };" in text                      # initial marking
    assert ":: d_step { m[0] -> assert(!(m[2] || m[4]));" in text
    assert "&& timeout) -> break" in text                      # final marking = valid end
    assert "/* t0 t_in */" in text


def test_test_arcs_do_not_assert() -> None:
    text = to_promela(mode_pair(True, False))
    line = next(x for x in text.splitlines() if "cons.rcv.ch.nothing" in x)
    # in + empty -> out + empty: empty is read, not refilled
    assert "assert(!(m[5]))" in line and "m[1] = 0" not in line


def test_parse_pan() -> None:
    ok = parse_pan(PAN_OK)
    assert ok.ran and ok.errors == 0 and ok.complete
    assert ok.states_stored == 118099 and ok.transitions == 658046 and ok.depth == 115
    assert ok.rate == 562376.19
    dead = parse_pan(PAN_DEADLOCK)
    assert dead.deadlock and not dead.unsafe and not dead.complete and dead.error_depth == 5


def test_missing_spin_is_reported_not_raised(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr("rssm_dsl.verify.promela.find_tools", lambda: (None, None))
    r = run_spin(mode_pair(True, True))
    assert not r.available and not r.ran and "not installed" in r.message


NETS = [
    mode_pair(True, True), mode_pair(False, False), mode_pair(True, False),
    mode_pair(False, True), send_send_deadlock(), send_send_deadlock(True),
    terminating_pipeline(3), unsafe_net(), ring(5), pipeline_ring(5, "BB"),
    hpn_like(2, 2, 2, producer_blocking=True), hpn_like(2, 2, 2, finish=True),
    random_product(7, 3, 4, 2, final=True), random_product(3, 3, 4, 2, raw=0.3),
]


@requires_spin
@pytest.mark.parametrize("net", NETS, ids=lambda n: n.system)
def test_spin_agrees(net: FlatNet) -> None:
    ours = explore_full(NetBits.of(net), keep_graph=False)
    spin = run_spin(net, separate=True)
    assert spin.ran, spin.message
    assert spin.unsafe == (ours.unsafe is not None), spin.message
    if ours.unsafe is not None:
        # BFS on both sides: the shortest unsafe firing has the same length
        assert spin.error_depth == len(ours.unsafe.steps)
        return
    assert spin.deadlock == (ours.deadlock_count > 0), spin.message
    # SPIN stores one state before the initial marking, and two after each final one
    assert spin.states_stored == ours.states + 1 + 2 * ours.final_deadlock_count
    if ours.deadlocks:
        assert spin.error_depth == len(ours.deadlocks[0].steps) + 1


@requires_spin
def test_spin_counts_match_on_a_larger_net() -> None:
    net = pipeline_ring(7, "BB")
    ours = explore_full(NetBits.of(net), keep_graph=False)
    spin = run_spin(net)
    assert spin.complete and spin.errors == 0
    assert spin.states_stored == ours.states + 1
    assert spin.transitions == ours.edges + 2
