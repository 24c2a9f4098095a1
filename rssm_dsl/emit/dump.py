"""The canonical text dump of the HPN IR: the golden format (stable, diffable)."""

from __future__ import annotations

from rssm_dsl.emit.order import pages_in_order
from rssm_dsl.hpn.ir import HPN
from rssm_dsl.source import Span


def _at(span: Span) -> str:
    return f"@{span.file}:{span.line}"


def dump_text(hpn: HPN) -> str:
    lines = [f"hpn {hpn.system}"]
    places_by_page: dict[str, list[str]] = {}
    for p in hpn.places.values():
        places_by_page.setdefault(p.page, []).append(p.id)
    trans_by_page: dict[str, list[str]] = {}
    for t in hpn.transitions.values():
        trans_by_page.setdefault(t.page, []).append(t.id)
    arcs_by_page: dict[str, list[str]] = {}
    for a in hpn.arcs:
        arcs_by_page.setdefault(a.page, []).append(f"{a.source} -> {a.target}")
    for page in pages_in_order(hpn):
        lines.append("")
        lines.append(
            f"page {page.id} {page.kind.value} layer={page.layer}.{page.sublayer} "
            f"parent={page.parent or '-'} in={page.in_place} out={page.out_place} "
            f"{_at(page.span)}"
        )
        for pid in places_by_page.get(page.id, []):
            p = hpn.places[pid]
            extra = []
            if p.initial:
                extra.append("initial")
            if p.fusion:
                extra.append(f"fused={p.fusion}")
            if p.operation is not None:
                op = p.operation
                void = " void" if op.void else ""
                extra.append(f"op={op.kind.value}{void} {{{op.text}}}")
            lines.append(f"  place {pid} {' '.join(extra)} {_at(p.span)}".replace("  @", " @"))
        for tid in trans_by_page.get(page.id, []):
            t = hpn.transitions[tid]
            cond = ""
            if t.condition is not None:
                c = t.condition
                const = "" if c.constant is None else f" const={str(c.constant).lower()}"
                cond = f" cond={c.kind.value}{const} [{c.text}]"
            lines.append(f"  transition {tid} role={t.role.value}{cond} {_at(t.span)}")
        for arc in arcs_by_page.get(page.id, []):
            lines.append(f"  arc {arc}")
    lines.append("")
    for f in hpn.fusions.values():
        init = " initial" if f.initial else ""
        lines.append(f"fusion {f.id}{init} channel={f.channel} places={','.join(f.places)}")
    return "\n".join(lines) + "\n"


def emit_dump(hpn: HPN) -> dict[str, str]:
    return {f"{hpn.system}.hpn.txt": dump_text(hpn)}
