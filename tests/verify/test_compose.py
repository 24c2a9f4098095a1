"""The compositional check against full exploration: same safeness, deadlock and progress
verdicts and the same reachable behaviours, on every example and on generated nets; and the
pieces it is built from (branching-bisimulation reduction, composition order)."""

from __future__ import annotations

import time
from pathlib import Path

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from netkit import (
    hpn_like,
    mode_pair,
    pipeline_ring,
    random_product,
    ring,
    send_send_deadlock,
    starved_consumer,
    terminating_pipeline,
    unsafe_net,
)

from rssm_dsl.hpn.flat import FlatNet
from rssm_dsl.hpn.flatten import flatten
from rssm_dsl.pipeline import compile_file
from rssm_dsl.synth import lean_ring_system
from rssm_dsl.verify import Verdict, VerifyOptions, verify
from rssm_dsl.verify.compose.cache import subtree_key
from rssm_dsl.verify.compose.check import compose_check
from rssm_dsl.verify.compose.lts import (
    FINAL,
    TAU,
    UNBOUNDED,
    Lts,
    interface_counts,
    minimize,
    refine,
)
from rssm_dsl.verify.compose.order import composition_order
from rssm_dsl.verify.compose.tree import page_tree
from rssm_dsl.verify.netbits import NetBits
from tests.conftest import REALISTIC

ROOT = Path(__file__).resolve().parents[2]
# the realistic examples are beyond full exploration, the reference here
EXAMPLES = sorted(p for p in (ROOT / "examples").rglob("*.rssm")
                  if "diagnostics" not in p.parts and p.stem not in REALISTIC)


def _net(path: Path) -> FlatNet:
    comp = compile_file(path)
    assert comp.ok and comp.hpn is not None
    return flatten(comp.hpn)


def _agree(net: FlatNet, must_complete: bool = True) -> None:
    full = verify(net, VerifyOptions(reduction="off", time_limit=120))
    res = compose_check(net, NetBits.of(net), 2_000_000, time.monotonic() + 120)
    if full.safe is False:
        # full exploration stops at the first unsafe firing; that verdict must be shared
        assert res.safe is False, res.stopped
        return
    if not full.complete:
        pytest.skip("full exploration does not finish")
    if not res.complete:
        # only the structural assumption may stop it, and then it claims nothing false
        assert not must_complete, res.stopped
        assert res.safe in (None, full.safe) and res.deadlock_free in (None, full.deadlock_free)
        return
    assert res.safe == full.safe
    assert res.deadlock_free == full.deadlock_free
    if full.safe and res.detail_complete and full.progress_ok is not None:
        assert set(res.progress_lost) == {c.subsystem for c in full.progress}
        assert set(res.progress_checked) == set(full.progress_checked)
        lost = set(full.unreachable_behaviours or ())
        mine = verify(net, VerifyOptions(reduction="compositional"))
        assert set(mine.unreachable_behaviours or ()) == lost


# the fleet example (a coordinator and eight robots): its full exploration, the reference
# here, does not end within its 120 s, so the case ended skipped after 145 s of the suite. The
# compositional check of the fleet itself runs in `rssmc verify` (the fleets of
# tests/verify/test_acceptance_specs.py); the other examples are this test's cases.
LONG_EXAMPLES = {"fleet", "handover_stall"}   # handover_stall: 18 s, the slowest of the rest


@pytest.mark.parametrize("path", [pytest.param(p, marks=pytest.mark.long)
                                  if p.stem in LONG_EXAMPLES else p for p in EXAMPLES],
                         ids=lambda p: p.name)
def test_examples_agree_with_full_exploration(path: Path) -> None:
    _agree(_net(path))


GENERATED = {
    **{f"mode_pair_{a}_{b}": (lambda a=a, b=b: mode_pair(a, b))
       for a in (False, True) for b in (False, True)},
    "send_send_deadlock": lambda: send_send_deadlock(False),
    "send_send_deadlock_third": lambda: send_send_deadlock(True),
    "starved_consumer": starved_consumer,
    "terminating_pipeline": lambda: terminating_pipeline(3),
    "unsafe_net": unsafe_net,
    **{f"ring_{n}": (lambda n=n: ring(n)) for n in (2, 3, 4, 5)},
    "ring_2_tokens": lambda: ring(4, tokens=2),
    "pipeline_ring_6_BB": lambda: pipeline_ring(6, "BB"),
    "pipeline_ring_5_NB": lambda: pipeline_ring(5, "NB"),
    "hpn_like": lambda: hpn_like(),
    **{f"random_product_{s}": (lambda s=s: random_product(s)) for s in range(12)},
}


@pytest.mark.parametrize("name", sorted(GENERATED))
def test_generated_nets_agree_with_full_exploration(name: str) -> None:
    _agree(GENERATED[name](), must_complete=False)


@pytest.mark.parametrize("n", [1, 2])
def test_lean_ring_matches_stubborn_sets(n: int, tmp_path: Path) -> None:
    path = tmp_path / "lean.rssm"
    path.write_text(lean_ring_system(n))
    net = _net(path)
    mine = verify(net, VerifyOptions(reduction="compositional", check_progress=False))
    theirs = verify(net, VerifyOptions(reduction="on", check_progress=False))
    assert mine.verdict is theirs.verdict is Verdict.VERIFIED_WITHOUT_PROGRESS
    assert mine.method == "compositional" and mine.complete


