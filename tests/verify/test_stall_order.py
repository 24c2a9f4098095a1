"""Progress by the stall order (rssm_dsl/verify/stalls.py, ``StallTest.ordered``): groups
that do not stall together, whose progress the slice's deadlock check still decides.

Pinned here: which groups the order covers (a table), and the sliced verdict that uses it
against the whole net's exhaustive verdict (``--reduction off``): the verdict and which
subsystems lose progress agree, on live and stuck systems; that the verifier says it used the
order; and that weak fairness and tracked values do not use it."""

from __future__ import annotations

from pathlib import Path

import pytest
from test_siphons import VR, _summary, _system

from rssm_dsl.hpn.flat import FlatNet
from rssm_dsl.verify import VerifyOptions, verify
from rssm_dsl.verify.budget import Budget
from rssm_dsl.verify.report import VerifyReport
from rssm_dsl.verify.sliced import ORDERED, verify_sliced
from rssm_dsl.verify.slicing import blocking_groups
from rssm_dsl.verify.stalls import StallTest

# (name, agents, links, ordered?)
SYSTEMS = [
    # a1's and a2's stalls stop everyone; a3 runs on when a2 stops sending (non-blocking
    # send), but waits only on a2, which sends to it in every iteration
    ("pair_feeds_consumer", 3, [(1, 2, "B"), (2, 1, "P"), (2, 3, "W")], True),
    # the same pair stuck in a send-send deadlock: the slice deadlocks, a3 with it
    ("stuck_pair_feeds_consumer", 3, [(1, 2, "B"), (2, 1, "B"), (2, 3, "W")], True),
    # a chain fed forward by non-blocking sends into blocking receives: a1 runs on alone
    ("forward_chain", 3, [(1, 2, "W"), (2, 3, "W")], True),
    # a server that takes without waiting: its stall stops a1, nobody's stall stops it, and
    # a1 and a2 wait on each other: not covered
    ("pair_and_server", 3, [(1, 2, "W"), (2, 1, "B"), (1, 3, "P")], False),
]


def _sliced(net: FlatNet, **kw: object) -> VerifyReport:
    budget = Budget(120.0)
    opts = VerifyOptions(reduction="on", slicing=False, budget=budget, **kw)  # type: ignore[arg-type]
    return verify_sliced(net, blocking_groups(net), opts, budget, verify)  # type: ignore[arg-type]


@pytest.mark.parametrize(("name", "n", "links", "ordered"), SYSTEMS,
                         ids=[s[0] for s in SYSTEMS])
def test_the_stall_order_agrees_with_the_whole_net(
        tmp_path: Path, name: str, n: int, links: list[tuple[int, int, str]],
        ordered: bool) -> None:
    net = _system(tmp_path, name, n, links)
    group = max(blocking_groups(net), key=len)
    test = StallTest(net)
    assert not test.together(group), name
    assert (test.ordered(group) is not None) is ordered, name
    whole = verify(net, VerifyOptions(reduction="off", slicing=False, max_states=500_000))
    assert whole.complete
    expected = _summary(whole)
    r = _sliced(net)
    got = _summary(r)
    assert got[1] in (None, expected[1]) and got[2] in (None, expected[2]), name
    assert (got[0], got[3]) == (expected[0], expected[3]), name
    if ordered and expected[0].name == "VERIFIED":
        assert any(ORDERED in n_ for n_ in r.notes), name


def test_weak_fairness_does_not_use_the_order(tmp_path: Path) -> None:
    net = _system(tmp_path, "forward_chain", 3, SYSTEMS[2][2])
    r = _sliced(net, fairness="weak")
    assert not any(ORDERED in n for n in r.notes)


def test_a_random_live_ring_is_verified_by_the_order(tmp_path: Path) -> None:
    path = tmp_path / "ring5.rssm"
    path.write_text(VR.random_system(5, "ring", "live", 1), encoding="utf-8")
    from rssm_dsl.hpn.flatten import flatten
    from rssm_dsl.pipeline import compile_file

    comp = compile_file(path)
    assert comp.ok and comp.hpn is not None
    net = flatten(comp.hpn)
    assert StallTest(net).ordered(max(blocking_groups(net), key=len)) is not None
    r = verify(net, VerifyOptions(time_limit=120))
    assert r.verdict.name == "VERIFIED"
    assert any(ORDERED in n for n in r.notes)


def test_a_producer_that_stops_sending_proves_nobody() -> None:
    """netkit.starved_consumer: P sends once, then iterates for ever without sending; C
    waits for it, blocking. P's iterations do not meet the channel in every iteration, so
    the stall order proves nothing for C (C does lose progress), though P's stall stops C."""
    from netkit import starved_consumer

    net = starved_consumer()
    assert StallTest(net).ordered(("P", "C")) is None
    r = verify(net)
    assert r.progress_ok is False and [c.subsystem for c in r.progress] == ["C"]
