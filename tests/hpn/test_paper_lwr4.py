"""The LWR4+ example's HPN matches the paper's Figs. 7-16, layer by layer.

Counts are of the net drawn on each page: its places, transitions and sub-pages (double
circles), as the paper draws them in section V."""

from __future__ import annotations

import pytest

from rssm_dsl.hpn.ir import HPN, PageKind
from rssm_dsl.pipeline import compile_file
from tests.conftest import EXAMPLES


@pytest.fixture(scope="module")
def hpn() -> HPN:
    comp = compile_file(EXAMPLES / "lwr4_circle.rssm")
    assert comp.ok and comp.hpn is not None
    return comp.hpn


def net(hpn: HPN, page: str) -> tuple[set[str], set[str], set[str]]:
    places, transitions, subpages, _ = hpn.contents(page)
    return {p.id for p in places}, {t.id for t in transitions}, {s.id for s in subpages}


def test_fig7_system_layer(hpn: HPN) -> None:
    assert net(hpn, "H") == ({"p[in]", "p[out]"}, {"t[in]", "t[out]"}, {"P[1]"})
    assert hpn.places["p[in]"].initial


def test_fig8_agent_layer_has_c_and_e_but_not_the_device(hpn: HPN) -> None:
    assert net(hpn, "P[1]") == ({"p[1,in]", "p[1,out]"}, {"t[1,in]", "t[1,out]"},
                                {"P[1,c]", "P[1,lwr]"})
    assert hpn.pages["P^E[1,lwr]"].parent is None  # E_{1,lwr} is a device net, not in H_1


def test_fig9_control_subsystem_switches_cw_ccw(hpn: HPN) -> None:
    places, transitions, pages = net(hpn, "P[1,c]")
    assert pages == {"P^B[1,c,cw]", "P^B[1,c,ccw]"}
    assert places == {"p[1,c,in]", "p[1,c,out]"}
    assert transitions == {"t[1,c,in]", "t[1,c,1]", "t[1,c,2]"}
    arcs = {(a.source, a.target) for a in hpn.arcs if a.page == "P[1,c]"}
    assert ("P^B[1,c,cw]", "t[1,c,1]") in arcs and ("t[1,c,1]", "P^B[1,c,ccw]") in arcs
    assert ("P^B[1,c,ccw]", "t[1,c,2]") in arcs and ("t[1,c,2]", "P^B[1,c,cw]") in arcs


def test_fig10_virtual_effector_single_behaviour(hpn: HPN) -> None:
    assert net(hpn, "P[1,lwr]") == ({"p[1,lwr,in]", "p[1,lwr,out]"}, {"t[1,lwr,in]"},
                                    {"P^B[1,lwr,move]"})


def test_fig11_behaviour_pattern_without_receive(hpn: HPN) -> None:
    places, transitions, pages = net(hpn, "P^B[1,c,cw]")
    assert places == {"p[1,c,cw,in]", "p[1,c,cw,2]", "p[1,c,cw,out]"}
    assert pages == {"P^f[1,c,cw]", "P^B[1,c,cw,snd]"}
    assert transitions == {"t[1,c,cw,in]", "t[1,c,cw,1]", "t[1,c,cw,2]", "t[1,c,cw,4]",
                           "t[1,c,cw,out]"}
    op = hpn.places["p[1,c,cw,2]"].operation
    assert op is not None and op.text == "i := i + 1"
    t4, t_out = hpn.transitions["t[1,c,cw,4]"], hpn.transitions["t[1,c,cw,out]"]
    assert t4.condition is not None and t4.condition.text == "not (full_circle)"
    assert t_out.condition is not None and t_out.condition.text == "full_circle"
    # the ccw behaviour has the same structure (Fig. 11 with cw -> ccw)
    assert len(net(hpn, "P^B[1,c,ccw]")[1]) == 5


