from __future__ import annotations

import pytest
from netkit import (
    NetBuilder,
    hpn_like,
    loop,
    mode_pair,
    pipeline_ring,
    send_send_deadlock,
    starved_consumer,
    terminating_pipeline,
)

from rssm_dsl.hpn.flat import FlatNet, Role
from rssm_dsl.verify.netbits import NetBits
from rssm_dsl.verify.progress import ProgressResult, check_progress, live_places
from rssm_dsl.verify.statespace import explore_full


def progress(net: FlatNet) -> ProgressResult:
    nb = NetBits.of(net)
    r = explore_full(nb)
    assert r.graph is not None
    return check_progress(nb, r.graph)


def stuck(net: FlatNet) -> list[str]:
    return [v.subsystem for v in progress(net).violations]


def names(net: FlatNet, steps: tuple[int, ...]) -> list[str]:
    return [net.transitions[t].name for t in steps]


@pytest.mark.parametrize("pb", [True, False])
@pytest.mark.parametrize("cb", [True, False])
def test_mode_pairs_make_progress(pb: bool, cb: bool) -> None:
    r = progress(mode_pair(pb, cb))
    assert r.checked == ("prod", "cons") and not r.violations


def test_partial_deadlock_behind_a_running_process() -> None:
    net = send_send_deadlock(third=True)
    r = progress(net)
    assert [v.subsystem for v in r.violations] == ["A", "B"]
    v = r.violations[0]
    assert v.prefix == ()              # A can never iterate, from the very start
    assert sorted(names(net, v.to_cycle)) == sorted(
        ["A.snd.ab", "A.snd.ab.done", "B.snd.ba", "B.snd.ba.done"])
    assert names(net, v.cycle) == ["C.work", "C.iterate"]


def test_global_deadlock_is_not_reported_as_loss_of_progress() -> None:
    assert stuck(send_send_deadlock()) == []


def test_starved_consumer() -> None:
    net = starved_consumer()
    r = progress(net)
    assert [v.subsystem for v in r.violations] == ["C"]
    v = r.violations[0]
    assert names(net, v.prefix)[-1] == "C.iterate"   # the last iteration C ever completes
    assert sorted(names(net, v.cycle)) == ["P.idle", "P.spin"]


def test_finished_subsystem_is_not_stuck() -> None:
    # w0 runs once and finishes while w1 keeps looping forever
    b = NetBuilder("fin")
    b.place("w0.a", marked=True, subsystem="w0")
    b.place("w0.done", subsystem="w0")
    b.transition("w0.run", ["w0.a"], ["w0.done"], Role.ITERATION, subsystem="w0")
    b.place("w1.a", marked=True, subsystem="w1")
    b.place("w1.b", subsystem="w1")
    b.transition("w1.work", ["w1.a"], ["w1.b"], subsystem="w1")
    loop(b, "w1", "w1.a", "w1.b")
    net = b.build(subsystems=["w0", "w1"])
    assert live_places(net, "w0") == 1 << net.place("w0.a").index
    assert stuck(net) == []


def test_terminating_system() -> None:
    assert stuck(terminating_pipeline(3)) == []


def test_subsystem_without_iteration_is_skipped() -> None:
    b = NetBuilder("x")
    b.place("a", marked=True, subsystem="idle")
    b.transition("t", ["a"], ["a"], subsystem="idle")
    r = progress(b.build(subsystems=["idle"]))
    assert r.skipped == ("idle",) and not r.violations


def test_livelock_in_non_terminal_component_is_not_reported() -> None:
    # P may loop forever without letting C move, but C can always still iterate (fairness)
    b = NetBuilder("fair")
    b.place("tok", marked=True)
    b.place("P.a", marked=True, subsystem="P")
    b.place("P.b", subsystem="P")
    b.transition("P.go", ["P.a", "tok"], ["P.b", "tok"], subsystem="P")
    loop(b, "P", "P.a", "P.b")
    b.place("C.a", marked=True, subsystem="C")
    b.place("C.b", subsystem="C")
    b.transition("C.go", ["C.a", "tok"], ["C.b", "tok"], subsystem="C")
    loop(b, "C", "C.a", "C.b")
    assert stuck(b.build(subsystems=["P", "C"])) == []


def test_blocking_ring_makes_progress_and_realistic_net_too() -> None:
    assert stuck(pipeline_ring(5, "BB")) == []
    assert stuck(hpn_like(3, 2, 2)) == []


def test_lasso_replays() -> None:
    net = send_send_deadlock(third=True)
    nb = NetBits.of(net)
    r = explore_full(nb)
    assert r.graph is not None
    v = check_progress(nb, r.graph).violations[0]
    m = nb.initial
    for t in v.prefix + v.to_cycle:
        assert m & nb.pre[t] == nb.pre[t]
        m = nb.fire(m, t)
    assert m == v.cycle_marking
    for t in v.cycle:
        assert m & nb.pre[t] == nb.pre[t]
        m = nb.fire(m, t)
    assert m == v.cycle_marking
