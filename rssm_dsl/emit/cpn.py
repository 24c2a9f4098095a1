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
The document is written as text in one pass over the IR's index (linear in the size of the
net), byte for byte as ElementTree would write it indented, with its escaping
(:mod:`rssm_dsl.emit.xmltext`). The substitution transitions' `subst` elements name ids
given after every page is written; they are filled into slots kept for them.
"""

from __future__ import annotations

from dataclasses import field

from rssm_core.records import dataclass
from rssm_dsl.emit.xmltext import Indents, attr, leaf
from rssm_dsl.filenames import file_name
from rssm_dsl.hpn.ir import HPN, Arc, HpnIndex, Page, Transition

UNIT = "UNIT"
TOKEN = "()"
ONE = "1`()"
TOOL = {"tool": "CPN Tools", "version": "4.0.1"}
DOCTYPE = ('<!DOCTYPE workspaceElements PUBLIC "-//CPN//DTD CPNXML 1.0//EN" '
           '"http://cpntools.org/DTD/6/cpn.dtd">')

_TOOL = f' tool="{TOOL["tool"]}" version="{TOOL["version"]}"'
# every CPN page is a child of <cpnet>: its nodes are at depth 3, their parts at 4 and 5
_P2, _P3, _P4, _P5 = ("  " * d for d in (2, 3, 4, 5))
_ORIGIN = '<posattr x="0.0" y="0.0" />'
_TYPE = f"\n{_P5}{_ORIGIN}\n{_P5}<text{_TOOL}>{UNIT}</text>\n{_P4}</type>"
_MARKED = f"\n{_P5}{_ORIGIN}\n{_P5}<text{_TOOL}>{ONE}</text>\n{_P4}</initmark>"
_UNMARKED = f"\n{_P5}{_ORIGIN}\n{_P5}<text{_TOOL} />\n{_P4}</initmark>"
_ANNOT = f"\n{_P5}{_ORIGIN}\n{_P5}<text{_TOOL}>{TOKEN}</text>\n{_P4}</annot>\n{_P3}</arc>"
_FALSE = f"\n{_P5}{_ORIGIN}\n{_P5}<text{_TOOL}>[false]</text>\n{_P4}</cond>"


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
    place: dict[str, str] = field(default_factory=dict)       # IR place id -> CPN place id
    entry: dict[str, str] = field(default_factory=dict)       # child page -> input socket id
    exit: dict[str, str] = field(default_factory=dict)        # child page -> output socket id
    trans: dict[str, str] = field(default_factory=dict)       # IR transition id -> CPN id
    subst: dict[str, tuple[str, int]] = field(default_factory=dict)
    # child page -> (substitution transition id, slot of its `subst` element in the output)


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


class _CpnWriter:
    """The document's lines (an entry may hold several, joined by newlines), written in the
    order ElementTree would write the elements, with XML ids given in the order the elements
    are made (see :func:`hpn_cpn`)."""

    def __init__(self, hpn: HPN) -> None:
        self.hpn = hpn
        self.ix = hpn.index()
        self.out: list[str] = []
        self.ids = _Ids()
        self.marked = _marked(hpn)
        self.fusion_members: dict[str, list[str]] = {f: [] for f in hpn.fusions}
        self.order: list[str] = []
        self.outs: dict[str, _PageOut] = {}

    def document(self) -> str:
        ids, out = self.ids, self.out
        out += ['<?xml version="1.0" encoding="UTF-8"?>', DOCTYPE, "<workspaceElements>",
                f'  <generator{_TOOL} format="6" />', "  <cpnet>", "    <globbox>",
                f'      <block id="{ids()}">', "        <id>Standard declarations</id>",
                f'        <color id="{ids()}">', f"          <id>{UNIT}</id>",
                "          <unit />", "        </color>", "      </block>", "    </globbox>"]
        self.order = _page_order(self.hpn, self.ix)
        self.outs = {pid: _PageOut(ids()) for pid in self.order}
        for pid in self.order:
            self.page(pid)
        self.substitutions()
        self.fusions()
        self.instances()
        out += [f"{_P2}<options />", f"{_P2}<binders />",
                f'{_P2}<monitorblock name="Monitors" />', f'{_P2}<IndexNode expanded="true" />',
                "  </cpnet>", "</workspaceElements>", ""]
        return "\n".join(out)

    # ---------------------------------------------------------------- one page
    def page(self, pid: str) -> None:
        page = self.hpn.pages[pid]
        po = self.outs[pid]
        net = self.ix.net(pid)
        self.out.append(f'{_P2}<page id="{po.xml_id}">\n{_P3}<pageattr name="{attr(pid)}" />')
        x = 0.0
        for pl in net.places:
            port = None
            if page.parent is not None and pl.fusion is None:
                port = "In" if pl.id == page.in_place else "Out" if pl.id == page.out_place else None
            po.place[pl.id] = self.place(pl.id, x, 0.0, port, pl.fusion)
            x += 100.0
        x = 0.0
        for child in net.children:
            for table, port_place in ((po.entry, child.in_place), (po.exit, child.out_place)):
                table[child.id] = self.place(port_place, x, 200.0, None,
                                             self.hpn.places[port_place].fusion)
                x += 100.0
        self.transitions(po, net.transitions, net.children)
        self.arcs(po, net.arcs, net.children)
        self.out.append(f"{_P2}</page>")

    def place(self, name: str, x: float, y: float, port: str | None, fusion: str | None
              ) -> str:
        """A place named after an IR place (its marking is the IR place's); its XML id."""
        ids = self.ids
        xml_id = ids()
        mark = _MARKED if self.marked[name] else _UNMARKED
        text = (f'{_P3}<place id="{xml_id}">\n{_P4}<posattr x="{x:.1f}" y="{y:.1f}" />\n'
                f'{_P4}{leaf("text", "", name)}\n{_P4}<ellipse w="60.0" h="40.0" />\n'
                f'{_P4}<type id="{ids()}">{_TYPE}\n{_P4}<initmark id="{ids()}">{mark}')
        if port is not None:
            text += f'\n{_P4}<port id="{ids()}" type="{attr(port)}" />'
        if fusion is not None:
            text += f'\n{_P4}<fusioninfo id="{ids()}" name="{attr(fusion)}" />'
            self.fusion_members[fusion].append(xml_id)
        self.out.append(f"{text}\n{_P3}</place>")
        return xml_id

    def transitions(self, po: _PageOut, transitions: tuple[Transition, ...],
                    children: tuple[Page, ...]) -> None:
        """The page's transitions, then a substitution transition per sub-page (its `subst`
        element goes into a slot, filled once every page has its ids)."""
        ids, out = self.ids, self.out
        x = 0.0
        for tr in transitions:
            xml_id = ids()
            text = _trans_head(xml_id, tr.id, x, 100.0, "60.0")
            if tr.condition is not None and tr.condition.constant is False:
                text += f'\n{_P4}<cond id="{ids()}">{_FALSE}'
            out.append(f"{text}\n{_P3}</trans>")
            po.trans[tr.id] = xml_id
            x += 100.0
        for child in children:
            xml_id = ids()
            out.append(_trans_head(xml_id, child.id, x, 300.0, "80.0"))
            po.subst[child.id] = (xml_id, len(out))
            out += ["", f"{_P3}</trans>"]
            x += 100.0

    def arcs(self, po: _PageOut, arcs: tuple[Arc, ...], children: tuple[Page, ...]) -> None:
        """The arcs of the page's own net, each (orientation, transition, place) once (the
        flattened net's pre- and post-sets are sets), then those of the substitutions."""
        seen: set[tuple[str, str, str]] = set()
        for a in arcs:
            if a.target in po.trans:
                key = ("PtoT", po.trans[a.target], _place_end(po, a.source, entering=False))
            else:
                key = ("TtoP", po.trans[a.source], _place_end(po, a.target, entering=True))
            if key not in seen:
                seen.add(key)
                self.arc(*key)
        for child in children:
            st = po.subst[child.id][0]
            self.arc("PtoT", st, po.entry[child.id])
            self.arc("TtoP", st, po.exit[child.id])

    def arc(self, orientation: str, trans: str, place: str) -> None:
        ids = self.ids
        self.out.append(
            f'{_P3}<arc id="{ids()}" orientation="{orientation}" order="1">\n'
            f'{_P4}<transend idref="{trans}" />\n{_P4}<placeend idref="{place}" />\n'
            f'{_P4}<annot id="{ids()}">{_ANNOT}')

    # ---------------------------------------------------------------- after the pages
    def substitutions(self) -> None:
        """The `subst` elements, now that every page's port places have ids."""
        hpn = self.hpn
        for pid in self.order:
            po = self.outs[pid]
            for child in self.ix.children(pid):
                sub = self.outs[child.id]
                pairs = ((child.in_place, po.entry[child.id]),
                         (child.out_place, po.exit[child.id]))
                portsock = "".join(f"({sub.place[port]},{sock})" for port, sock in pairs
                                   if hpn.places[port].fusion is None)
                self.out[po.subst[child.id][1]] = (
                    f'{_P4}<subst subpage="{sub.xml_id}" portsock="{attr(portsock)}">\n'
                    f'{_P5}<subpageinfo id="{self.ids()}" name="{attr(child.id)}" />\n'
                    f"{_P4}</subst>")

    def fusions(self) -> None:
        out = self.out
        for fid, members in self.fusion_members.items():
            head = f'{_P2}<fusion id="{self.ids()}" name="{attr(fid)}"'
            if not members:
                out.append(head + " />")
                continue
            out.append(head + ">")
            out += [f'{_P3}<fusion_elm idref="{m}" />' for m in members]
            out.append(f"{_P2}</fusion>")

    def instances(self) -> None:
        """The prime pages (no parent), each with its substitution transitions' instances."""
        roots = [pid for pid in self.order if self.hpn.pages[pid].parent is None]
        if not roots:
            self.out.append(f"{_P2}<instances />")
            return
        self.out.append(f"{_P2}<instances>")
        pad = Indents()
        for pid in roots:
            self.instance(pad, 3, pid, f' page="{self.outs[pid].xml_id}"')
        self.out.append(f"{_P2}</instances>")

    def instance(self, pad: Indents, depth: int, pid: str, attrs: str) -> None:
        head = f'{pad[depth][1:]}<instance id="{self.ids()}"{attrs}'
        children = self.ix.children(pid)
        if not children:
            self.out.append(head + " />")
            return
        self.out.append(head + ">")
        for child in children:
            self.instance(pad, depth + 1, child.id,
                          f' trans="{self.outs[pid].subst[child.id][0]}"')
        self.out.append(f"{pad[depth][1:]}</instance>")


def _trans_head(xml_id: str, name: str, x: float, y: float, width: str) -> str:
    """The opening of a `trans` element and its fixed parts (the caller closes it)."""
    return (f'{_P3}<trans id="{xml_id}" explicit="false">\n'
            f'{_P4}<posattr x="{x:.1f}" y="{y:.1f}" />\n{_P4}{leaf("text", "", name)}\n'
            f'{_P4}<box w="{width}" h="40.0" />')


def hpn_cpn(hpn: HPN) -> str:
    """The `.cpn` text of the HPN (see the module docstring for the encoding)."""
    return _CpnWriter(hpn).document()


def _place_end(po: _PageOut, node: str, entering: bool) -> str:
    """The CPN place an arc of the page attaches to: the place itself, or the input
    (entering) / output socket of a sub-page node."""
    if node in po.place:
        return po.place[node]
    return po.entry[node] if entering else po.exit[node]


def _page_order(hpn: HPN, ix: HpnIndex) -> list[str]:
    """Pages depth first from the root H, then the device pages (each with its sub-pages)."""
    order: list[str] = []

    def visit(pid: str) -> None:
        order.append(pid)
        for child in ix.children(pid):
            visit(child.id)

    visit(hpn.root)
    for page in ix.roots:
        if page.id != hpn.root:
            visit(page.id)
    return order


def emit_cpn(hpn: HPN) -> dict[str, str]:
    return {file_name(hpn.system, ".cpn"): hpn_cpn(hpn)}
