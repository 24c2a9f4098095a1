"""Labelled transition systems and their reduction modulo divergence-preserving branching
bisimilarity.

An ``Lts`` has states ``0 .. n-1`` (``init`` the initial one), per-state flags (``FINAL``: the
state's part of the final marking is marked; ``UNSAFE``: a firing put a second token into a
place, the state is a sink) and edges labelled with an *action*: a flat transition index, or
``TAU`` (-1) for a hidden transition; ``VIOLATED`` and ``BUSY`` serve the structural assumption
of ``check``. A divergent state (one that can move silently forever)
carries a ``TAU`` self-loop, so a state with no edge at all is a real deadlock. Further flags
(``OBSERVED << i``) record observations of a component's local state, such as "some place
of this behaviour is marked".

``minimize`` returns the quotient modulo divergence-preserving branching bisimilarity that
respects the flags. That equivalence is a congruence for the parallel composition and hiding
used in ``product`` and preserves deadlocks, reachable flags, the visible actions that can
occur and the branching-time properties without next-step (CTL*-X), which is what the
compositional check relies on. The algorithm:

1. Collapse the strongly connected components of the silent steps between states with equal
   flags (iterative Tarjan); a non-trivial component, or a silent self-loop, is divergent.
   The result is free of silent cycles, and Tarjan numbers components successors-first.
2. Signature refinement (Blom and Orzan): the signature of a state is the set of
   ``(action, block)`` pairs it can reach after silent steps inside its own block, a silent
   step into its own block (inert) being no pair of its own. With components processed
   successors-first one sweep computes all signatures; the blocks are split by signature
   until nothing changes. The initial partition separates flags and divergence.
3. The quotient has one state per block, the non-inert edges, and a silent self-loop on
   divergent blocks.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence

from rssm_core.records import dataclass
from rssm_dsl.verify.budget import Budget
from rssm_dsl.verify.scc import components

Check = Callable[[], object]


def _no_check() -> None:
    return None


_EVERY = 0xFFFF         # the budget is checked every 65,536 states of a pass over the LTS

TAU = -1
FINAL = 1
UNSAFE = 2          # a firing put a second token into a place: a sink
VIOLATED = 4        # a page was entered while busy, against the structure assumed: a sink
BUSY = 8            # some control place of the (sub)tree is marked
OBSERVED = 16       # first of the observation flags: bit OBSERVED << i for observation i
SINK = UNSAFE | VIOLATED
Edges = list[tuple[int, int]]          # (action, target)


@dataclass(frozen=True, slots=True)
class Lts:
    init: int
    flags: list[int]
    out: list[Edges]
    alphabet: frozenset[int]           # actions still visible (may be a superset of those used)

    @property
    def size(self) -> int:
        return len(self.flags)

    @property
    def edge_count(self) -> int:
        return sum(len(e) for e in self.out)

    def hide(self, actions: frozenset[int] | set[int]) -> Lts:
        if not actions:
            return self
        out = [[(TAU if a in actions else a, d) for a, d in edges] for edges in self.out]
        return Lts(self.init, self.flags, out, self.alphabet - actions)


def _silent_components(lts: Lts, check: Check) -> tuple[list[int], int]:
    """The strongly connected components of the silent edges between states with equal
    flags, numbered so that every silent edge leaving a component goes to a lower number."""
    flags = lts.flags
    succ = []
    for v, edges in enumerate(lts.out):
        if v & _EVERY == 0:
            check()
        succ.append([w for a, w in edges if a == TAU and w != v and flags[w] == flags[v]])
    return components(succ, check)


UNBOUNDED = -1


def interface_counts(edges_of: list[Edges], group: frozenset[int],
                     check: Check = _no_check) -> list[int]:
    """Per state, the largest number of ``group`` actions on a path that uses only silent
    steps and ``group`` actions (``UNBOUNDED`` if such a path can repeat one forever).

    This is a property of the state's weak traces, so branching-bisimilar states share it:
    it may seed the partition. For a chain of agents, with ``group`` the actions towards the
    next agent, it is the number of messages the chain can still deliver without input, the
    counter that plain refinement would otherwise discover one round per value."""
    succ = [[d for a, d in edges if a == TAU or a in group] for edges in edges_of]
    comp, nc = components(succ, check)
    best = [0] * nc
    members: list[list[int]] = [[] for _ in range(nc)]
    for c, k in enumerate(comp):
        members[k].append(c)
    for k in range(nc):                 # successors first
        if k & _EVERY == 0:
            check()
        value = 0
        for c in members[k]:
            for a, d in edges_of[c]:
                if a != TAU and a not in group:
                    continue
                step = 0 if a == TAU else 1
                kd = comp[d]
                if kd == k:
                    if step:
                        value = UNBOUNDED
                        break
                    continue
                if best[kd] == UNBOUNDED:
                    value = UNBOUNDED
                    break
                value = max(value, best[kd] + step)
            if value == UNBOUNDED:
                break
        best[k] = value
    return [best[k] for k in comp]


def minimize(lts: Lts, groups: Sequence[frozenset[int]] = (),
             budget: Budget | None = None) -> Lts:
    """The quotient of ``lts`` (reachable part) modulo divergence-preserving branching
    bisimilarity, flags respected. ``groups`` (visible actions towards one neighbour each)
    only speed it up: their ``interface_counts`` seed the partition. The budget is checked
    every 65,536 states of every pass."""
    check: Check = budget.check if budget is not None else _no_check
    comp, nc = _silent_components(lts, check)
    # collapsed graph, components numbered successors-first (silent edges go to lower ids)
    cflags = [0] * nc
    div = [False] * nc
    size = [0] * nc
    cout: list[set[tuple[int, int]]] = [set() for _ in range(nc)]
    for s, edges in enumerate(lts.out):
        if s & _EVERY == 0:
            check()
        c = comp[s]
        cflags[c] = lts.flags[s]
        size[c] += 1
        targets = cout[c]
        for a, d in edges:
            cd = comp[d]
            if a == TAU and cd == c:
                div[c] = True          # a silent self-loop or a silent cycle inside c
            else:
                targets.add((a, cd))
    for c in range(nc):
        if size[c] > 1:
            div[c] = True
    edges_of = [list(t) for t in cout]
    seeds = cflags
    for group in groups:
        if group & lts.alphabet:
            counts = interface_counts(edges_of, group & lts.alphabet, check)
            keys: dict[tuple[int, int], int] = {}
            seeds = [keys.setdefault((f, v), len(keys)) for f, v in zip(seeds, counts, strict=True)]
    block = refine(seeds, div, edges_of, check)
    return _quotient(lts, comp, block, cflags, div, edges_of, check)


def refine(flags: list[int], div: list[bool], edges_of: list[Edges],
           check: Check = _no_check) -> list[int]:
    """The block of every state of a graph free of silent cycles whose silent edges go to
    lower-numbered states: the coarsest partition that separates flags (any int per state
    that bisimilar states share) and divergence and in which all states of a block have the
    same signature.

    Incremental signature refinement: a state's signature only changes when a state it
    reaches by an edge, or by silent steps inside its block, moves to another block. So each
    round recomputes the signatures of the states that moved and of their predecessors
    (closed backwards under inert silent steps) only, in increasing order so that inert
    successors come first. Within a block the states not recomputed all keep the signature
    the block had when it was last split (``common``); recomputed states that differ from it
    move to new blocks, one per signature. A block whose states were all recomputed keeps its
    largest group. Counting structures (a chain of agents with messages in flight) need as
    many rounds as they have states; each round costs only the region that changed."""
    n = len(flags)
    visible, silent, preds, silent_preds = _split_edges(edges_of, check)
    keys: dict[tuple[int, bool], int] = {}
    block = [keys.setdefault((flags[c], div[c]), len(keys)) for c in range(n)]
    count = [0] * len(keys)
    for b in block:
        count[b] += 1
    common: list[frozenset[int] | None] = [None] * len(keys)
    sigs: list[frozenset[int]] = [frozenset()] * n
    interned: dict[frozenset[int], frozenset[int]] = {}
    dirty: list[int] = list(range(n))
    while dirty:
        check()
        _signatures(dirty, block, visible, silent, sigs, interned, check)
        moved = _split(dirty, block, sigs, count, common)
        if not moved:
            break
        check()
        dirty = _affected(moved, block, preds, silent_preds)
    return block


def _split_edges(edges_of: list[Edges], check: Check = _no_check) -> tuple[list[list[tuple[int, int]]], list[list[int]],
                                                  list[list[int]], list[list[int]]]:
    """Per state: its visible edges (the action coded for ``refine``'s signatures as
    ``(action + 1) << 32``, and the target), its silent successors, its predecessors and
    its silent predecessors."""
    n = len(edges_of)
    # a pair (action, block) is coded as one int: (action + 1) << 32 | block
    visible: list[list[tuple[int, int]]] = [[] for _ in range(n)]
    silent: list[list[int]] = [[] for _ in range(n)]
    preds: list[list[int]] = [[] for _ in range(n)]
    silent_preds: list[list[int]] = [[] for _ in range(n)]
    for c in range(n):
        if c & _EVERY == 0:
            check()
        for a, d in edges_of[c]:
            preds[d].append(c)
            if a == TAU:
                silent[c].append(d)
                silent_preds[d].append(c)
            else:
                visible[c].append(((a + 1) << 32, d))
    return visible, silent, preds, silent_preds


def _signatures(dirty: list[int], block: list[int], visible: list[list[tuple[int, int]]],
                silent: list[list[int]], sigs: list[frozenset[int]],
                interned: dict[frozenset[int], frozenset[int]], check: Check) -> None:
    """Recompute the signatures of the ``dirty`` states (in increasing order, so that their
    inert silent successors come first)."""
    for k, c in enumerate(dirty):
        if k & _EVERY == 0:
            check()
        bc = block[c]
        sig = {code | block[d] for code, d in visible[c]}
        inherited: frozenset[int] | None = None
        several = False
        for d in silent[c]:
            bd = block[d]
            if bd != bc:
                sig.add(bd)            # (TAU + 1) << 32 is 0
            elif inherited is None:
                inherited = sigs[d]
            elif sigs[d] is not inherited:
                several = True
        if inherited is None:
            fs = frozenset(sig)
        elif not several and sig <= inherited:
            fs = inherited             # the common case inside a block: nothing new
        else:
            for d in silent[c]:
                if block[d] == bc:
                    sig |= sigs[d]
            fs = frozenset(sig)
        # equal signatures are one object, so that the test above is by identity
        sigs[c] = interned.setdefault(fs, fs)


def _split(dirty: list[int], block: list[int], sigs: list[frozenset[int]], count: list[int],
           common: list[frozenset[int] | None]) -> list[int]:
    """Move the recomputed states whose signature differs from their block's to new
    blocks, one per signature; the states that moved."""
    by_block: dict[int, list[int]] = {}
    for c in dirty:
        by_block.setdefault(block[c], []).append(c)
    moved: list[int] = []
    for b, states in by_block.items():
        groups: dict[frozenset[int], list[int]] = {}
        for c in states:
            groups.setdefault(sigs[c], []).append(c)
        keep = common[b]
        if len(states) == count[b] or keep is None:
            keep = max(groups, key=lambda g: len(groups[g]))
            common[b] = keep
        if len(groups) == 1 and keep in groups:
            continue
        for g, members in groups.items():
            if g == keep:
                continue
            nb = len(count)
            count.append(len(members))
            common.append(g)
            count[b] -= len(members)
            for c in members:
                block[c] = nb
            moved.extend(members)
    return moved


def _affected(moved: list[int], block: list[int], preds: list[list[int]],
              silent_preds: list[list[int]]) -> list[int]:
    """The states whose signature may have changed: those that moved and their
    predecessors, closed backwards under inert silent steps; in increasing order."""
    seen = set(moved)
    for c in moved:
        seen.update(preds[c])
    stack = list(seen)
    while stack:
        c = stack.pop()
        bc = block[c]
        for p in silent_preds[c]:
            if p not in seen and block[p] == bc:
                seen.add(p)
                stack.append(p)
    return sorted(seen)


def _quotient(lts: Lts, comp: list[int], block: list[int], cflags: list[int],
              div: list[bool], edges_of: list[Edges], check: Check = _no_check) -> Lts:
    """One state per block reachable from the initial one, renumbered breadth-first."""
    ids: dict[int, int] = {}
    for b in block:
        ids.setdefault(b, len(ids))
    nblocks = len(ids)
    block = [ids[b] for b in block]
    qout: list[set[tuple[int, int]]] = [set() for _ in range(nblocks)]
    qflags = [0] * nblocks
    qdiv = [False] * nblocks
    for c in range(len(block)):
        if c & _EVERY == 0:
            check()
        b = block[c]
        qflags[b] = cflags[c]
        qdiv[b] = div[c]
        for a, d in edges_of[c]:
            bd = block[d]
            if not (a == TAU and bd == b):
                qout[b].add((a, bd))
    start = block[comp[lts.init]]
    order = [start]
    number = {start: 0}
    i = 0
    while i < len(order):
        b = order[i]
        i += 1
        for _, d in sorted(qout[b]):
            if d not in number:
                number[d] = len(order)
                order.append(d)
    flags = [qflags[b] for b in order]
    out: list[Edges] = []
    for b in order:
        edges = sorted((a, number[d]) for a, d in qout[b])
        if qdiv[b]:
            edges.insert(0, (TAU, number[b]))
        out.append(edges)
    return Lts(0, flags, out, lts.alphabet)
