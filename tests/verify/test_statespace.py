from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from netkit import (
    NetBuilder,
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
from rssm_dsl.verify.statespace import Progress, _Table, explore_full
from rssm_dsl.verify.stubborn import explore_reduced


def names(net: FlatNet, steps: tuple[int, ...]) -> list[str]:
    return [net.transitions[t].name for t in steps]


def reachable_by_hand(net: FlatNet) -> set[frozenset[int]]:
    """A naive reference: sets of place indices, depth-first."""
    seen: set[frozenset[int]] = {net.initial}
    todo = [net.initial]
    while todo:
        m = todo.pop()
        for t in net.transitions:
            if set(t.pre) <= m:
                m2 = (m - set(t.pre)) | set(t.post)
                if m2 not in seen:
                    seen.add(m2)
                    todo.append(m2)
    return seen


@pytest.mark.parametrize("pb", [True, False])
@pytest.mark.parametrize("cb", [True, False])
def test_mode_pairs(pb: bool, cb: bool) -> None:
    net = mode_pair(pb, cb)
    r = explore_full(NetBits.of(net))
    assert r.complete and r.unsafe is None and r.deadlock_count == 0
    assert r.states == len(reachable_by_hand(net))
    assert r.fired is not None


def test_send_send_deadlock_shortest_counterexample() -> None:
    net = send_send_deadlock()
    r = explore_full(NetBits.of(net))
    assert r.deadlock_count == 1
    steps = names(net, r.deadlocks[0].steps)
    assert len(steps) == 4
    assert sorted(steps) == sorted(["A.snd.ab", "A.snd.ab.done", "B.snd.ba", "B.snd.ba.done"])
    assert steps.index("A.snd.ab") < steps.index("A.snd.ab.done")
    final = {net.places[p].name for p in NetBits.of(net).marking_of(r.deadlocks[0].marking)}
    assert final == {"ab.full", "ba.full", "A.snd.ab.wait", "B.snd.ba.wait"}


def test_third_process_hides_the_global_deadlock() -> None:
    r = explore_full(NetBits.of(send_send_deadlock(third=True)))
    assert r.complete and r.deadlock_count == 0


def test_final_marking_is_not_a_deadlock() -> None:
    r = explore_full(NetBits.of(terminating_pipeline(3)))
    assert r.deadlock_count == 0 and r.final_deadlock_count == 1
    assert r.states == 2 + 2 ** 3


def test_unsafe_firing_stops_with_counterexample() -> None:
    net = unsafe_net()
    r = explore_full(NetBits.of(net))
    assert r.unsafe is not None and not r.complete
    assert names(net, r.unsafe.steps)[0] == "fork" and len(r.unsafe.steps) == 3
    assert r.unsafe.places == 1 << net.place("x").index


def test_dead_transitions_and_ever_marked() -> None:
    net = send_send_deadlock()
    r = explore_full(NetBits.of(net))
    dead = {net.transitions[t].name for t in range(len(net.transitions))} - {
        net.transitions[t].name for t in r.fired or ()}
    assert "A.iterate" in dead and "A.snd.ab" not in dead
    assert r.ever_marked is not None
    assert not r.ever_marked >> net.place("A.s2").index & 1


def test_state_limit_and_time_limit_are_inconclusive() -> None:
    b = NetBits.of(ring(8))
    r = explore_full(b, max_states=100)
    assert not r.complete and r.stopped is not None and "state limit" in r.stopped
    r = explore_full(b, time_limit=0.0)
    assert not r.complete and r.stopped is not None and "time limit" in r.stopped


def test_progress_callback() -> None:
    seen: list[Progress] = []
    r = explore_full(NetBits.of(ring(6)), progress=seen.append)
    assert seen and seen[-1].states == r.states
    assert [p.depth for p in seen] == sorted(p.depth for p in seen)


def test_graph_edges_are_firings() -> None:
    net = ring(4)
    nb = NetBits.of(net)
    r = explore_full(nb)
    g = r.graph
    assert g is not None and g.src.size == r.edges
    for e in range(0, r.edges, 7):
        m = g.marking(int(g.src[e]))
        t = int(g.trans[e])
        assert m & nb.pre[t] == nb.pre[t]
        assert nb.fire(m, t) == g.marking(int(g.dst[e]))
    for s in range(g.size):
        m = nb.initial
        for t in g.path(s):
            m = nb.fire(m, t)
        assert m == g.marking(s)


def wide_net(n: int) -> NetBuilder:
    """n independent two-state toggles: 2**n states, n*? places spread over many words."""
    b = NetBuilder("wide")
    for i in range(n):
        b.place(f"a{i}", marked=True)
        for k in range(30):              # padding places so that the net spans words
            b.place(f"pad{i}.{k}")
        b.place(f"b{i}")
        b.transition(f"go{i}", [f"a{i}"], [f"b{i}"])
        b.transition(f"back{i}", [f"b{i}"], [f"a{i}"])
    return b


def test_multi_word_markings() -> None:
    net = wide_net(9).build()
    nb = NetBits.of(net)
    assert nb.nwords >= 4
    r = explore_full(nb)
    assert r.states == 2 ** 9 and r.complete


def test_transitions_spanning_words() -> None:
    b = wide_net(4)
    b.transition("sync", ["a0", "a3"], ["b0", "b3"])
    net = b.build()
    r = explore_full(NetBits.of(net))
    assert r.states == len(reachable_by_hand(net))


def test_hash_table_with_colliding_hashes() -> None:
    rng = np.random.default_rng(3)
    rows = rng.integers(0, 2**62, size=(300, 2), dtype=np.int64).astype(np.uint64)
    batch = np.concatenate([rows, rows[::3], rows[:50]])
    table = _Table(2, capacity=16)
    same_hash = np.zeros(batch.shape[0], dtype=np.uint64)     # every key collides
    ids, new = table.lookup_insert(same_hash, batch)
    assert table.size == 300 and new.size == 300
    assert (ids[:300] == np.arange(300)).all()
    assert (ids[300:400] == np.arange(0, 300, 3)).all()
    ids2, new2 = table.lookup_insert(np.zeros(300, dtype=np.uint64), rows[::-1].copy())
    assert new2.size == 0 and (ids2 == np.arange(299, -1, -1)).all()


@settings(max_examples=60, deadline=None)
@given(seed=st.integers(0, 10**6), machines=st.integers(1, 4), states=st.integers(2, 5),
       shared=st.integers(0, 3), raw=st.sampled_from([0.0, 0.3]), final=st.booleans())
def test_numpy_explorer_agrees_with_python_explorer(
        seed: int, machines: int, states: int, shared: int, raw: float, final: bool) -> None:
    net = random_product(seed, machines, states, shared, raw=raw, final=final)
    nb = NetBits.of(net)
    a = explore_full(nb)
    b = explore_reduced(nb, reduce=False)
    assert (a.unsafe is None) == (b.unsafe is None)
    if a.unsafe is None:
        assert a.states == b.states == len(reachable_by_hand(net))
        assert a.edges == b.edges
        assert a.deadlock_count == b.deadlock_count
        assert a.final_deadlock_count == b.final_deadlock_count
        # BFS: both give shortest counterexamples
        assert [len(d.steps) for d in a.deadlocks] == [len(d.steps) for d in b.deadlocks]
    else:
        assert b.unsafe is not None
        assert len(a.unsafe.steps) == len(b.unsafe.steps)


def test_pipeline_ring_counts() -> None:
    r = explore_full(NetBits.of(pipeline_ring(4, "BB")))
    assert r.complete and r.deadlock_count == 0
