"""CPN Tools `.cpn` of the unflattened HPN: one CPN page per HPN page, for hierarchical tools.

The HPN's page hierarchy is place-bordered (a sub-page is a node of its parent's net that
transitions put tokens into, entering at its input place, and take tokens from, leaving at
its output place); CPN Tools' is transition-bordered. The encoding:

- a sub-page C of page P is a substitution transition named C on P, with two socket places
  on P (named after C's input and output places) assigned to C's input place (port type In)
  and output place (port type Out); an arc of P into the node C goes to the input socket,
  an arc out of C leaves from the output socket. The substitution transition takes from the
  input socket and gives to the output socket, as CPN Tools requires of sockets;
- a fusion set is a CPN Tools fusion group (`fusioninfo` on every member plus a `fusion`
  element): one place shared across pages. An input or output place that is also a fusion
  member (the builder makes none) is not a port: its socket joins the same fusion group;
- every place has colour set UNIT (a safe net's marking is which places hold a token), every
  arc carries `()`, the initial marking is `1`()`;
- a transition whose condition is constant false keeps its place in the net with the guard
  `[false]`, so it can never occur (the flattened net leaves it out); every other condition
  is a free choice, so other transitions have no guard;
- device pages (no parent) and the system page H are the prime pages (`<instances>`).

Names are the IR ids in the paper's notation; XML ids are generated (`ID1`, `ID2`, ...).
All text goes through ElementTree, which escapes it.
"""

from __future__ import annotations

import xml.etree.ElementTree as ET
from dataclasses import dataclass, field

from rssm_dsl.hpn.ir import HPN, Page

UNIT = "UNIT"
TOKEN = "()"
ONE = "1`()"
TOOL = {"tool": "CPN Tools", "version": "4.0.1"}
DOCTYPE = ('<!DOCTYPE workspaceElements PUBLIC "-//CPN//DTD CPNXML 1.0//EN" '
           '"http://cpntools.org/DTD/6/cpn.dtd">')


@dataclass
class _Ids:
    n: int = 0

    def __call__(self) -> str:
        self.n += 1
        return f"ID{self.n}"


@dataclass
class _PageOut:
    """The CPN elements of one HPN page, by the IR node they stand for."""

    xml_id: str
    element: ET.Element
    place: dict[str, str] = field(default_factory=dict)       # IR place id -> CPN place id
    entry: dict[str, str] = field(default_factory=dict)       # child page -> input socket id
    exit: dict[str, str] = field(default_factory=dict)        # child page -> output socket id
    trans: dict[str, str] = field(default_factory=dict)       # IR transition id -> CPN id
    subst: dict[str, ET.Element] = field(default_factory=dict)  # child page -> subst trans


def _text(parent: ET.Element, tag: str, value: str, ids: _Ids) -> ET.Element:
    el = ET.SubElement(parent, tag, id=ids())
    ET.SubElement(el, "posattr", x="0.0", y="0.0")
    ET.SubElement(el, "text", TOOL).text = value
    return el


def _node(parent: ET.Element, tag: str, xml_id: str, name: str, x: float, y: float
          ) -> ET.Element:
    el = ET.SubElement(parent, tag, id=xml_id)
    ET.SubElement(el, "posattr", x=f"{x:.1f}", y=f"{y:.1f}")
    ET.SubElement(el, "text").text = name
    return el


def _place(parent: ET.Element, xml_id: str, name: str, marked: bool, x: float, y: float,
           ids: _Ids, port: str | None = None, fusion: str | None = None) -> ET.Element:
    el = _node(parent, "place", xml_id, name, x, y)
    ET.SubElement(el, "ellipse", w="60.0", h="40.0")
    _text(el, "type", UNIT, ids)
    _text(el, "initmark", ONE if marked else "", ids)
    if port is not None:
        ET.SubElement(el, "port", id=ids(), type=port)
    if fusion is not None:
        ET.SubElement(el, "fusioninfo", id=ids(), name=fusion)
    return el


def _arc(page: ET.Element, ids: _Ids, orientation: str, trans: str, place: str) -> None:
    el = ET.SubElement(page, "arc", id=ids(), orientation=orientation, order="1")
    ET.SubElement(el, "transend", idref=trans)
    ET.SubElement(el, "placeend", idref=place)
    _text(el, "annot", TOKEN, ids)


def _marked(hpn: HPN) -> dict[str, bool]:
    """Whether each IR place starts marked, as flattening decides it: a fusion set is
    marked when any member is, and then every member carries the mark (CPN Tools requires
    the members of a fusion group to agree)."""
    marked = {pid: p.initial for pid, p in hpn.places.items()}
    for fs in hpn.fusions.values():
        on = any(hpn.places[m].initial for m in fs.places if m in hpn.places)
        for m in fs.places:
            marked[m] = on
    return marked


