"""Subtrees that are the same net up to renaming are composed once.

Systems repeat themselves: every agent of a ring is built from the same text, and so are the
left and right effector of an agent. The reduced LTS of a subtree depends only on the places
of its pages, the transitions touching them (their arcs on those places, whether they leave
the subtree or are shared between its pages, which pages they enter), the initial and final
marking on those places and the shape of the subtree. ``subtree_key`` writes all of this
with places numbered locally in the order of their indices in the flat net (the order
flattening emits a page's places in) and transitions in the order of their local arcs.
Two subtrees with equal keys have LTSs equal up to the renaming of local transition i of
one into local transition i of the other, which ``rename`` applies: the key is everything the composition
reads, so equal keys cannot be wrong; a copy numbered differently only misses the cache.
"""

from __future__ import annotations

from collections.abc import Hashable, Sequence

from rssm_dsl.verify.compose.lts import TAU, Lts
from rssm_dsl.verify.compose.tree import Node
from rssm_dsl.verify.netbits import NetBits, bits


def subtree_key(nodes: Sequence[Node], k: int, nb: NetBits, users: dict[int, list[int]],
                own_control: Sequence[int],
                entries: Sequence[frozenset[int]]) -> tuple[Hashable, tuple[int, ...]]:
    """The key of node k's subtree and its transitions in local order."""
    node = nodes[k]
    span = range(node.first, node.last)
    local: dict[int, int] = {}
    shape = []
    for j in span:
        n = nodes[j]
        own = bits(n.own.places) if n.own is not None else []
        for p in own:
            local[p] = len(local)
        parent = n.parent - node.first if j != k and n.parent is not None else -1
        shape.append((n.kind, parent, tuple(local[p] for p in own),
                       tuple(local[p] for p in bits(own_control[j]))))
    mask = 0
    for p in local:
        mask |= 1 << p
    ts = 0
    for p in local:
        ts |= nb.consumers[p] | nb.producers[p]

    def places(m: int) -> tuple[int, ...]:
        return tuple(sorted(local[p] for p in bits(m & mask)))

    def arcs_of(t: int) -> tuple[tuple[int, ...], tuple[int, ...], tuple[int, ...], bool]:
        return (places(nb.pre[t]), places(nb.post[t]),
                tuple(u - node.first for u in users[t] if u in span),
                any(u not in span for u in users[t]))

    # transitions in the order of their arcs (copies of a page are not always flattened
    # in the same interleaving); two with the same arcs are interchangeable inside
    order = sorted((arcs_of(t), t) for t in bits(ts))
    transitions = tuple(t for _, t in order)
    arcs = tuple(a for a, _ in order)
    index = {t: i for i, t in enumerate(transitions)}
    entered = tuple(tuple(sorted(index[t] for t in entries[j] if t in index)) for j in span)
    key = (tuple(shape), arcs, entered, places(nb.initial), places(nb.final), nb.final != 0)
    return key, transitions


def rename(lts: Lts, source: tuple[int, ...], target: tuple[int, ...]) -> Lts:
    """``lts`` with transition ``source[i]`` renamed ``target[i]``."""
    to = dict(zip(source, target, strict=True))
    out = [[(a if a == TAU else to[a], d) for a, d in edges] for edges in lts.out]
    return Lts(lts.init, lts.flags, out, frozenset(to[a] for a in lts.alphabet))
