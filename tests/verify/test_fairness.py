"""Progress under weak and strong fairness (verify/progress.py): weak fairness reports every
loss of progress strong fairness reports, and also starvation by a schedule that passes
over a move enabled only now and then; its lasso's cycle is weakly fair."""

from __future__ import annotations

from pathlib import Path

import pytest

from rssm_dsl.hpn.flat import FlatNet, FlatTransition
from rssm_dsl.hpn.flatten import flatten
from rssm_dsl.pipeline import compile_file
from rssm_dsl.verify import VerifyOptions, verify
from rssm_dsl.verify.report import Counterexample, Verdict

ROOT = Path(__file__).parents[2]
SPECS = {
    # spec: (subsystems losing progress under strong fairness, under weak fairness)
    "tests/verify/specs/starve_weak.rssm": (set(), {"a2.c"}),
    "examples/verify/progress_triple.rssm": ({"left.c", "right.c"}, {"left.c", "right.c"}),
    "examples/relay_blocking.rssm": (set(), set()),
    "examples/verify/lockstep.rssm": (set(), set()),
}


def _net(spec: str) -> FlatNet:
    comp = compile_file(ROOT / spec)
    assert comp.hpn is not None, comp.diagnostics
    return flatten(comp.hpn)


def _lost(net: FlatNet, fairness: str) -> tuple[set[str], tuple[Counterexample, ...], str]:
    r = verify(net, VerifyOptions(time_limit=60, fairness=fairness, reduction="off"))
    assert r.progress_ok is not None, r.notes
    assert r.fairness == fairness
    return {c.subsystem for c in r.progress if c.subsystem}, r.progress, r.verdict.value


@pytest.mark.parametrize("spec", sorted(SPECS))
def test_weak_fairness_reports_a_superset_of_strong(spec: str) -> None:
    net = _net(spec)
    strong, _, _ = _lost(net, "strong")
    weak, _, _ = _lost(net, "weak")
    assert (strong, weak) == SPECS[spec]
    assert strong <= weak


def _fire(net: FlatNet, marking: frozenset[int], t: FlatTransition) -> frozenset[int]:
    assert marking >= set(t.pre), f"{t.label} is not enabled"
    return (marking - set(t.pre)) | set(t.post)


def _enabled(net: FlatNet, marking: frozenset[int]) -> set[int]:
    return {t.index for t in net.transitions if marking >= set(t.pre)}


def test_the_weak_lasso_is_weakly_fair_and_never_iterates_the_starved_one() -> None:
    net = _net("tests/verify/specs/starve_weak.rssm")
    _, (cx,), verdict = _lost(net, "weak")
    assert verdict == Verdict.VIOLATED.value and cx.subsystem == "a2.c"
    m = frozenset(net.initial)
    for t in cx.steps:
        m = _fire(net, m, t)
    start = m
    always: set[int] | None = None
    somewhere: set[int] = set()
    taken: set[int] = set()
    for t in cx.cycle:
        enabled = _enabled(net, m)
        always = enabled if always is None else always & enabled
        somewhere |= enabled
        m = _fire(net, m, t)
        taken.add(t.index)
        assert not (t.subsystem == "a2.c" and t.role.value == "iteration")
    assert m == start, "the cycle comes back"
    assert always is not None and always <= taken, "every move enabled throughout is taken"
    # the consumer's receive is enabled somewhere on the cycle, but not throughout
    take = {t.index for t in net.transitions if t.subsystem == "a2.c"
            and any(net.places[p].channel for p in t.pre)}
    assert take & somewhere and not take & always


def test_weak_fairness_needs_the_full_state_space() -> None:
    net = _net("tests/verify/specs/starve_weak.rssm")
    r = verify(net, VerifyOptions(time_limit=60, fairness="weak", reduction="on"))
    assert r.progress_ok is None and r.verdict is Verdict.INCONCLUSIVE
    assert any("weak fairness needs the full state space" in n for n in r.notes)


def test_the_report_states_the_fairness_it_assumed() -> None:
    net = _net("tests/verify/specs/starve_weak.rssm")
    r = verify(net, VerifyOptions(time_limit=60, fairness="weak"))
    data = r.to_json()
    assert data["progress_assumption"]["fairness"] == "weak"
    assert data["progress_assumption"]["text"].startswith("weak fairness")
    with pytest.raises(ValueError):
        VerifyOptions(fairness="fair")