def hpn_cpn(hpn: HPN) -> str:
    """The `.cpn` text of the HPN (see the module docstring for the encoding)."""
    ids = _Ids()
    root = ET.Element("workspaceElements")
    ET.SubElement(root, "generator", TOOL, format="6")
    cpnet = ET.SubElement(root, "cpnet")
    globbox = ET.SubElement(cpnet, "globbox")
    block = ET.SubElement(globbox, "block", id=ids())
    ET.SubElement(block, "id").text = "Standard declarations"
    color = ET.SubElement(block, "color", id=ids())
    ET.SubElement(color, "id").text = UNIT
    ET.SubElement(color, "unit")

    marked = _marked(hpn)
    order = _page_order(hpn)
    outs: dict[str, _PageOut] = {}
    for pid in order:
        el = ET.SubElement(cpnet, "page", id=ids())
        ET.SubElement(el, "pageattr", name=pid)
        outs[pid] = _PageOut(el.get("id", ""), el)
    fusion_members: dict[str, list[str]] = {f: [] for f in hpn.fusions}

    for pid in order:
        page = hpn.pages[pid]
        out = outs[pid]
        places, transitions, children, arcs = hpn.contents(pid)
        x = 0.0
        for pl in places:
            port = None
            if page.parent is not None and pl.fusion is None:
                port = "In" if pl.id == page.in_place else "Out" if pl.id == page.out_place else None
            xml_id = ids()
            _place(out.element, xml_id, pl.id, marked[pl.id], x, 0.0, ids, port, pl.fusion)
            out.place[pl.id] = xml_id
            if pl.fusion is not None:
                fusion_members[pl.fusion].append(xml_id)
            x += 100.0
        x = 0.0
        for child in children:
            for which, port_place in (("in", child.in_place), ("out", child.out_place)):
                pp = hpn.places[port_place]
                xml_id = ids()
                _place(out.element, xml_id, port_place, marked[port_place], x, 200.0, ids,
                       fusion=pp.fusion)
                (out.entry if which == "in" else out.exit)[child.id] = xml_id
                if pp.fusion is not None:
                    fusion_members[pp.fusion].append(xml_id)
                x += 100.0
        x = 0.0
        for tr in transitions:
            xml_id = ids()
            el = _node(out.element, "trans", xml_id, tr.id, x, 100.0)
            el.set("explicit", "false")
            ET.SubElement(el, "box", w="60.0", h="40.0")
            if tr.condition is not None and tr.condition.constant is False:
                _text(el, "cond", "[false]", ids)
            out.trans[tr.id] = xml_id
            x += 100.0
        for child in children:
            xml_id = ids()
            el = _node(out.element, "trans", xml_id, child.id, x, 300.0)
            el.set("explicit", "false")
            ET.SubElement(el, "box", w="80.0", h="40.0")
            out.subst[child.id] = el
            x += 100.0
        # arcs of the page's own net, each (orientation, transition, place) once: the
        # flattened net's pre- and post-sets are sets
        seen: set[tuple[str, str, str]] = set()
        for a in arcs:
            if a.target in out.trans:
                key = ("PtoT", out.trans[a.target], _place_end(out, a.source, entering=False))
            else:
                key = ("TtoP", out.trans[a.source], _place_end(out, a.target, entering=True))
            if key not in seen:
                seen.add(key)
                _arc(out.element, ids, *key)
        for child in children:
            st = out.subst[child.id].get("id", "")
            _arc(out.element, ids, "PtoT", st, out.entry[child.id])
            _arc(out.element, ids, "TtoP", st, out.exit[child.id])

    # substitution transitions, now that every page's port places have ids
    for pid in order:
        out = outs[pid]
        for child in hpn.children(pid):
            sub = outs[child.id]
            pairs = [(child.in_place, out.entry[child.id]), (child.out_place, out.exit[child.id])]
            portsock = "".join(f"({sub.place[port]},{sock})" for port, sock in pairs
                               if hpn.places[port].fusion is None)
            subst = ET.SubElement(out.subst[child.id], "subst", subpage=sub.xml_id,
                                  portsock=portsock)
            ET.SubElement(subst, "subpageinfo", id=ids(), name=child.id)

    for fid, members in fusion_members.items():
        fel = ET.SubElement(cpnet, "fusion", id=ids(), name=fid)
        for m in members:
            ET.SubElement(fel, "fusion_elm", idref=m)

    instances = ET.SubElement(cpnet, "instances")

    def instance(parent: ET.Element, page: Page, attr: dict[str, str]) -> None:
        el = ET.SubElement(parent, "instance", {"id": ids(), **attr})
        for child in hpn.children(page.id):
            instance(el, child, {"trans": outs[page.id].subst[child.id].get("id", "")})

    for pid in order:
        if hpn.pages[pid].parent is None:
            instance(instances, hpn.pages[pid], {"page": outs[pid].xml_id})
    ET.SubElement(cpnet, "options")
    ET.SubElement(cpnet, "binders")
    ET.SubElement(cpnet, "monitorblock", name="Monitors")
    ET.SubElement(cpnet, "IndexNode", expanded="true")
    ET.indent(root)
    return ('<?xml version="1.0" encoding="UTF-8"?>\n' + DOCTYPE + "\n"
            + ET.tostring(root, encoding="unicode") + "\n")


def _place_end(out: _PageOut, node: str, entering: bool) -> str:
    """The CPN place an arc of the page attaches to: the place itself, or the input
    (entering) / output socket of a sub-page node."""
    if node in out.place:
        return out.place[node]
    return out.entry[node] if entering else out.exit[node]


def _page_order(hpn: HPN) -> list[str]:
    """Pages depth first from the root H, then the device pages (each with its sub-pages)."""
    order: list[str] = []

    def visit(pid: str) -> None:
        order.append(pid)
        for child in hpn.children(pid):
            visit(child.id)

    visit(hpn.root)
    for pid, page in hpn.pages.items():
        if page.parent is None and pid != hpn.root:
            visit(pid)
    return order


def emit_cpn(hpn: HPN) -> dict[str, str]:
    return {f"{hpn.system}.cpn": hpn_cpn(hpn)}
