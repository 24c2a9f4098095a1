"""The tree of components: the HPN's pages, each holding the places drawn on it.

The system page holds the start and end of the whole system, an agent page those of the
agent (and the agent's device nets hang under it), a subsystem page its switching layer,
and so on down to the pages of single partial functions and buffers. A channel's fusion
places form a component of their own under the lowest page holding both its ends (the
agent for a channel inside an agent, the system for one between agents), so that neither
end carries the channel's state alone.
Composing a page's own places with its children (``check``) rebuilds the net from the
inside out, and every transition that stays inside a page's subtree can be hidden as soon
as that subtree is composed: a partial function is reduced before its behaviour sees it, a
subsystem before its agent, an agent before the system.

A flat net without page information (hand-built test nets) gets a two-level tree: one
piece per subsystem and one per channel under a root holding the rest.
"""

from __future__ import annotations

from dataclasses import field

from rssm_core.records import dataclass
from rssm_dsl.hpn.flat import FlatNet
from rssm_dsl.verify.compose.components import Component
from rssm_dsl.verify.netbits import NetBits, bits

SUBSYSTEM_KINDS = ("subsystem", "device")


@dataclass
class Node:
    name: str                            # page id (or subsystem name in the fallback tree)
    kind: str
    owner: str                           # the subsystem or device for subsystem/device pages
    own: Component | None                # the places on this page, if any
    parent: int | None
    children: list[int] = field(default_factory=list)
    first: int = 0                       # pre-order interval of the subtree: [first, last)
    last: int = 0


_Info = list[tuple[str, str, str, int | None]]     # per node: (name, kind, owner, parent)


def page_tree(net: FlatNet, nb: NetBits) -> list[Node]:
    """The nodes, root first, in pre-order; pages without places below them are left out."""
    info, masks, root = _pages(net, nb) if net.pages else _fallback(net)
    kids: list[list[int]] = [[] for _ in info]
    for k, (_, _, _, parent) in enumerate(info):
        if parent is not None:
            kids[parent].append(k)
    nodes: list[Node] = []

    def visit(k: int, parent: int | None) -> int | None:
        """Add page k's subtree in pre-order; the new index, or None if it has no place."""
        name, kind, owner, _ = info[k]
        own = Component.of(nb, name, masks[k]) if masks[k] else None
        me = len(nodes)
        nodes.append(Node(name, kind, owner, own, parent, first=me))
        for c in kids[k]:
            child = visit(c, me)
            if child is not None:
                nodes[me].children.append(child)
        if own is None and not nodes[me].children:
            nodes.pop()
            return None
        nodes[me].last = len(nodes)
        return me

    # pre-order by recursion over at most ten levels of pages
    visit(root, None)
    return nodes


def _pages(net: FlatNet, nb: NetBits) -> tuple[_Info, list[int], int]:
    """The HPN's pages and the channels' components (see the module docstring), the places
    of each, and the root."""
    ids = {pg.id: k for k, pg in enumerate(net.pages)}
    root = next((k for k, pg in enumerate(net.pages) if pg.kind == "system"), 0)
    agents = {pg.owner: k for k, pg in enumerate(net.pages) if pg.kind == "agent"}

    def parent_of(k: int) -> int | None:
        """The page's parent; a device net (a root of its own) hangs under its agent."""
        pg = net.pages[k]
        if pg.parent is not None:
            return ids[pg.parent]
        return None if k == root else agents.get(pg.agent or "", root)

    info: _Info = [(pg.id, pg.kind, pg.owner, parent_of(k)) for k, pg in enumerate(net.pages)]
    masks = [0] * len(info)
    fusion = []
    for p in net.places:
        if is_fusion(net, p.index):
            fusion.append(p.index)
        else:
            masks[ids.get(p.page or "", root)] |= 1 << p.index
    # a channel's fusion places: one component of their own under the lowest page
    # holding both ends (together, so that the channel's places constrain each other)
    channels: dict[str, list[int]] = {}
    for q in fusion:
        channels.setdefault(net.places[q].channel or "", []).append(q)
    for channel, places in channels.items():
        ends = {page for q in places for t in bits(nb.consumers[q] | nb.producers[q])
                for page in _pages_of(net, nb, t, ids, root)}
        info.append((channel, "channel", channel, _lowest_common(info, ends, root)))
        masks.append(sum(1 << q for q in places))
    return info, masks, root


def _fallback(net: FlatNet) -> tuple[_Info, list[int], int]:
    """Without page information: one node per subsystem and one per channel under a root
    holding the rest."""
    subs = sorted({p.subsystem for p in net.places if p.subsystem is not None})
    chans = sorted({p.channel or "" for p in net.places if is_fusion(net, p.index)})
    info: _Info = [("net", "system", net.system, None)]
    info += [(s, "subsystem", s, 0) for s in subs]
    info += [(c, "channel", c, 0) for c in chans]
    masks = [0] * len(info)
    for p in net.places:
        if p.subsystem is not None:
            masks[subs.index(p.subsystem) + 1] |= 1 << p.index
        elif p.channel is not None:
            masks[chans.index(p.channel) + 1 + len(subs)] |= 1 << p.index
        else:
            masks[0] |= 1 << p.index
    return info, masks, 0


def is_fusion(net: FlatNet, p: int) -> bool:
    """A channel's fusion place (shared by two subsystems), not a place of one page."""
    place = net.places[p]
    return place.subsystem is None and place.channel is not None


def _pages_of(net: FlatNet, nb: NetBits, t: int, ids: dict[str, int], root: int) -> set[int]:
    return {ids.get(net.places[p].page or "", root) for p in bits(nb.pre[t] | nb.post[t])
            if not is_fusion(net, p)}


def _lowest_common(info: _Info, pages: set[int], root: int) -> int:
    """The lowest page that has all of ``pages`` in its subtree."""
    common: list[int] | None = None
    for pg in pages:
        path = []
        node: int | None = pg
        while node is not None:
            path.append(node)
            node = info[node][3]
        path.reverse()                      # root first
        if common is None:
            common = path
        else:
            n = 0
            while n < min(len(common), len(path)) and common[n] == path[n]:
                n += 1
            common = common[:n]
    return common[-1] if common else root
