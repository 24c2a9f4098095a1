"""Partial deadlocks as empty siphons (rssm_dsl/verify/siphons.py).

Pinned here: the largest empty siphon of a marking against a brute force on small random nets;
what the sliced verification reports through it (the slices forced past their small full
exploration, so that the siphon search runs) against the whole net's exhaustive verdict
(``--reduction off``) on a table of small systems whose blocking group does not stall
together: the verdict, and which subsystems lose progress; every loss reported has a lasso
of the whole net whose cycle never iterates the subsystem; and the random shapes of
bench/verify_random.py with a planted deadlock are reported VIOLATED with a firing sequence
for every loss of progress."""

from __future__ import annotations

import importlib.util
import itertools
import random
import sys
from pathlib import Path
from types import ModuleType

import pytest
from netkit import NetBuilder, mode_pair, send_send_deadlock, starved_consumer

from rssm_core.firing import Net
from rssm_dsl.hpn.flat import FlatNet, Role
from rssm_dsl.hpn.flatten import flatten
from rssm_dsl.pipeline import compile_file
from rssm_dsl.verify import VerifyOptions, siphons, verify
from rssm_dsl.verify import sliced as sliced_mod
from rssm_dsl.verify.budget import Budget
from rssm_dsl.verify.report import VerifyReport
from rssm_dsl.verify.siphons import SiphonTest, find_stalls
from rssm_dsl.verify.sliced import _Whole, verify_sliced
from rssm_dsl.verify.slicing import blocking_groups, slice_net
from rssm_dsl.verify.stalls import StallTest

ROOT = Path(__file__).resolve().parents[2]


def _bench() -> ModuleType:
    spec = importlib.util.spec_from_file_location("verify_random",
                                                  ROOT / "bench" / "verify_random.py")
    assert spec is not None and spec.loader is not None
    mod = importlib.util.module_from_spec(spec)
    sys.modules["verify_random"] = mod
    spec.loader.exec_module(mod)
    return mod


VR = _bench()


def _system(tmp: Path, name: str, n: int, links: list[tuple[int, int, str]]) -> FlatNet:
    """Control subsystems only (no devices: the whole net stays small), linked as ``links``
    (from agent, to agent, link kind of bench/verify_random.py: B, N, W, P)."""
    agents = {k: VR.Agent(k) for k in range(1, n + 1)}
    for u, v, kind in links:
        agents[u].outs.append((v, kind))
        agents[v].ins.append((u, kind))
    text = "".join(VR._agent(a) for a in agents.values())
    path = tmp / f"{name}.rssm"
    path.write_text(f"system {name} {{\n{text}}}\n", encoding="utf-8")
    comp = compile_file(path)
    assert comp.ok and comp.hpn is not None, comp.diagnostics
    return flatten(comp.hpn)


# (name, agents, links): groups that do not stall together, stuck or not
SYSTEMS = [
    # a1 and a2 send to each other, blocking, before receiving: stuck for good; a3 takes what
    # a1 sends without waiting and runs on alone
    ("pair_and_server", 3, [(1, 2, "B"), (2, 1, "B"), (1, 3, "P")]),
    # a ring of blocking sends, and a server of a1 that runs on
    ("ring_and_server", 4, [(1, 2, "B"), (2, 3, "P"), (3, 1, "B"), (1, 4, "P")]),
    # a pair with one non-blocking send: live, and the server
    ("live_pair_and_server", 3, [(1, 2, "W"), (2, 1, "B"), (1, 3, "P")]),
    # a chain: the consumer of a blocking send takes without waiting, then a free send
    ("chain", 3, [(1, 2, "P"), (2, 3, "W")]),
    # a server fed by a blocking send, itself sending, blocking, to a pair stuck in a send-send
    ("server_feeds_stuck_pair", 4, [(1, 2, "P"), (3, 4, "B"), (4, 3, "B"), (2, 3, "P")]),
]


def _whole(net: FlatNet) -> tuple[object, ...]:
    r = verify(net, VerifyOptions(reduction="off", slicing=False, max_states=500_000,
                                  time_limit=120))
    assert r.complete
    return _summary(r)


def _summary(r: VerifyReport) -> tuple[object, ...]:
    lost = {c.subsystem for c in r.progress} | set(r.progress_lost)
    return (r.verdict, r.deadlock_free, r.progress_ok, frozenset(lost))


def _sliced(net: FlatNet, monkeypatch: pytest.MonkeyPatch) -> VerifyReport:
    """The sliced verification with no slice explored whole first: the stubborn sets, and
    before them the siphon search, decide each group."""
    monkeypatch.setattr(sliced_mod, "SMALL_SLICE", 1)
    budget = Budget(120.0)
    opts = VerifyOptions(reduction="on", slicing=False, budget=budget)
    return verify_sliced(net, blocking_groups(net), opts, budget, verify)  # type: ignore[arg-type]


