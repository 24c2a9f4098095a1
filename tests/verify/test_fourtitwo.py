from __future__ import annotations

import pytest
from conftest import requires_4ti2
from netkit import hpn_like, mode_pair, random_product, ring, send_send_deadlock, unsafe_net

from rssm_dsl.hpn.flat import FlatNet
from rssm_dsl.verify.fourtitwo import find_rays, parse_matrix, semiflows_4ti2
from rssm_dsl.verify.invariants import incidence_matrix, minimal_semiflows


def ours(net: FlatNet) -> tuple[tuple[int, ...], ...]:
    flows, complete, _ = minimal_semiflows(incidence_matrix(net))
    assert complete
    return tuple(sorted(tuple(f) for f in flows))


def test_parse_matrix() -> None:
    assert parse_matrix("2 3\n1 0 2\n0 1 1\n") == [(1, 0, 2), (0, 1, 1)]
    assert parse_matrix("") == []


def test_missing_tool_is_reported_not_raised(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr("rssm_dsl.verify.fourtitwo.find_rays", lambda: None)
    r = semiflows_4ti2(mode_pair(True, True))
    assert not r.available and "not installed" in r.message


@requires_4ti2
def test_rays_binary_found() -> None:
    assert find_rays() is not None


@requires_4ti2
@pytest.mark.parametrize("net", [
    mode_pair(True, True), mode_pair(False, True), mode_pair(True, False),
    mode_pair(False, False), send_send_deadlock(True), unsafe_net(), ring(5),
    hpn_like(subsystems=2, behaviours=2, branches=2),
], ids=["BB", "NB", "BN", "NN", "sendsend", "unsafe", "ring5", "hpnlike"])
def test_same_semiflows_as_4ti2(net: FlatNet) -> None:
    r = semiflows_4ti2(net)
    assert r.available, r.message
    assert r.semiflows == ours(net), r.message


@requires_4ti2
@pytest.mark.parametrize("seed", range(12))
def test_same_semiflows_as_4ti2_random(seed: int) -> None:
    net = random_product(seed, machines=3, states=4, shared=3, raw=0.3)
    r = semiflows_4ti2(net)
    assert r.semiflows == ours(net)
