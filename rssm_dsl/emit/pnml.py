"""PNML (ISO/IEC 15909-2) for general Petri-net tools, with the paper's names as
place/transition names and the user's words in `toolspecific` (tool "rssmc").

Two forms: the flattened net on one page (`flat_pnml`), and the paged form (`paged_pnml`),
one `<page>` per HPN page nested as the hierarchy is. Some readers silently ignore nested
pages; the flat form is for them. In the paged form:

- a sub-page C is a nested `<page>` of its parent's page; an arc of the parent into C goes to
  a `referencePlace` on the parent page referring to C's input place, an arc out of C leaves
  from a `referencePlace` referring to C's output place (PNML arcs join nodes of one page);
- a fusion set is one place: its first member (in page order) is a `place`, every other
  member a `referencePlace` referring to it; each member's `toolspecific` names the set;
- a transition whose condition is constant false is left out, as in the flattened net
  (a P/T net has no guards); other conditions are free choices.

Reading the reference nodes as the nodes they refer to gives the flattened net back.
XML ids are generated (`p1`, `t1`, `r1`, `a1`, `pg1`); names go through ElementTree.
"""

from __future__ import annotations

import xml.etree.ElementTree as ET

from rssm_dsl.hpn.flat import FlatNet
from rssm_dsl.hpn.flatten import flatten
from rssm_dsl.hpn.ir import HPN

PTNET = "http://www.pnml.org/version-2009/grammar/ptnet"
NS = "http://www.pnml.org/version-2009/grammar/pnml"


def _text(parent: ET.Element, tag: str, value: str) -> None:
    ET.SubElement(ET.SubElement(parent, tag), "text").text = value


def flat_pnml(net: FlatNet) -> str:
    root = ET.Element("pnml", xmlns=NS)
    xnet = ET.SubElement(root, "net", id=f"net-{net.system}", type=PTNET)
    _text(xnet, "name", f"{net.system} (flattened HPN)")
    page = ET.SubElement(xnet, "page", id="flat")
    for p in net.places:
        xp = ET.SubElement(page, "place", id=f"p{p.index}")
        _text(xp, "name", p.name)
        if p.index in net.initial:
            _text(xp, "initialMarking", "1")
        ET.SubElement(xp, "toolspecific", tool="rssmc", version="1").text = p.label
    for t in net.transitions:
        xt = ET.SubElement(page, "transition", id=f"t{t.index}")
        _text(xt, "name", t.name)
        ET.SubElement(xt, "toolspecific", tool="rssmc", version="1").text = t.label
    n = 0
    for t in net.transitions:
        for src in t.pre:
            ET.SubElement(page, "arc", id=f"a{n}", source=f"p{src}", target=f"t{t.index}")
            n += 1
        for dst in t.post:
            ET.SubElement(page, "arc", id=f"a{n}", source=f"t{t.index}", target=f"p{dst}")
            n += 1
    ET.indent(root)
    return '<?xml version="1.0" encoding="UTF-8"?>\n' + ET.tostring(root, encoding="unicode") + "\n"


def _document(root: ET.Element) -> str:
    ET.indent(root)
    return '<?xml version="1.0" encoding="UTF-8"?>\n' + ET.tostring(root, encoding="unicode") + "\n"


def _tool(parent: ET.Element, **attrs: str) -> ET.Element:
    return ET.SubElement(parent, "toolspecific", {"tool": "rssmc", "version": "1", **attrs})


def _dropped(hpn: HPN, tid: str) -> bool:
    cond = hpn.transitions[tid].condition
    return cond is not None and cond.constant is False