def test_the_largest_empty_siphon_against_a_brute_force() -> None:
    rng = random.Random(7)
    for k in range(200):
        n = rng.randint(2, 7)
        b = NetBuilder(f"random{k}")
        for i in range(n):
            b.place(f"p{i}", marked=rng.random() < 0.3)
        arcs = []
        for i in range(rng.randint(1, 8)):
            pre = rng.sample(range(n), rng.randint(0, 2))
            post = rng.sample(range(n), rng.randint(0, 2))
            b.transition(f"t{i}", pre, post)
            arcs.append((sum(1 << p for p in pre), sum(1 << p for p in post)))
        net = b.build()
        marking = sum(1 << p for p in net.initial)
        best = 0
        for size in range(n + 1):
            for q in itertools.combinations(range(n), size):
                mask = sum(1 << p for p in q)
                # a siphon: whoever puts a token into it takes one from it
                if not mask & marking and all(not post & mask or pre & mask
                                              for pre, post in arcs):
                    best |= mask
        assert SiphonTest(net).empty_siphon(marking) == best


@pytest.mark.parametrize(("name", "n", "links"), SYSTEMS, ids=[s[0] for s in SYSTEMS])
def test_sliced_with_siphons_agrees_with_the_whole_net(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch, name: str, n: int,
        links: list[tuple[int, int, str]]) -> None:
    net = _system(tmp_path, name, n, links)
    group = max(blocking_groups(net), key=len)
    assert not StallTest(net).together(group), name
    expected = _whole(net)
    r = _sliced(net, monkeypatch)
    got = _summary(r)
    # deadlock freedom and progress may be left open when the siphons settled the group (a
    # stuck group whose lift is a deadlock of the whole net): never wrong
    assert got[1] in (None, expected[1]) and got[2] in (None, expected[2]), name
    assert (got[0], got[3]) == (expected[0], expected[3]), name
    for cx in r.progress:
        assert cx.cycle, name
        assert not any(t.subsystem == cx.subsystem and t.role is Role.ITERATION
                       for t in (*cx.to_cycle, *cx.cycle)), name
        _replays(net, (*cx.steps, *cx.to_cycle, *cx.cycle, *cx.cycle))


def _replays(net: FlatNet, steps: tuple[object, ...]) -> None:
    rule: Net = net.rule
    m = set(net.initial)
    for t in steps:
        i = t.index  # type: ignore[attr-defined]
        assert m.issuperset(rule.pre[i])
        m.difference_update(rule.consume[i])
        m.update(rule.produce[i])


def test_the_siphon_search_finds_the_planted_stall(tmp_path: Path) -> None:
    net = _system(tmp_path, "pair_and_server", 3, SYSTEMS[0][2])
    sl = slice_net(net, max(blocking_groups(net), key=len))
    found = find_stalls(sl, None, Budget(60.0), 10_000)
    assert {c.subsystem for c in found.found} == {"a1.c", "a2.c"}
    # the same from the deadlock-only stubborn-set search's graph, without the runs
    searched = siphons._search(sl, None, Budget(60.0), 10_000)
    assert searched.complete
    assert {c.subsystem for c in searched.found} == {"a1.c", "a2.c"}
    whole = _Whole(net, None)
    for cx in searched.found:
        _, progress = siphons.lift_stall(net, whole, sl, cx)
        assert [c.subsystem for c in progress] == [cx.subsystem]
        _replays(net, (*progress[0].steps, *progress[0].to_cycle, *progress[0].cycle))


def test_the_siphon_search_claims_nothing_on_small_nets() -> None:
    """Groups of the stall table of test_stalls.py: a starved consumer (its producer spins
    without sending: no siphon, the consumer's take stays possible), a non-blocking
    consumer and a send-send deadlock with a third party: what it claims the whole net
    confirms."""
    for net in (starved_consumer(), mode_pair(True, False), send_send_deadlock(third=True)):
        whole = verify(net, VerifyOptions(reduction="off", slicing=False))
        lost = {c.subsystem for c in whole.progress} | set(whole.progress_lost)
        for group in blocking_groups(net):
            found = find_stalls(slice_net(net, group), None, Budget(60.0), 10_000)
            claimed = {c.subsystem for c in found.found}
            assert claimed <= lost or whole.deadlocks, (net.system, claimed, lost)


@pytest.mark.parametrize("n", [5, 10, 20])
def test_planted_rings_are_violated_with_a_lasso_for_every_loss(tmp_path: Path, n: int) -> None:
    path = tmp_path / f"ring{n}.rssm"
    path.write_text(VR.random_system(n, "ring", "deadlock", 1), encoding="utf-8")
    comp = compile_file(path)
    assert comp.ok and comp.hpn is not None
    net = flatten(comp.hpn)
    r = verify(net, VerifyOptions(time_limit=120))
    assert r.verdict.name == "VIOLATED"
    assert r.progress and all(c.steps and c.cycle for c in r.progress)
    assert not r.progress_lost or set(r.progress_lost) <= {c.subsystem for c in r.progress}
    assert not r.unconfirmed
    for cx in r.progress:
        _replays(net, (*cx.steps, *cx.to_cycle, *cx.cycle, *cx.cycle))


def test_a_cap_reached_in_the_siphon_search_stops_only_the_search(tmp_path: Path) -> None:
    """A first try under a cap (the falsifier's first second) that ends in the siphon
    search: the search returns empty-handed, the cap is hit, the run's own stop is clear."""
    net = _system(tmp_path, "pair_and_server", 3, SYSTEMS[0][2])
    sl = slice_net(net, max(blocking_groups(net), key=len))
    budget = Budget(60.0)
    with budget.capped(0.0) as cap:
        found = find_stalls(sl, None, budget, 10_000)
    assert not found.found and cap.hit and budget.stop is None
