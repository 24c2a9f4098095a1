"""IR well-formedness: the invariants every HPN the compiler builds must satisfy.

Returns a list of violations (empty when well-formed); the tests and the property tests
run it on every IR produced."""

from __future__ import annotations

from rssm_dsl.hpn.ir import HPN, SYSTEM_SCOPE, Element, Name, Page, Place, Transition


def violations(hpn: HPN) -> list[str]:
    out: list[str] = []
    if hpn.root not in hpn.pages:
        out.append(f"root page {hpn.root} missing")
    _pages(hpn, out)
    _places(hpn, out)
    _fusions(hpn, out)
    _arcs(hpn, out)
    _keys(hpn, out)
    return out


def _pages(hpn: HPN, out: list[str]) -> None:
    for page in hpn.pages.values():
        if page.parent is not None and page.parent not in hpn.pages:
            out.append(f"page {page.id}: parent {page.parent} missing")
        for which, pid in (("input", page.in_place), ("output", page.out_place)):
            place = hpn.places.get(pid)
            if place is None or place.page != page.id:
                out.append(f"page {page.id}: {which} place {pid} is not in its net")
        if page.in_place == page.out_place:
            out.append(f"page {page.id}: input and output place are the same")


def _places(hpn: HPN, out: list[str]) -> None:
    for place in hpn.places.values():
        if place.page not in hpn.pages:
            out.append(f"place {place.id}: page {place.page} missing")
        if place.fusion is not None:
            fs = hpn.fusions.get(place.fusion)
            if fs is None or place.id not in fs.places:
                out.append(f"place {place.id}: not a member of fusion set {place.fusion}")
            elif place.initial != fs.initial:
                out.append(f"place {place.id}: initial marking disagrees with {fs.id}")


def _fusions(hpn: HPN, out: list[str]) -> None:
    for fs in hpn.fusions.values():
        for m in fs.places:
            if m not in hpn.places or hpn.places[m].fusion != fs.id:
                out.append(f"fusion {fs.id}: member {m} does not point back")
        if not fs.places:
            out.append(f"fusion {fs.id}: empty")


def _arcs(hpn: HPN, out: list[str]) -> None:
    connected: dict[str, int] = dict.fromkeys(hpn.transitions, 0)
    for arc in hpn.arcs:
        kinds = []
        for node in (arc.source, arc.target):
            if node in hpn.transitions:
                kinds.append("t")
            elif node in hpn.places or node in hpn.pages:
                kinds.append("p")
            else:
                kinds.append("?")
                out.append(f"arc {arc.source} -> {arc.target}: unknown node {node}")
        if kinds in (["t", "t"], ["p", "p"]):
            out.append(f"arc {arc.source} -> {arc.target}: joins two nodes of one kind")
        for node in (arc.source, arc.target):
            if hpn.node_page(node) != arc.page:
                out.append(f"arc {arc.source} -> {arc.target}: {node} is not in page {arc.page}")
            if node in connected:
                connected[node] += 1
    for tid, n in connected.items():
        if n == 0:
            out.append(f"transition {tid}: no arcs")


def _keys(hpn: HPN, out: list[str]) -> None:
    """Structured names: each prints as its element's id, a page's scope extends its
    parent's by what its kind adds, and a place or transition lies in its page's scope."""
    elements: list[Element] = [*hpn.pages.values(), *hpn.places.values(),
                               *hpn.transitions.values(), *hpn.fusions.values()]
    for el in elements:
        key = el.key
        if key is not None and key.text != el.id:
            out.append(f"{el.id}: its key prints as {key.text}")
        if isinstance(key, Name) and Name.of(key.symbol, key.sup, key.parts).text != key.text:
            out.append(f"{el.id}: its key's text is not its parts printed")
    for page in hpn.pages.values():
        _page_scope(hpn, page, out)
    nodes: list[Place | Transition] = [*hpn.places.values(), *hpn.transitions.values()]
    for node in nodes:
        page_key = hpn.pages[node.page].key if node.page in hpn.pages else None
        if node.key is not None and page_key is not None and node.key.scope != page_key.scope:
            out.append(f"{node.id}: its key does not lie in the scope of page {node.page}")


def _page_scope(hpn: HPN, page: Page, out: list[str]) -> None:
    if page.key is None:
        return
    parent = hpn.pages.get(page.parent) if page.parent is not None else None
    if page.parent is not None and (parent is None or parent.key is None):
        return
    above = parent.key.scope if parent is not None and parent.key is not None else SYSTEM_SCOPE
    try:
        scope = above.below(page.kind, page.key.within(above).local)
    except ValueError as e:
        out.append(f"page {page.id}: {e}")
        return
    if scope != page.key.scope or page.key.local:
        out.append(f"page {page.id}: its key's scope is not its parent's extended by its kind")
