"""IR well-formedness: the invariants every HPN the compiler builds must satisfy.

Returns a list of violations (empty when well-formed); the tests and the property tests
run it on every IR produced."""

from __future__ import annotations

from rssm_dsl.hpn.ir import HPN


def violations(hpn: HPN) -> list[str]:
    out: list[str] = []
    if hpn.root not in hpn.pages:
        out.append(f"root page {hpn.root} missing")
    for page in hpn.pages.values():
        if page.parent is not None and page.parent not in hpn.pages:
            out.append(f"page {page.id}: parent {page.parent} missing")
        for which, pid in (("input", page.in_place), ("output", page.out_place)):
            place = hpn.places.get(pid)
            if place is None or place.page != page.id:
                out.append(f"page {page.id}: {which} place {pid} is not in its net")
        if page.in_place == page.out_place:
            out.append(f"page {page.id}: input and output place are the same")
    for place in hpn.places.values():
        if place.page not in hpn.pages:
            out.append(f"place {place.id}: page {place.page} missing")
        if place.fusion is not None:
            fs = hpn.fusions.get(place.fusion)
            if fs is None or place.id not in fs.places:
                out.append(f"place {place.id}: not a member of fusion set {place.fusion}")
            elif place.initial != fs.initial:
                out.append(f"place {place.id}: initial marking disagrees with {fs.id}")
    for fs in hpn.fusions.values():
        for m in fs.places:
            if m not in hpn.places or hpn.places[m].fusion != fs.id:
                out.append(f"fusion {fs.id}: member {m} does not point back")
        if not fs.places:
            out.append(f"fusion {fs.id}: empty")
    connected: dict[str, int] = {t: 0 for t in hpn.transitions}
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
    return out