def paged_pnml(hpn: HPN) -> str:
    """The HPN with its pages nested as in the hierarchy (see the module docstring)."""
    root = ET.Element("pnml", xmlns=NS)
    xnet = ET.SubElement(root, "net", id=f"net-{hpn.system}", type=PTNET)
    _text(xnet, "name", f"{hpn.system} (HPN, one page per net)")
    counts: dict[str, int] = {}

    def new_id(prefix: str) -> str:
        counts[prefix] = counts.get(prefix, 0) + 1
        return f"{prefix}{counts[prefix]}"

    marked = {pid: p.initial for pid, p in hpn.places.items()}
    for fs in hpn.fusions.values():
        on = any(hpn.places[m].initial for m in fs.places if m in hpn.places)
        marked.update(dict.fromkeys(fs.places, on))
    xml_of: dict[str, str] = {}                  # IR place -> its PNML place / reference id
    primary: dict[str, str] = {}                 # fusion set -> PNML id of its place
    pending: list[tuple[ET.Element, str]] = []   # (referencePlace, IR place it refers to)

    def page(parent: ET.Element, pid: str) -> None:
        pg = hpn.pages[pid]
        xpage = ET.SubElement(parent, "page", id=new_id("pg"))
        _text(xpage, "name", pid)
        _tool(xpage, kind=pg.kind.value).text = pg.label
        places, transitions, children, arcs = hpn.contents(pid)
        for pl in places:
            if pl.fusion is not None and pl.fusion in primary:
                xml_id = new_id("r")
                xp = ET.SubElement(xpage, "referencePlace", id=xml_id, ref=primary[pl.fusion])
                _text(xp, "name", pl.id)
            else:
                xml_id = new_id("p")
                xp = ET.SubElement(xpage, "place", id=xml_id)
                _text(xp, "name", pl.id)
                if marked[pl.id]:
                    _text(xp, "initialMarking", "1")
                if pl.fusion is not None:
                    primary[pl.fusion] = xml_id
            xml_of[pl.id] = xml_id
            tool = _tool(xp)
            tool.text = pl.label
            if pl.fusion is not None:
                tool.set("fusion", pl.fusion)
            if pl.id == pg.in_place:
                tool.set("port", "in")
            elif pl.id == pg.out_place:
                tool.set("port", "out")
        entry: dict[str, str] = {}
        leave: dict[str, str] = {}
        for child in children:
            for port, table in ((child.in_place, entry), (child.out_place, leave)):
                ref = ET.SubElement(xpage, "referencePlace", id=new_id("r"), ref="")
                _text(ref, "name", port)
                _tool(ref, page=child.id)
                pending.append((ref, port))
                table[child.id] = ref.get("id", "")
        trans: dict[str, str] = {}
        for tr in transitions:
            if _dropped(hpn, tr.id):
                continue
            xml_id = new_id("t")
            xt = ET.SubElement(xpage, "transition", id=xml_id)
            _text(xt, "name", tr.id)
            _tool(xt, role=tr.role.value).text = tr.label
            trans[tr.id] = xml_id
        seen: set[tuple[str, str]] = set()
        for a in arcs:
            if a.target in hpn.transitions:
                if a.target not in trans:
                    continue
                key = (xml_of.get(a.source) or leave[a.source], trans[a.target])
            else:
                if a.source not in trans:
                    continue
                key = (trans[a.source], xml_of.get(a.target) or entry[a.target])
            if key not in seen:
                seen.add(key)
                ET.SubElement(xpage, "arc", id=new_id("a"), source=key[0], target=key[1])
        for child in children:
            page(xpage, child.id)

    page(xnet, hpn.root)
    for pid, pg in hpn.pages.items():
        if pg.parent is None and pid != hpn.root:
            page(xnet, pid)
    for ref, port in pending:
        ref.set("ref", xml_of[port])
    return _document(root)


def emit_pnml(hpn: HPN) -> dict[str, str]:
    return {f"{hpn.system}.pnml": flat_pnml(flatten(hpn))}


def emit_paged_pnml(hpn: HPN) -> dict[str, str]:
    return {f"{hpn.system}.paged.pnml": paged_pnml(hpn)}
