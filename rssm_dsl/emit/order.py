"""A deterministic walk of the page hierarchy: depth first from H, then the device nets."""

from __future__ import annotations

from collections.abc import Iterator

from rssm_dsl.hpn.ir import HPN, Page

_LINES = 8192   # lines joined into one piece of a streamed text


def pages_in_order(hpn: HPN) -> list[Page]:
    ix = hpn.index()
    out: list[Page] = []
    stack = [hpn.pages[hpn.root], *(hpn.pages[d] for d in hpn.devices)]
    stack.reverse()
    while stack:
        page = stack.pop()
        out.append(page)
        stack.extend(reversed(ix.children(page.id)))
    return out


def line_pieces(lines: list[str]) -> Iterator[str]:
    """``"\\n".join(lines) + "\\n"`` in pieces of a few thousand lines (an output written
    as it is joined, never held whole)."""
    for k in range(0, len(lines), _LINES):
        yield "\n".join(lines[k:k + _LINES]) + "\n"