def test_fig12_behaviour_pattern_with_receive(hpn: HPN) -> None:
    places, transitions, pages = net(hpn, "P^B[1,lwr,move]")
    assert places == {"p[1,lwr,move,in]", "p[1,lwr,move,2]", "p[1,lwr,move,out]"}
    assert pages == {"P^f[1,lwr,move]", "P^B[1,lwr,move,snd]", "P^B[1,lwr,move,rcv]"}
    assert len(transitions) == 6  # t_in, t_1, t_2, t_3, t_4, t_out
    # `terminal never when false`: t_out's condition is constant false (endless behaviour)
    t_out = hpn.transitions["t[1,lwr,move,out]"]
    assert t_out.condition is not None and t_out.condition.constant is False


def test_fig13_fig14_send_arrangements_one_nonblocking_page(hpn: HPN) -> None:
    for page, sub in (("P^B[1,c,cw,snd]", "P^B[1,c,cw,snd,1]"),
                      ("P^B[1,c,ccw,snd]", "P^B[1,c,ccw,snd,1]"),
                      ("P^B[1,lwr,move,snd]", "P^B[1,lwr,move,snd,1]")):
        assert net(hpn, page)[2] == {sub}
        places, transitions, _ = net(hpn, sub)
        # non-blocking producer: in + empty -> op | in + full -> op (overwrite); op -> out + full
        assert len(transitions) == 3
        assert {hpn.places[p].fusion is not None for p in places} == {True, False}


def test_fig15_receive_arrangement_is_sequential(hpn: HPN) -> None:
    _places, transitions, pages = net(hpn, "P^B[1,lwr,move,rcv]")
    assert pages == {"P^B[1,lwr,move,rcv,1]", "P^B[1,lwr,move,rcv,2]"}
    arcs = {(a.source, a.target) for a in hpn.arcs if a.page == "P^B[1,lwr,move,rcv]"}
    middle = [t for t in transitions if ("P^B[1,lwr,move,rcv,1]", t) in arcs]
    assert len(middle) == 1 and (middle[0], "P^B[1,lwr,move,rcv,2]") in arcs
    for k in (1, 2):  # non-blocking consumer: take new data, or go on with what it had
        assert len(net(hpn, f"P^B[1,lwr,move,rcv,{k}]")[1]) == 3


def test_fig16_canonical_decomposition_and_data_availability(hpn: HPN) -> None:
    assert net(hpn, "P^f[1,lwr,move]")[2] == {"P^f[1,lwr,move,1]", "P^f[1,lwr,move,2]"}
    # mu + 1 = 2 partial functions (torque, memory), each with 2^nu = 4 cases (Eq. 5)
    for psi in (1, 2):
        places, _transitions, _ = net(hpn, f"P^f[1,lwr,move,{psi}]")
        assert len([p for p in places if not p.endswith(("in]", "out]"))]) == 4
    conds = [hpn.transitions[f"t[1,lwr,move,1,{w}]"].condition for w in range(1, 5)]
    assert [c.new if c else None for c in conds] == [
        (True, True), (False, True), (True, False), (False, False)]
    ops = [hpn.places[f"p[1,lwr,move,1,{w}]"].operation for w in range(1, 5)]
    assert [o.void if o else None for o in ops] == [False, False, True, True]


def test_page_kinds_per_layer(hpn: HPN) -> None:
    kinds: dict[PageKind, int] = {}
    for p in hpn.pages.values():
        kinds[p.kind] = kinds.get(p.kind, 0) + 1
    assert kinds[PageKind.SYSTEM] == 1 and kinds[PageKind.AGENT] == 1
    assert kinds[PageKind.SUBSYSTEM] == 2 and kinds[PageKind.BEHAVIOUR] == 3
    assert kinds[PageKind.FUNCTION] == 3 and kinds[PageKind.PARTIAL] == 2 * 2 + 2
    assert kinds[PageKind.DEVICE] == 1
    # two channels c -> e and e <-> E: 3 channels, each two fused places
    assert len(hpn.fusions) == 6
