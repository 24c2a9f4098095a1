"""The canonical text dump of the HPN IR: the golden format (stable, diffable)."""

from __future__ import annotations

from collections.abc import Iterable, Iterator

from rssm_dsl.emit.order import line_pieces, pages_in_order
from rssm_dsl.filenames import file_name
from rssm_dsl.hpn.ir import HPN
from rssm_dsl.source import Span


def _at(span: Span) -> str:
    return f"@{span.file}:{span.line}"


def dump_text(hpn: HPN) -> str:
    return "\n".join(_lines(hpn)) + "\n"


def _lines(hpn: HPN) -> list[str]:
    lines = [f"hpn {hpn.system}"]
    ix = hpn.index()
    for page in pages_in_order(hpn):
        net = ix.net(page.id)
        lines.append("")
        lines.append(
            f"page {page.id} {page.kind.value} layer={page.layer}.{page.sublayer} "
            f"parent={page.parent or '-'} in={page.in_place} out={page.out_place} "
            f"{_at(page.span)}"
        )
        for p in net.places:
            if not p.initial and not p.fusion and p.operation is None:   # most places
                s = p.span
                lines.append(f"  place {p.id}  @{s.file}:{s.line}".replace("  @", " @"))
                continue
            extra = []
            if p.initial:
                extra.append("initial")
            if p.fusion:
                extra.append(f"fused={p.fusion}")
            if p.operation is not None:
                op = p.operation
                void = " void" if op.void else ""
                extra.append(f"op={op.kind.value}{void} {{{op.text}}}")
            lines.append(f"  place {p.id} {' '.join(extra)} {_at(p.span)}".replace("  @", " @"))
        for t in net.transitions:
            cond = ""
            if t.condition is not None:
                c = t.condition
                const = "" if c.constant is None else f" const={str(c.constant).lower()}"
                cond = f" cond={c.kind.value}{const} [{c.text}]"
            s = t.span       # (_at written out, the role's value read without the property)
            lines.append(f"  transition {t.id} role={t.role._value_}{cond} @{s.file}:{s.line}")
        for arc in net.arcs:
            lines.append(f"  arc {arc.source} -> {arc.target}")
    lines.append("")
    for f in hpn.fusions.values():
        init = " initial" if f.initial else ""
        lines.append(f"fusion {f.id}{init} channel={f.channel} places={','.join(f.places)}")
    return lines


def emit_dump(hpn: HPN) -> dict[str, str]:
    return {file_name(hpn.system, ".hpn.txt"): dump_text(hpn)}


def stream_dump(hpn: HPN) -> Iterator[tuple[str, Iterable[str]]]:
    """:func:`emit_dump`'s file, its text in pieces."""
    yield file_name(hpn.system, ".hpn.txt"), line_pieces(_lines(hpn))
