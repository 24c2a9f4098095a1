"""SPIN on progress verdicts: from the point of no return of every loss of
progress the verifier reports, SPIN finds no iteration of the subsystem and no deadlock; from
a marking where the subsystem can still iterate, SPIN finds the iteration."""

from __future__ import annotations

from pathlib import Path

import pytest
from conftest import requires_spin

from rssm_dsl.hpn.flat import FlatNet
from rssm_dsl.hpn.flatten import flatten
from rssm_dsl.pipeline import compile_file
from rssm_dsl.synth import mixed_ring_system
from rssm_dsl.verify import VerifyOptions, verify
from rssm_dsl.verify.promela import check_lasso
from rssm_dsl.verify.report import Verdict

ROOT = Path(__file__).parents[2]


def _net(path: Path) -> FlatNet:
    comp = compile_file(path)
    assert comp.hpn is not None, comp.diagnostics
    return flatten(comp.hpn)


def _ring(tmp_path: Path, links: str) -> FlatNet:
    path = tmp_path / f"ring_{links}.rssm"
    path.write_text(mixed_ring_system(4, links), encoding="utf-8")
    return _net(path)


# nets with losses of progress, and the subsystems that lose it
LOSSES = {
    "progress_triple": (lambda tmp: _net(ROOT / "examples" / "verify" / "progress_triple.rssm"),
                        {"left.c", "right.c"}),
    "ring of blocking links": (lambda tmp: _ring(tmp, "B"), {"a1.c", "a2.c", "a3.c", "a4.c"}),
}


@requires_spin
@pytest.mark.parametrize("name", sorted(LOSSES))
def test_spin_confirms_every_lasso_from_its_point_of_no_return(name: str,
                                                               tmp_path: Path) -> None:
    make, lost = LOSSES[name]
    net = make(tmp_path)
    r = verify(net, VerifyOptions(time_limit=60))
    assert r.verdict is Verdict.VIOLATED
    assert {c.subsystem for c in r.progress} == lost
    for c in r.progress:
        assert c.subsystem is not None
        check = check_lasso(net, c.steps, c.subsystem, timeout=120)
        assert check.confirmed is True, check


@requires_spin
def test_spin_refutes_a_point_from_which_the_subsystem_iterates(tmp_path: Path) -> None:
    net = _net(ROOT / "examples" / "relay_blocking.rssm")
    check = check_lasso(net, (), "a1.c", timeout=120)
    assert check.iterates is True and check.confirmed is False
    lockstep = _net(ROOT / "examples" / "verify" / "lockstep.rssm")
    check = check_lasso(lockstep, (), "robot.c", timeout=120)
    assert check.iterates is True and check.confirmed is False


@requires_spin
def test_a_lasso_that_does_not_replay_is_not_confirmed() -> None:
    net = _net(ROOT / "examples" / "verify" / "progress_triple.rssm")
    late = net.transitions[-1]          # not enabled at the start
    assert not set(net.initial) >= set(late.pre)
    check = check_lasso(net, (late,), "left.c", timeout=60)
    assert not check.ran and check.confirmed is None
