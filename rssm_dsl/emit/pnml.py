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
XML ids are generated (`p1`, `t1`, `r1`, `a1`, `pg1`). Both forms are written as text in one
pass over the net (the paged form over the IR's index: linear in the size of the net), byte
for byte as ElementTree would write them indented, with its escaping
(:mod:`rssm_dsl.emit.xmltext`); the references to a sub-page's ports name ids given when
the sub-page is written, and are filled into slots kept for them.
"""

from __future__ import annotations

from collections.abc import Iterable, Iterator, Sequence

from rssm_dsl.emit.xmltext import Indents, attr, leaf, text
from rssm_dsl.filenames import file_name
from rssm_dsl.hpn.flat import FlatNet
from rssm_dsl.hpn.flatten import flat_initial, flat_structure
from rssm_dsl.hpn.ir import HPN, Arc, Page, Place, Transition

PTNET = "http://www.pnml.org/version-2009/grammar/ptnet"
NS = "http://www.pnml.org/version-2009/grammar/pnml"
HEADER = '<?xml version="1.0" encoding="UTF-8"?>'
_TOOL = ' tool="rssmc" version="1"'


def _named(pad: Indents, depth: int, value: str) -> str:
    """`<name><text>value</text></name>` as a child at ``depth`` (no leading newline)."""
    return (f"{pad[depth][1:]}<name>{pad[depth + 1]}{leaf('text', '', value)}"
            f"{pad[depth]}</name>")


def _head(system: str, title: str) -> list[str]:
    pad = Indents()
    return [HEADER, f'<pnml xmlns="{attr(NS)}">',
            f'  <net id="{attr("net-" + system)}" type="{attr(PTNET)}">',
            _named(pad, 2, f"{system} ({title})")]


_TAIL = ["  </net>", "</pnml>", ""]


# a place of the flat PNML: (index, name, label); a transition: (index, name, label, the
# indices of its input places, of its output places)
_FlatPlace = tuple[int, str, str]
_FlatTransition = tuple[int, str, str, Sequence[int], Sequence[int]]


def flat_pnml(net: FlatNet) -> str:
    return "".join(_flat_pieces(net.system, [(p.index, p.name, p.label) for p in net.places],
                                net.initial, [(t.index, t.name, t.label, t.pre, t.post)
                                              for t in net.transitions]))


def flat_pnml_pieces(hpn: HPN) -> Iterator[str]:
    """``flat_pnml(flatten(hpn))`` in pieces, from the flat net's places and arcs alone
    (rssm_dsl.hpn.flatten.flat_structure): what the flat net binds to them (operations,
    conditions, owners, the sites of new(x)) is not shown, so not computed."""
    st = flat_structure(hpn)
    places, fusions, transitions = hpn.places, hpn.fusions, hpn.transitions
    flat_places = [(i, n, fusions[n].label if n in fusions else places[n].label)
                   for i, n in enumerate(st.names)]
    initial = flat_initial(hpn, st)
    pre, post = st.pre, st.post
    flat_transitions: list[_FlatTransition] = [
        (i, tid, transitions[tid].label, sorted(pre[tid]), sorted(post[tid]))
        for i, tid in enumerate(st.transitions)]
    del st, pre, post
    return _flat_pieces(hpn.system, flat_places, initial, flat_transitions)


def _leaves(tag: str, attrs: str, values: list[str]) -> list[str]:
    """``leaf(tag, attrs, v)`` of each value; when none is empty (nearly always), all
    escaped at once and written by one format."""
    sep = "\x00"                  # (not in XML text; if it is, value by value)
    joined = sep.join(values)
    if not all(values) or joined.count(sep) != len(values) - 1:
        return [leaf(tag, attrs, v) for v in values]
    return list(map(f"<{tag}{attrs}>%s</{tag}>".__mod__, text(joined).split(sep)))


_LINES = 8192   # lines joined into one piece of the streamed text


def _flat_pieces(system: str, places: list[_FlatPlace], initial: frozenset[int],
                 transitions: list[_FlatTransition]) -> Iterator[str]:
    """The flat PNML's text in pieces of a few thousand lines, each given as it is made."""
    pad = Indents()
    s3, s4, s5 = pad[3], pad[4], pad[5]
    out = _head(system, "flattened HPN")
    out.append('    <page id="flat">')
    sep = ""                               # before a piece: a line break, but at the start
    marking = f"{s4}<initialMarking>{s5}<text>1</text>{s4}</initialMarking>"
    place_names = _leaves("text", "", [p[1] for p in places])
    place_labels = _leaves("toolspecific", _TOOL, [p[2] for p in places])
    for (i, _, _), name, label in zip(places, place_names, place_labels, strict=True):
        out.append(f'{s3[1:]}<place id="p{i}">{s4}<name>{s5}{name}{s4}</name>'
                   f"{marking if i in initial else ''}{s4}{label}{s3}</place>")
        if len(out) >= _LINES:            # a piece is full: given, and a new one begun
            yield sep + "\n".join(out)
            out, sep = [], "\n"
    del place_names, place_labels
    names = _leaves("text", "", [t[1] for t in transitions])
    labels = _leaves("toolspecific", _TOOL, [t[2] for t in transitions])
    for (i, *_), name, label in zip(transitions, names, labels, strict=True):
        out.append(f'{s3[1:]}<transition id="t{i}">{s4}<name>{s5}{name}{s4}</name>'
                   f"{s4}{label}{s3}</transition>")
        if len(out) >= _LINES:            # a piece is full: given, and a new one begun
            yield sep + "\n".join(out)
            out, sep = [], "\n"
    del names, labels
    n = 0
    arc = s3[1:] + '<arc id="a'
    for i, _, _, ins, outs in transitions:
        for src in ins:
            out.append(f'{arc}{n}" source="p{src}" target="t{i}" />')
            n += 1
        for dst in outs:
            out.append(f'{arc}{n}" source="t{i}" target="p{dst}" />')
            n += 1
        if len(out) >= _LINES:            # a piece is full: given, and a new one begun
            yield sep + "\n".join(out)
            out, sep = [], "\n"
    out.append("    </page>")
    yield sep + "\n".join(out + _TAIL)


def _dropped(tr: Transition) -> bool:
    return tr.condition is not None and tr.condition.constant is False


class _PagedWriter:
    """The paged document's lines (an entry may hold several, joined by newlines), with XML
    ids given in the order the elements are written (see :func:`paged_pnml`)."""

    def __init__(self, hpn: HPN) -> None:
        self.hpn = hpn
        self.ix = hpn.index()
        self.pad = Indents()
        self.out = _head(hpn.system, "HPN, one page per net")
        self.counts = {"pg": 0, "p": 0, "r": 0, "t": 0, "a": 0}
        self.marked = {pid: p.initial for pid, p in hpn.places.items()}
        for fs in hpn.fusions.values():
            on = any(hpn.places[m].initial for m in fs.places if m in hpn.places)
            self.marked.update(dict.fromkeys(fs.places, on))
        self.xml_of: dict[str, str] = {}         # IR place -> its PNML place / reference id
        self.primary: dict[str, str] = {}        # fusion set -> PNML id of its place
        self.pending: list[tuple[int, str, str, int]] = []
        # (slot in the output, reference id, IR place it refers to, depth): the references
        # to a sub-page's ports, whose ids are given when the sub-page is written

    def new_id(self, prefix: str) -> str:
        self.counts[prefix] += 1
        return f"{prefix}{self.counts[prefix]}"

    def document(self) -> str:
        self.page(2, self.hpn.root)
        for pg in self.ix.roots:
            if pg.id != self.hpn.root:
                self.page(2, pg.id)
        pad, out = self.pad, self.out
        for slot, ref, port, depth in self.pending:
            out[slot] = f'{pad[depth][1:]}<referencePlace id="{ref}" ref="{self.xml_of[port]}">'
        return "\n".join(out + _TAIL)

    def page(self, depth: int, pid: str) -> None:
        pg = self.hpn.pages[pid]
        net = self.ix.net(pid)
        pad = self.pad
        tool = leaf("toolspecific", f"{_TOOL} kind={_q(pg.kind.value)}", pg.label)
        self.out.append(f'{pad[depth][1:]}<page id="{self.new_id("pg")}">\n'
                        f"{_named(pad, depth + 1, pid)}{pad[depth + 1]}{tool}")
        for pl in net.places:
            self.place(depth + 1, pl, pg)
        entry: dict[str, str] = {}
        leave: dict[str, str] = {}
        for child in net.children:
            entry[child.id] = self.port_reference(depth + 1, child.in_place, child.id)
            leave[child.id] = self.port_reference(depth + 1, child.out_place, child.id)
        trans = {tr.id: self.transition(depth + 1, tr) for tr in net.transitions
                 if not _dropped(tr)}
        self.arcs(depth + 1, net.arcs, trans, entry, leave)
        for child in net.children:
            self.page(depth + 1, child.id)
        self.out.append(f"{pad[depth][1:]}</page>")

    def place(self, depth: int, pl: Place, pg: Page) -> None:
        """An IR place: a `place`, or a reference to its fusion set's place."""
        s1, s2, s3 = self.pad[depth], self.pad[depth + 1], self.pad[depth + 2]
        tool = _TOOL
        if pl.fusion is not None:
            tool += f" fusion={_q(pl.fusion)}"
        if pl.id == pg.in_place:
            tool += ' port="in"'
        elif pl.id == pg.out_place:
            tool += ' port="out"'
        name = f"{s2}<name>{s3}{leaf('text', '', pl.id)}{s2}</name>"
        tail = f"{s2}{leaf('toolspecific', tool, pl.label)}"
        if pl.fusion is not None and pl.fusion in self.primary:
            xml_id = self.new_id("r")
            self.out.append(f'{s1[1:]}<referencePlace id="{xml_id}" '
                            f'ref="{self.primary[pl.fusion]}">{name}{tail}{s1}</referencePlace>')
        else:
            xml_id = self.new_id("p")
            mark = (f"{s2}<initialMarking>{s3}<text>1</text>{s2}</initialMarking>"
                    if self.marked[pl.id] else "")
            self.out.append(f'{s1[1:]}<place id="{xml_id}">{name}{mark}{tail}{s1}</place>')
            if pl.fusion is not None:
                self.primary[pl.fusion] = xml_id
        self.xml_of[pl.id] = xml_id

    def port_reference(self, depth: int, port: str, child: str) -> str:
        """A reference to a sub-page's input or output place; its id. The opening tag goes
        into a slot, filled at the end (the place has no id yet)."""
        s1, s2, s3 = self.pad[depth], self.pad[depth + 1], self.pad[depth + 2]
        ref = self.new_id("r")
        self.pending.append((len(self.out), ref, port, depth))
        self.out.append("")
        self.out.append(f"{s2[1:]}<name>{s3}{leaf('text', '', port)}{s2}</name>{s2}"
                        f"<toolspecific{_TOOL} page={_q(child)} />{s1}</referencePlace>")
        return ref

    def transition(self, depth: int, tr: Transition) -> str:
        s1, s2, s3 = self.pad[depth], self.pad[depth + 1], self.pad[depth + 2]
        xml_id = self.new_id("t")
        tool = leaf("toolspecific", f"{_TOOL} role={_q(tr.role.value)}", tr.label)
        self.out.append(f'{s1[1:]}<transition id="{xml_id}">{s2}<name>{s3}'
                        f"{leaf('text', '', tr.id)}{s2}</name>{s2}{tool}{s1}</transition>")
        return xml_id

    def arcs(self, depth: int, arcs: tuple[Arc, ...], trans: dict[str, str],
             entry: dict[str, str], leave: dict[str, str]) -> None:
        """The page's arcs between written nodes, each (source, target) once."""
        transitions, xml_of = self.hpn.transitions, self.xml_of
        indent = self.pad[depth][1:]
        seen: set[tuple[str, str]] = set()
        for a in arcs:
            if a.target in transitions:
                if a.target not in trans:
                    continue
                key = (xml_of.get(a.source) or leave[a.source], trans[a.target])
            else:
                if a.source not in trans:
                    continue
                key = (trans[a.source], xml_of.get(a.target) or entry[a.target])
            if key not in seen:
                seen.add(key)
                self.out.append(f'{indent}<arc id="{self.new_id("a")}" source="{key[0]}" '
                                f'target="{key[1]}" />')


def paged_pnml(hpn: HPN) -> str:
    """The HPN with its pages nested as in the hierarchy (see the module docstring)."""
    return _PagedWriter(hpn).document()


def _q(value: str) -> str:
    """An attribute value, escaped and quoted."""
    return f'"{attr(value)}"'


def emit_pnml(hpn: HPN) -> dict[str, str]:
    return {file_name(hpn.system, ".pnml"): "".join(flat_pnml_pieces(hpn))}


def stream_pnml(hpn: HPN) -> Iterator[tuple[str, Iterable[str]]]:
    """:func:`emit_pnml`'s file, its text in pieces."""
    yield file_name(hpn.system, ".pnml"), flat_pnml_pieces(hpn)


def emit_paged_pnml(hpn: HPN) -> dict[str, str]:
    return {file_name(hpn.system, ".paged.pnml"): paged_pnml(hpn)}