def test_the_deadlocking_pair_gets_its_counterexample_in_auto_mode() -> None:
    net = _net(ROOT / "examples" / "verify" / "deadlock_pair.rssm")
    r = verify(net, VerifyOptions(auto_full_states=10))
    assert "compositional" in r.method and r.deadlock_free is False
    assert r.deadlocks, "the stubborn-set search finds the firing sequence"


def test_loss_of_progress_without_full_exploration() -> None:
    net = _net(ROOT / "examples" / "verify" / "progress_triple.rssm")
    r = verify(net, VerifyOptions(reduction="compositional"))
    assert r.verdict is Verdict.VIOLATED and r.progress_ok is False
    assert set(r.progress_lost) == {"left.c", "right.c"}


def test_pages_become_a_tree_with_channels_under_the_lowest_common_page() -> None:
    net = _net(ROOT / "examples" / "relay_blocking.rssm")
    nodes = page_tree(net, NetBits.of(net))
    assert nodes[0].kind == "system"
    covered = 0
    for n in nodes:
        if n.own is not None:
            assert not covered & n.own.places, "every place in exactly one node"
            covered |= n.own.places
    assert covered == (1 << len(net.places)) - 1
    channels = [n for n in nodes if n.kind == "channel"]
    assert channels and all(nodes[n.parent].kind == "system"  # type: ignore[index]
                            for n in channels if n.parent is not None)


def _lts(edges: list[tuple[int, int, int]], n: int, flags: list[int] | None = None) -> Lts:
    out: list[list[tuple[int, int]]] = [[] for _ in range(n)]
    for s, a, d in edges:
        out[s].append((a, d))
    alphabet = frozenset(a for _, a, _ in edges if a != TAU)
    return Lts(0, flags or [0] * n, out, alphabet)


def test_minimize_merges_inert_silent_steps_and_keeps_deadlocks() -> None:
    # 0 -tau-> 1 -a-> 2 ; 0 -a-> 2 : branching bisimilar to one a-step
    m = minimize(_lts([(0, TAU, 1), (1, 5, 2), (0, 5, 2)], 3))
    assert m.size == 2 and m.out[0] == [(5, 1)] and m.out[1] == []
    # a silent choice into a deadlock is not inert: 0 -tau-> dead, 0 -a-> 2 -a-> 2
    m = minimize(_lts([(0, TAU, 1), (0, 5, 2), (2, 5, 2)], 3))
    assert m.size == 3 and any(not edges for edges in m.out)


def test_minimize_keeps_divergence_apart_from_deadlock() -> None:
    looping = minimize(_lts([(0, TAU, 1), (1, TAU, 0)], 2))
    assert looping.size == 1 and looping.out[0] == [(TAU, 0)]
    stuck = minimize(_lts([(0, TAU, 1)], 2))
    assert stuck.size == 1 and stuck.out[0] == []


def test_minimize_respects_flags() -> None:
    m = minimize(_lts([(0, TAU, 1)], 2, [0, FINAL]))
    assert m.size == 2 and m.flags == [0, FINAL]


def test_composition_order_walks_a_chain() -> None:
    # parts 0-1-2-3 in a chain, listed out of order: 0, 2, 3, 1
    alphabets = [{1}, {2, 3}, {3, 4}, {1, 2}]
    assert composition_order(alphabets) == [0, 3, 1, 2]


def _reference_refine(flags: list[int], div: list[bool],
                      edges_of: list[list[tuple[int, int]]]) -> list[int]:
    """Plain signature refinement (Blom and Orzan): every signature recomputed every round."""
    keys: dict[tuple[int, bool], int] = {}
    block = [keys.setdefault((flags[c], div[c]), len(keys)) for c in range(len(flags))]
    count = len(keys)
    while True:
        sigs: list[frozenset[tuple[int, int]]] = []
        for c, edges in enumerate(edges_of):
            sig: set[tuple[int, int]] = set()
            for a, d in edges:
                if a == TAU and block[d] == block[c]:
                    sig |= sigs[d]
                else:
                    sig.add((a, block[d]))
            sigs.append(frozenset(sig))
        new: dict[tuple[int, frozenset[tuple[int, int]]], int] = {}
        block = [new.setdefault((block[c], sigs[c]), len(new)) for c in range(len(flags))]
        if len(new) == count:
            return block
        count = len(new)


def _same_partition(x: list[int], y: list[int]) -> bool:
    pairs = set(zip(x, y, strict=True))
    return len(pairs) == len(set(x)) == len(set(y))


