"""A deterministic walk of the page hierarchy: depth first from H, then the device nets."""

from __future__ import annotations

from rssm_dsl.hpn.ir import HPN, Page


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
