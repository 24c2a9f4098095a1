"""The IR's structured names and indexes.

The indexes must agree with a brute-force scan of the tables on every example, follow every
change to the tables, and the structured names must print as the ids and say what the ids
say (agent, subsystem, behaviour, ...), so that nothing needs to parse an id."""

from __future__ import annotations

import copy
import pickle
from dataclasses import replace
from pathlib import Path

import pytest

from rssm_dsl.hpn.flat import FlatNet
from rssm_dsl.hpn.flatten import flatten
from rssm_dsl.hpn.ir import (
    HPN,
    SYSTEM_SCOPE,
    Arc,
    FusionName,
    Name,
    Page,
    PageKind,
    Place,
    Scope,
    Transition,
)
from rssm_dsl.hpn.wellformed import violations
from rssm_dsl.pipeline import compile_file
from rssm_dsl.source import Span
from tests.conftest import EXAMPLES, example_specs

SPAN = Span("x.rssm", 1, 1, 1, 2)


def compiled(spec: Path) -> HPN:
    comp = compile_file(spec)
    assert comp.hpn is not None, spec
    return comp.hpn


@pytest.fixture(scope="module")
def lwr4() -> HPN:
    return compiled(EXAMPLES / "lwr4_circle.rssm")


def assert_index_is_a_scan(hpn: HPN) -> None:
    ix = hpn.index()
    pages = list(hpn.pages.values())
    for pg in pages:
        net = ix.net(pg.id)
        assert list(net.places) == [p for p in hpn.places.values() if p.page == pg.id]
        assert list(net.transitions) == [t for t in hpn.transitions.values() if t.page == pg.id]
        assert list(net.children) == [c for c in pages if c.parent == pg.id]
        assert list(net.arcs) == [a for a in hpn.arcs if a.page == pg.id]
        assert hpn.contents(pg.id) == (list(net.places), list(net.transitions),
                                       list(net.children), list(net.arcs))
    assert list(ix.roots) == [pg for pg in pages if pg.parent is None]
    for node in (*hpn.pages, *hpn.places, *hpn.transitions):
        assert list(ix.into(node)) == [a for a in hpn.arcs if a.target == node]
        assert list(ix.out_of(node)) == [a for a in hpn.arcs if a.source == node]
    for table in (hpn.pages, hpn.places, hpn.transitions, hpn.fusions):
        for eid, element in table.items():
            assert ix.element(eid) is element
    assert ix.element("no such id") is None
    assert ix.net("no such page").places == ()


def assert_flat_lookups_are_a_scan(net: FlatNet) -> None:
    for p in net.places:
        assert net.place(p.name) is p
        rule = net.rule
        assert rule.consumers[p.index] == tuple(t.index for t in net.transitions if p.index in t.pre)
        assert rule.producers[p.index] == tuple(t.index for t in net.transitions
                                                if p.index in t.post and p.index not in t.pre)
    for t in net.transitions:
        assert net.transition(t.name) is t
    with pytest.raises(KeyError):
        net.place("no such place")


@pytest.mark.parametrize("spec", example_specs(), ids=lambda p: p.stem)
def test_indexes_agree_with_a_scan_of_the_tables(spec: Path) -> None:
    hpn = compiled(spec)
    assert_index_is_a_scan(hpn)
    assert_flat_lookups_are_a_scan(flatten(hpn))
    assert hpn.index() is hpn.index()            # built once, then kept


@pytest.mark.parametrize("spec", example_specs(), ids=lambda p: p.stem)
def test_every_element_has_a_key_that_prints_as_its_id(spec: Path) -> None:
    hpn = compiled(spec)
    assert violations(hpn) == []
    for table in (hpn.pages, hpn.places, hpn.transitions, hpn.fusions):
        for eid, element in table.items():
            assert element.key is not None and str(element.key) == element.key.text == eid
    nodes: list[Place | Transition] = [*hpn.places.values(), *hpn.transitions.values()]
    for node in nodes:
        assert node.key is not None
        page_key = hpn.pages[node.page].key
        assert page_key is not None and node.key.scope == page_key.scope


def test_names_hold_the_paper_indices(lwr4: HPN) -> None:
    key = lwr4.places["p[1,lwr,move,rcv,2,in]"].key
    assert key == Name.of("p", "", ("1", "lwr", "move", "rcv", 2, "in"),
                          Scope("1", "lwr", "move", "rcv", 2))
    assert (key.scope.j, key.scope.v, key.scope.omega, key.scope.verb, key.scope.k,
            key.local) == ("1", "lwr", "move", "rcv", 2, ("in",))
    t4 = lwr4.transitions["t[1,c,cw,4]"].key
    assert t4 is not None and t4.scope == Scope("1", "c", "cw") and t4.local == (4,)
    partial = lwr4.pages["P^f[1,c,cw,2]"].key
    assert partial is not None and partial.scope.psi == 2 and partial.scope.verb is None
    assert partial.sup == "^f" and partial.local == ()
    function = lwr4.places["p[1,c,cw,f,in]"].key
    assert function is not None and function.scope == Scope("1", "c", "cw")
    assert function.local == ("f", "in")
    device = lwr4.pages["P^E[1,lwr]"].key
    assert device is not None and device.sup == "^E" and device.scope == Scope("1", "lwr")
    root = lwr4.pages["H"].key
    assert root is not None and root.text == "H" and root.scope == SYSTEM_SCOPE
    assert lwr4.places["p[in]"].key == Name.of("p", "", ("in",))


