"""Groups that stall together (rssm_dsl/verify/stalls.py): a loss of progress inside such a
group is a deadlock of its slice, so the slice's deadlock check decides progress.

Pinned here: which groups stall together (a table, with the reason for each); the claim
itself, checked against the whole net's own progress check on every group of a table of nets
(a member loses progress in the whole net iff the slice deadlocks); that the claim needs the
structural test (a group that does not stall together loses progress with a deadlock-free
slice); and that the verifier uses the shortcut for rings, under strong fairness only."""

from __future__ import annotations

from pathlib import Path

from netkit import (
    mode_pair,
    pipeline_ring,
    send_send_deadlock,
    starved_consumer,
)

from rssm_dsl.hpn.flat import FlatNet
from rssm_dsl.hpn.flatten import flatten
from rssm_dsl.pipeline import compile_file
from rssm_dsl.synth import mixed_ring_system
from rssm_dsl.verify import VerifyOptions, verify
from rssm_dsl.verify.report import Verdict
from rssm_dsl.verify.slicing import blocking_groups, slice_net
from rssm_dsl.verify.stalls import stall_together

ROOT = Path(__file__).resolve().parents[2]
SHORTCUT = "progress follows from deadlock freedom"


def _spec(path: Path) -> FlatNet:
    comp = compile_file(path)
    assert comp.ok and comp.hpn is not None
    return flatten(comp.hpn)


def _ring(n: int, links: str, tmp: Path, effector_every: int = 3) -> FlatNet:
    path = tmp / f"ring_{links}_{n}_{effector_every}.rssm"
    path.write_text(mixed_ring_system(n, links, effector_every), encoding="utf-8")
    return _spec(path)


def _controllers(net: FlatNet) -> tuple[str, ...]:
    return max(blocking_groups(net), key=len)


# (net, group, stalls together?, why)
def _table(tmp: Path) -> list[tuple[str, FlatNet, tuple[str, ...], bool]]:
    rows: list[tuple[str, FlatNet, tuple[str, ...], bool]] = []
    # each c receives, blocking, its predecessor's message in every iteration: round the ring
    # (no effectors: the whole net is explored below)
    for links in ("B", "W"):
        net = _ring(3, links, tmp, effector_every=4)
        rows.append((f"ring {links}", net, _controllers(net), True))
    # a blocking send waits for the consumer's take, the blocking receive for the send
    for path in (ROOT / "examples" / "verify" / "deadlock_pair.rssm",
                 ROOT / "examples" / "verify" / "progress_triple.rssm",
                 ROOT / "examples" / "relay_blocking.rssm"):
        net = _spec(path)
        rows.append((path.name, net, _controllers(net), True))
    # the producer spins on without sending: the consumer needs it, not the other way round
    net = starved_consumer()
    rows.append(("starved consumer", net, ("C", "P"), False))
    # a non-blocking consumer takes data if there is any: it runs on without the producer
    net = mode_pair(True, False)
    rows.append(("blocking send, non-blocking receive", net, ("cons", "prod"), False))
    net = mode_pair(True, True)
    rows.append(("blocking pair", net, ("cons", "prod"), True))
    net = pipeline_ring(4, "NB")
    rows.append(("pipeline ring NB", net, tuple(net.subsystems), True))
    net = send_send_deadlock(third=True)
    rows.append(("send-send deadlock", net, ("A", "B"), True))
    return rows


def test_which_groups_stall_together(tmp_path: Path) -> None:
    for name, net, group, expected in _table(tmp_path):
        assert stall_together(net, group) is expected, name
    # the realistic handovers (too large for the whole-net comparison below)
    for name in ("handover.rssm", "handover_buggy.rssm"):
        net = _spec(ROOT / "examples" / "verify" / name)
        assert stall_together(net, _controllers(net)), name


def test_a_member_loses_progress_iff_the_slice_deadlocks(tmp_path: Path) -> None:
    """The claim of stalls.py against the whole net's own progress check, per group that
    stalls together; and the counterexample when a group does not."""
    seen = set()
    for name, net, group, together in _table(tmp_path):
        whole = verify(net, VerifyOptions(reduction="off", slicing=False, max_states=300_000))
        assert whole.complete, name
        lost = ({c.subsystem for c in whole.progress} | set(whole.progress_lost)) & set(group)
        sl = slice_net(net, group)
        alone = verify(sl.net, VerifyOptions(reduction="off", slicing=False,
                                             check_progress=False))
        assert alone.complete, name
        # stuck for good: a member loses progress, or the whole net deadlocks with it
        stuck = bool(lost) or bool(whole.deadlocks)
        if together:
            assert stuck == bool(alone.deadlocks), name
            seen.add(stuck)
        else:
            seen.add("apart" if lost and not alone.deadlocks else "apart, agreeing")
    # both outcomes occur, and a group that does not stall together loses progress with a
    # deadlock-free slice: without the structural test the shortcut would be wrong
    assert {True, False, "apart"} <= seen


def test_the_verifier_decides_a_ring_by_its_slices_deadlocks(tmp_path: Path) -> None:
    net = _ring(8, "W", tmp_path)
    r = verify(net, VerifyOptions())
    assert r.verdict is Verdict.VERIFIED and r.progress_ok
    assert any(SHORTCUT in n for n in r.notes)
    assert set(_controllers(net)) <= set(r.progress_checked)


def test_a_stuck_ring_still_loses_progress_with_lassos(tmp_path: Path) -> None:
    net = _ring(6, "B", tmp_path)
    r = verify(net, VerifyOptions())
    assert r.verdict is Verdict.VIOLATED and r.deadlock_free
    assert {c.subsystem for c in r.progress} == set(_controllers(net))
    assert all(c.cycle for c in r.progress)


def test_weak_fairness_does_not_take_the_shortcut(tmp_path: Path) -> None:
    net = _ring(3, "W", tmp_path, effector_every=4)     # weak fairness: the full graph
    r = verify(net, VerifyOptions(fairness="weak"))
    assert r.verdict is Verdict.VERIFIED
    assert not any(SHORTCUT in n for n in r.notes)