@st.composite
def _silent_dag(draw: st.DrawFn) -> tuple[list[int], list[bool], list[list[tuple[int, int]]]]:
    """A graph whose silent edges go to lower-numbered states, as ``refine`` expects."""
    n = draw(st.integers(1, 14))
    edges_of: list[list[tuple[int, int]]] = [[] for _ in range(n)]
    for _ in range(draw(st.integers(0, 3 * n))):
        c = draw(st.integers(0, n - 1))
        a = draw(st.sampled_from([TAU, TAU, 1, 2]))
        d = draw(st.integers(0, c - 1)) if a == TAU and c > 0 else draw(st.integers(0, n - 1))
        if a == TAU and c == 0:
            continue
        if (a, d) not in edges_of[c]:
            edges_of[c].append((a, d))
    flags = [draw(st.sampled_from([0, 0, FINAL])) for _ in range(n)]
    div = [draw(st.booleans()) for _ in range(n)]
    return flags, div, edges_of


@settings(max_examples=400, deadline=None)
@given(_silent_dag())
def test_incremental_refinement_finds_the_partition_of_plain_refinement(
        graph: tuple[list[int], list[bool], list[list[tuple[int, int]]]]) -> None:
    flags, div, edges_of = graph
    assert _same_partition(refine(flags, div, edges_of),
                           _reference_refine(flags, div, edges_of))


def test_incremental_refinement_counts_a_long_chain() -> None:
    # a counter: n states in a line, each a-step down, b-step up; all states differ
    n = 300
    edges_of = [[(1, c - 1)] if c else [] for c in range(n)]
    for c in range(n - 1):
        edges_of[c].append((2, c + 1))
    block = refine([0] * n, [False] * n, edges_of)
    assert len(set(block)) == n


@st.composite
def _lts_and_groups(draw: st.DrawFn) -> tuple[Lts, list[frozenset[int]]]:
    n = draw(st.integers(1, 12))
    actions = [1, 2, 3, 4]
    edges = []
    for _ in range(draw(st.integers(0, 3 * n))):
        edges.append((draw(st.integers(0, n - 1)), draw(st.sampled_from([TAU, TAU, *actions])),
                      draw(st.integers(0, n - 1))))
    flags = [draw(st.sampled_from([0, 0, FINAL])) for _ in range(n)]
    lts = _lts(edges, n, flags)
    split = draw(st.integers(1, 4))
    return lts, [frozenset(actions[:split]), frozenset(actions[split:])]


@settings(max_examples=300, deadline=None)
@given(_lts_and_groups())
def test_interface_counts_only_speed_the_reduction_up(case: tuple[Lts, list[frozenset[int]]]
                                                      ) -> None:
    lts, groups = case
    plain, seeded = minimize(lts), minimize(lts, groups)
    assert seeded.size == plain.size
    assert sorted(seeded.flags) == sorted(plain.flags)
    assert seeded.edge_count == plain.edge_count


def test_interface_counts_count_deliveries_without_input() -> None:
    # a buffer of 3 places: in (1) fills one, out (2) empties one; out-steps without input
    edges = [(c, 1, c + 1) for c in range(3)] + [(c + 1, 2, c) for c in range(3)]
    counts = interface_counts([[(a, d) for s, a, d in edges if s == c] for c in range(4)],
                              frozenset({2}))
    assert counts == [0, 1, 2, 3]
    assert interface_counts([[(1, 1)], [(1, 0)]], frozenset({1})) == [UNBOUNDED, UNBOUNDED]


def test_identical_agents_are_composed_once(tmp_path: Path) -> None:
    path = tmp_path / "ring.rssm"
    path.write_text(lean_ring_system(3))
    net = _net(path)
    nb = NetBits.of(net)
    reused = compose_check(net, nb, 2_000_000, time.monotonic() + 300)
    again = compose_check(net, nb, 2_000_000, time.monotonic() + 300, reuse=False)
    assert reused.complete and again.complete
    assert (reused.safe, reused.deadlock_free) == (again.safe, again.deadlock_free) == (True, True)
    assert reused.reached == again.reached
    assert reused.progress_checked == again.progress_checked
    assert reused.progress_lost == again.progress_lost == []
    verdict_only = [compose_check(net, nb, 2_000_000, time.monotonic() + 300, detail=False,
                                  reuse=reuse) for reuse in (True, False)]
    assert verdict_only[0].states < verdict_only[1].states / 2


def test_subtree_keys_tell_agents_and_subsystems_apart(tmp_path: Path) -> None:
    path = tmp_path / "ring.rssm"
    path.write_text(lean_ring_system(3))
    net = _net(path)
    nb = NetBits.of(net)
    nodes = page_tree(net, nb)
    users: dict[int, list[int]] = {}
    for k, node in enumerate(nodes):
        if node.own is not None:
            for t in node.own.transitions:
                users.setdefault(t, []).append(k)
    zero = [0] * len(nodes)
    none: list[frozenset[int]] = [frozenset()] * len(nodes)

    def key(kind: str, owner: str) -> object:
        k = next(k for k, n in enumerate(nodes) if n.kind == kind and n.owner == owner)
        return subtree_key(nodes, k, nb, users, zero, none)[0]

    assert key("agent", "a1") == key("agent", "a2") == key("agent", "a3")
    assert key("subsystem", "a1.e.left") == key("subsystem", "a2.e.right")
    assert key("subsystem", "a1.c") != key("subsystem", "a1.e.left")
