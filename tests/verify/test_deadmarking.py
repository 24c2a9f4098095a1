"""Deadlock freedom from the place invariants (rssm_dsl/verify/deadmarking.py): never claimed
for a net the full search finds a deadlock in, and it decides, without a search, the fleet
of seven robots that no exploration decides."""

from __future__ import annotations

from pathlib import Path

import pytest
from netkit import mode_pair, random_product, ring, send_send_deadlock, terminating_pipeline

from rssm_dsl.hpn.flat import FlatNet
from rssm_dsl.hpn.flatten import flatten
from rssm_dsl.pipeline import compile_file
from rssm_dsl.verify.cover import one_token_semiflows
from rssm_dsl.verify.datanet import track_new
from rssm_dsl.verify.deadmarking import dead_markings
from rssm_dsl.verify.invariants import place_invariants
from rssm_dsl.verify.netbits import NetBits
from rssm_dsl.verify.statespace import explore_full

SPECS = Path(__file__).resolve().parent / "specs"
ACCEPTANCE = Path(__file__).resolve().parent / "acceptance"


def _judged(net: FlatNet) -> tuple[bool, frozenset[int] | None, int]:
    """(proved, the dead marking found, the number of reachable deadlocks)."""
    nb = NetBits.of(net)
    flows, empty = place_invariants(net).token_flows()
    result = dead_markings(nb, flows, empty)
    full = explore_full(nb, max_counterexamples=1)
    assert full.complete
    return result.proved, result.found, full.deadlock_count


@pytest.mark.parametrize("seed", range(150))
def test_never_proved_where_the_full_search_finds_a_deadlock(seed: int) -> None:
    net = random_product(seed, machines=2 + seed % 4, states=2 + seed % 4,
                         shared=1 + seed % 3, sync=0.6 + 0.1 * (seed % 4),
                         read=0.3 if seed % 2 else 0.0, final=seed % 3 == 0)
    proved, found, deadlocks = _judged(net)
    if deadlocks:
        assert not proved
    if found is not None:                       # what it found is a dead, non-final marking
        nb = NetBits.of(net)
        m = sum(1 << p for p in found)
        assert all(m & pre != pre for pre in nb.pre)
        assert not (nb.final and m & nb.final == nb.final)


def test_the_seeds_hold_deadlocks_and_proofs() -> None:
    """The batch above is not vacuous: it has nets with deadlocks and nets proved free."""
    kinds = set()
    for seed in range(150):
        net = random_product(seed, machines=2 + seed % 4, states=2 + seed % 4,
                             shared=1 + seed % 3, sync=0.6 + 0.1 * (seed % 4),
                             read=0.3 if seed % 2 else 0.0, final=seed % 3 == 0)
        proved, _, deadlocks = _judged(net)
        kinds.add((proved, deadlocks > 0))
    assert {(True, False), (False, True)} <= kinds


@pytest.mark.parametrize("net, free", [
    (mode_pair(True, True), True), (send_send_deadlock(), False), (ring(5), False),
    (terminating_pipeline(4), True),
], ids=lambda x: getattr(x, "system", str(x)))
def test_small_nets(net: FlatNet, free: bool) -> None:
    proved, _, deadlocks = _judged(net)
    assert (deadlocks == 0) is free
    if not free:
        assert not proved


def _spec_net(path: Path) -> NetBits:
    comp = compile_file(path)
    assert comp.hpn is not None
    return NetBits.of(track_new(flatten(comp.hpn)).net)


def _flows(net: FlatNet) -> tuple[list[int], int]:
    """The one-token semiflows the verifier finds by search on a large net (as masks)."""
    flows, empty = [], 0
    for f in one_token_semiflows(net, range(len(net.places))):
        mask = sum(1 << p for p in f.support)
        if f.tokens == 1:
            flows.append(mask)
        else:
            empty |= mask
    return flows, empty


def test_the_fleet_of_seven_robots_is_proved_in_a_few_branchings() -> None:
    """The coordinator waits, blocking, for each robot's acknowledgement, and each robot
    until its acknowledgement is taken: the robot waits only while the channel is full, the
    coordinator only while it is empty, so no marking the invariants allow is dead."""
    nb = _spec_net(ACCEPTANCE / "fleet.rssm")
    flows, empty = _flows(nb.net)
    result = dead_markings(nb, flows, empty)
    assert result.proved and result.nodes < 100


def test_the_fleet_with_a_deadlock_is_not_proved() -> None:
    """fleet7_bug: the coordinator and a robot wait for each other (a real deadlock)."""
    nb = _spec_net(SPECS / "fleet7_bug.rssm")
    flows, empty = _flows(nb.net)
    result = dead_markings(nb, flows, empty)
    assert not result.proved and result.found is not None
