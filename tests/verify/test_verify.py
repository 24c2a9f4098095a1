from __future__ import annotations

import json

import pytest
from netkit import (
    hpn_like,
    mode_pair,
    pipeline_ring,
    ring,
    send_send_deadlock,
    starved_consumer,
    terminating_pipeline,
    unsafe_net,
)

from rssm_dsl.verify import (
    Verdict,
    VerifyOptions,
    exit_code,
    render_json,
    render_text,
    step_text,
    verify,
)


@pytest.mark.parametrize("pb", [True, False])
@pytest.mark.parametrize("cb", [True, False])
def test_mode_pairs_verified(pb: bool, cb: bool) -> None:
    r = verify(mode_pair(pb, cb))
    assert r.verdict is Verdict.VERIFIED and r.exit_code == 0
    assert r.safe and r.safe_by == "place invariants"
    assert r.deadlock_free and r.progress_ok
    assert r.method == "full" and r.complete
    assert r.uncovered_places == ()


def test_deadlock_report() -> None:
    r = verify(send_send_deadlock())
    assert r.verdict is Verdict.VIOLATED and r.exit_code == 1
    assert r.deadlock_free is False and r.deadlock_count == 1
    cx = r.deadlocks[0]
    assert len(cx.steps) == 4
    assert set(cx.marking) == {"ab.full", "ba.full", "A.snd.ab.wait", "B.snd.ba.wait"}
    text = render_text(r)
    assert "deadlock 1 of 1" in text
    assert f"1. {step_text(cx.steps[0])}" in text
    assert "(test.rssm:" in step_text(cx.steps[0])
    assert "A.iterate" in {t.name for t in r.dead_transitions or ()}
    assert r.unreachable_behaviours and any("A.main" in b for b in r.unreachable_behaviours)


def test_progress_report() -> None:
    r = verify(send_send_deadlock(third=True))
    assert r.verdict is Verdict.VIOLATED
    assert r.deadlock_free is True and r.progress_ok is False
    assert [c.subsystem for c in r.progress] == ["A", "B"]
    text = render_text(r)
    assert "loss of progress: A never completes an iteration again" in text
    assert "and then forever:" in text
    data = json.loads(render_json(r))
    assert data["progress"][0]["subsystem"] == "A"
    assert data["progress"][0]["cycle"][0]["name"] == "C.work"


def test_starved_consumer_report() -> None:
    r = verify(starved_consumer())
    assert r.verdict is Verdict.VIOLATED and [c.subsystem for c in r.progress] == ["C"]


def test_unsafe_report() -> None:
    r = verify(unsafe_net())
    assert r.verdict is Verdict.VIOLATED and r.safe is False
    assert r.unsafe is not None and r.unsafe.doubled == ("x",)
    assert "would put a second token into: x" in render_text(r)
    assert set(r.uncovered_places) == {"a", "b", "x", "y"}


def test_final_marking_verified() -> None:
    r = verify(terminating_pipeline(3))
    assert r.verdict is Verdict.VERIFIED


def test_state_limit_falls_back_to_the_compositional_check() -> None:
    # (the place invariants alone show this ring deadlock-free: test_fleet.py, deadmarking)
    r = verify(pipeline_ring(8, "BB"), VerifyOptions(auto_full_states=1000,
                                                      dead_markings=False))
    assert r.method == "full+compositional"
    assert r.deadlock_free is True and r.safe is True and r.progress_ok is True
    assert r.verdict is Verdict.VERIFIED and r.dead_transitions is None
    assert any("state limit" in n for n in r.notes)
    assert any("compositional check:" in n for n in r.notes)
    r = verify(pipeline_ring(8, "BB"), VerifyOptions(max_states=100, dead_markings=False))
    assert r.progress_ok is None and r.verdict is Verdict.INCONCLUSIVE and r.exit_code == 3
    # with the invariants' proof no state is needed: progress follows from deadlock freedom
    r = verify(pipeline_ring(8, "BB"), VerifyOptions(max_states=100))
    assert r.verdict is Verdict.VERIFIED and r.method == "invariants"


def test_reduction_on() -> None:
    r = verify(pipeline_ring(8, "BB"), VerifyOptions(reduction="on"))
    assert r.method == "stubborn" and r.verdict is Verdict.VERIFIED and r.states < 1000
    assert r.progress_ok is True
    r = verify(ring(6), VerifyOptions(reduction="on"))
    assert r.verdict is Verdict.VIOLATED and r.deadlock_count == 1
    r = verify(send_send_deadlock(third=True), VerifyOptions(reduction="on"))
    assert r.verdict is Verdict.VIOLATED and [c.subsystem for c in r.progress] == ["A", "B"]
    assert r.deadlock_free is True


def test_everything_limited_is_inconclusive() -> None:
    r = verify(ring(8), VerifyOptions(max_states=10, reduction="off", invariants=False))
    assert r.verdict is Verdict.INCONCLUSIVE and r.safe is None and r.deadlock_free is None


def test_found_violation_wins_over_limits() -> None:
    r = verify(ring(4), VerifyOptions(reduction="off"))
    assert r.verdict is Verdict.VIOLATED


def test_progress_check_can_be_switched_off() -> None:
    # safe and deadlock-free, but the loss of progress goes unchecked: not plain VERIFIED
    r = verify(send_send_deadlock(third=True), VerifyOptions(check_progress=False))
    assert r.verdict is Verdict.VERIFIED_WITHOUT_PROGRESS and r.progress_ok is None
    assert r.exit_code == 4 and r.headline().startswith("VERIFIED (progress not checked)")
    assert r.properties()["progress"] == {"status": "not checked", "by": None,
                                          "why": "--no-progress-check"}


def test_json_is_complete_and_serialisable() -> None:
    r = verify(hpn_like(2, 2, 2))
    data = json.loads(render_json(r))
    assert data["verdict"] == "verified" and data["exit_code"] == 0
    assert data["state_space"]["states"] == r.states
    assert data["invariants"]["list"][0]["proves_safe"]
    assert isinstance(data["dead_transitions"], list)


def test_exit_codes() -> None:
    # 2 is left to usage errors and bad input
    assert [exit_code(v) for v in Verdict] == [0, 1, 3, 4]


def test_options_are_checked() -> None:
    with pytest.raises(ValueError):
        VerifyOptions(reduction="maybe")