def test_fusion_names_say_which_place_of_the_channel(lwr4: HPN) -> None:
    assert lwr4.fusions
    for fs in lwr4.fusions.values():
        assert fs.key is not None
        assert fs.key.full == (fs.key.which == FusionName.FULL) == fs.label.endswith(": full")
        assert fs.initial == (not fs.key.full)          # a channel starts empty
    channels = {fs.channel for fs in lwr4.fusions.values()}
    for full in (True, False):                          # each channel has one of each
        ends = [(k.agents, k.subsystems, k.indices) for fs in lwr4.fusions.values()
                if (k := fs.key) is not None and k.full == full]
        assert len(set(ends)) == len(ends) == len(channels)


def test_flat_pages_know_their_agent(lwr4: HPN) -> None:
    pages = {pg.id: pg for pg in flatten(lwr4).pages}
    assert pages["H"].agent is None
    assert pages["P[1]"].agent == pages["P[1,c]"].agent == "a1"
    assert pages["P^E[1,lwr]"].agent == "a1"            # a device net: its device's agent


def test_a_name_outside_its_scope_is_refused() -> None:
    with pytest.raises(ValueError):
        Name.of("p", "", ("2", "c", "in"), Scope("1", "c"))
    with pytest.raises(ValueError):
        Name.of("p", "", ("1", "c", "in")).within(Scope("2"))
    with pytest.raises(ValueError):
        Scope("1").below(PageKind.BEHAVIOUR, (3,))


def test_wellformedness_checks_the_keys(lwr4: HPN) -> None:
    hpn = copy.deepcopy(lwr4)
    place = hpn.places["p[1,c,cw,2]"]
    hpn.places[place.id] = replace(place, key=Name.of("p", "", ("1", "c", "cw", 3),
                                                       Scope("1", "c", "cw")))
    assert any("its key prints as p[1,c,cw,3]" in v for v in violations(hpn))
    hpn.places[place.id] = replace(place, key=Name.of("p", "", ("1", "c", "cw", 2),
                                                       Scope("1", "c")))
    assert any("does not lie in the scope of page" in v for v in violations(hpn))
    page = hpn.pages["P^B[1,c,cw]"]
    hpn.pages[page.id] = replace(page, key=Name.of("P", "^B", ("1", "c", "cw"),
                                                    Scope("1", "c", action="cw")))
    assert any("not its parent's extended by its kind" in v for v in violations(hpn))


# --- the cache follows every change to the tables -------------------------------------------

def small_hpn() -> HPN:
    h = HPN("s", root="H")
    h.pages["H"] = Page("H", PageKind.SYSTEM, None, "i", "o", SPAN, "s", "s")
    h.pages["C"] = Page("C", PageKind.AGENT, "H", "ci", "co", SPAN, "c", "s")
    for pid, page in (("i", "H"), ("o", "H"), ("ci", "C"), ("co", "C")):
        h.places[pid] = Place(pid, page, SPAN, pid)
    return h


def test_the_index_follows_changes_to_the_tables() -> None:
    h = small_hpn()
    assert [p.id for p in h.index().net("H").places] == ["i", "o"]
    h.places["x"] = Place("x", "H", SPAN, "x")
    assert [p.id for p in h.index().net("H").places] == ["i", "o", "x"]
    h.places["x"] = Place("x", "C", SPAN, "x")                     # moved to another page
    assert [p.id for p in h.index().net("C").places] == ["ci", "co", "x"]
    del h.places["x"]
    assert "x" not in {p.id for p in h.index().net("C").places}
    h.arcs.append(Arc("H", "i", "C"))
    assert h.index().into("C") == (Arc("H", "i", "C"),)
    h.arcs += [Arc("H", "C", "o")]
    assert h.index().out_of("C") == (Arc("H", "C", "o"),)
    h.arcs[0] = Arc("H", "o", "C")
    assert h.index().into("C") == (Arc("H", "o", "C"),)
    h.arcs = [Arc("H", "i", "C")]                                  # a whole new list
    assert h.index().out_of("C") == () and h.index().into("C") == (Arc("H", "i", "C"),)
    h.arcs.append(Arc("H", "C", "o"))                              # ... that is tracked too
    assert h.index().out_of("C") == (Arc("H", "C", "o"),)
    h.pages.update({"D": Page("D", PageKind.AGENT, "H", "di", "do", SPAN, "d", "s")})
    assert [c.id for c in h.index().children("H")] == ["C", "D"]
    h.pages.pop("D")
    assert [c.id for c in h.index().children("H")] == ["C"]
    assert_index_is_a_scan(h)


def test_an_hpn_made_from_plain_tables_copies_and_pickles(lwr4: HPN) -> None:
    h = HPN("s", "H", pages={}, places={}, arcs=[])
    h.pages["H"] = Page("H", PageKind.SYSTEM, None, "i", "o", SPAN, "s", "s")
    assert [pg.id for pg in h.index().roots] == ["H"]
    for clone in (copy.deepcopy(lwr4), pickle.loads(pickle.dumps(lwr4))):
        assert clone == lwr4
        assert_index_is_a_scan(clone)
        clone.places.pop("p[in]")
        assert clone.index().element("p[in]") is None and lwr4.index().element("p[in]")
