"""Compositional verification: the verdicts of the full state space without building it.

RSSM agents and subsystems interact only through the places they share (channel fusion
places and the start and end of the hierarchy). ``tree.page_tree`` cuts the net there; each
component's LTS is reduced modulo divergence-preserving branching bisimilarity after hiding
what no other component sees, and components are composed one at a time in
``composition_order``, hiding each transition as soon as all components touching it are in,
and reducing again; subtrees equal up to renaming are composed once (``cache``). For a
ring of N agents the intermediate systems grow linearly with N (the messages a chain of
agents holds), not exponentially.

What is decided, exactly (the equivalence preserves it, see ``lts``):

- safeness: a firing that puts a second token into a place is a flagged sink state;
- deadlocks: a state of the final composition with no move that is neither final nor unsafe;
- with ``detail``: for each subsystem, the whole net composed again along the path from the
  subsystem's page to the root (every other subtree as built for the verdict, the system
  page resumed from the step before the subsystem's agent), with the subsystem's ITERATION
  transitions visible and two kinds of state flagged: "some place of behaviour b is marked"
  (which behaviours are reachable) and "the subsystem is not finished"
  (``progress.live_places``). On it the progress check of ``progress``: a reachable
  unfinished state from which neither an iteration nor a deadlock can be reached.

Dead transitions are not computed here (each would have to stay visible).

Counterexamples are not produced here: the caller looks for one with the explicit search
when a violation is found.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Hashable, Sequence
from dataclasses import dataclass, field

from rssm_dsl.hpn.flat import FlatNet, Role
from rssm_dsl.verify.compose.cache import rename, subtree_key
from rssm_dsl.verify.compose.components import local_lts
from rssm_dsl.verify.compose.lts import (
    BUSY,
    FINAL,
    OBSERVED,
    SINK,
    UNSAFE,
    VIOLATED,
    Lts,
    minimize,
)
from rssm_dsl.verify.compose.order import composition_order
from rssm_dsl.verify.compose.product import TooLarge, product
from rssm_dsl.verify.compose.tree import SUBSYSTEM_KINDS, is_fusion, page_tree
from rssm_dsl.verify.netbits import NetBits, bits
from rssm_dsl.verify.progress import live_places


class OutOfTime(Exception):
    """The time limit was reached."""


@dataclass
class ComposeResult:
    complete: bool = False
    stopped: str | None = None
    safe: bool | None = None
    deadlock_free: bool | None = None
    components: int = 0
    states: int = 0                    # states built over all compositions
    largest: int = 0                   # the largest composition before reduction
    detail_complete: bool = False
    reached: set[tuple[str, str]] = field(default_factory=set)   # (subsystem, behaviour)
    progress_checked: list[str] = field(default_factory=list)
    progress_lost: list[str] = field(default_factory=list)


StepCallback = Callable[[str, int, int], None]     # (phase, components done, of total)


def compose_check(net: FlatNet, nb: NetBits, max_states: int, deadline: float | None,
                  detail: bool = True, progress_subsystems: list[str] | None = None,
                  on_step: StepCallback | None = None, reuse: bool = True) -> ComposeResult:
    """``reuse``: rename the LTS of a subtree equal to one built before (``cache``)."""
    res = ComposeResult()
    try:
        _run(net, nb, max_states, deadline, detail, progress_subsystems, on_step, reuse, res)
    except TooLarge as e:
        res.stopped = str(e)
    except OutOfTime:
        res.stopped = "time limit reached"
    return res


def _run(net: FlatNet, nb: NetBits, max_states: int, deadline: float | None, detail: bool,
         progress_subsystems: list[str] | None, on_step: StepCallback | None, reuse: bool,
         res: ComposeResult) -> None:
    nodes = page_tree(net, nb)
    res.components = sum(1 for n in nodes if n.own is not None)
    # users[t]: pre-order numbers of the nodes whose own places t touches
    users: dict[int, list[int]] = {}
    for k, node in enumerate(nodes):
        if node.own is not None:
            for t in node.own.transitions:
                users.setdefault(t, []).append(k)
    shared = frozenset(t for t, us in users.items() if len(us) > 1)
    # the structural assumption: a page's subtree is entered only while none of its control
    # places (all but the channels' fusion places) is marked
    control = 0
    for p in net.places:
        if not is_fusion(net, p.index):
            control |= 1 << p.index
    own_control = [(n.own.places & control) if n.own is not None else 0 for n in nodes]
    tree_control = own_control[:]
    for k in range(len(nodes) - 1, 0, -1):
        parent = nodes[k].parent
        assert parent is not None
        if nodes[k].kind != "device":     # a device net runs from the start, on its own
            tree_control[parent] |= tree_control[k]
    entries = [frozenset() if k == 0 else _entries(nb, tree_control[k])
               for k in range(len(nodes))]
    done = 0

    def tick(phase: str) -> None:
        nonlocal done
        if deadline is not None and time.monotonic() > deadline:
            raise OutOfTime
        done += 1
        if on_step is not None:
            on_step(phase, done, len(nodes))

    def counted(lts: Lts) -> Lts:
        res.states += lts.size
        res.largest = max(res.largest, lts.size)
        return lts

    def minimized(lts: Lts, groups: Sequence[frozenset[int]] = ()) -> Lts:
        return minimize(counted(lts), groups)

    def compose(x: Lts, y: Lts, hidden: frozenset[int] | set[int],
                groups: Sequence[frozenset[int]] = ()) -> Lts:
        return minimized(product(x, y, frozenset(hidden), max_states), groups)

    def leaves_subtree(t: int, k: int) -> bool:
        node = nodes[k]
        return any(not node.first <= u < node.last for u in users[t])

    def own_lts(k: int, keep: frozenset[int] = frozenset(),
                observe: tuple[int, ...] = ()) -> Lts | None:
        own = nodes[k].own
        if own is None:
            return None
        tick("components")
        return minimized(local_lts(nb, own, shared | keep, max_states, observe,
                                   own_control[k], entries[k]))

    def build(k: int, keep: frozenset[int] = frozenset(), observe: tuple[int, ...] = (),
              child: tuple[int, Lts] | None = None) -> Lts:
        """Node k's subtree composed, only ``keep`` and the transitions leaving it visible;
        with ``observe``, rebuilt all the way down; with ``child``, that child's LTS given."""
        mine = own_lts(k, keep, observe)
        parts = ([mine] if mine is not None else []) + [
            child[1] if child is not None and c == child[0] else
            built[c] if not observe else build(c, keep, observe)
            for c in nodes[k].children]
        visible = frozenset(t for p in parts for t in p.alphabet
                            if t in keep or leaves_subtree(t, k))
        connectors = {i + (mine is not None) for i, c in enumerate(nodes[k].children)
                      if nodes[c].kind == "channel"}
        if k == 0 and child is not None and root_order:
            # only the child differs from step 1: resume the recorded composition
            whole = chain(parts, visible, connectors, True,
                          resume_at=nodes[k].children.index(child[0]) + (mine is not None))
        else:
            whole = chain(parts, visible, connectors, k == 0, record=k == 0 and not keep)
        result = guard(whole, entries[k])
        if nodes[k].kind == "device":     # its places are not its agent's control places
            result = minimized(Lts(result.init, [f & ~BUSY for f in result.flags], result.out,
                                   result.alphabet))
        return result

    def guard(lts: Lts, enter: frozenset[int]) -> Lts:
        """``lts`` with every firing of ``enter`` in a ``BUSY`` state sent to a
        ``VIOLATED`` sink."""
        if not enter or not any(lts.flags[s] & BUSY and any(a in enter for a, _ in edges)
                                for s, edges in enumerate(lts.out)):
            return lts
        sink = lts.size
        out = [[(a, sink if a in enter and lts.flags[s] & BUSY else d) for a, d in edges]
               for s, edges in enumerate(lts.out)]
        return minimized(Lts(lts.init, [*lts.flags, VIOLATED], [*out, []], lts.alphabet))

    # the system page's composition in step 1: its order, and what was composed before each
    # step, so that the progress check starts a subsystem's agent from there
    root_order: list[int] = []
    root_steps: list[tuple[int, Lts | None]] = []

    def chain(parts: list[Lts], visible: frozenset[int],
              connectors: frozenset[int] | set[int] = frozenset(),
              k_root: bool = False, record: bool = False,
              resume_at: int | None = None) -> Lts:
        """Compose ``parts`` one at a time (``composition_order``), hiding every action not
        in ``visible`` as soon as all parts using it are in. A connector (a channel) that
        links what is composed to the next part goes in together with that part.

        ``record``: keep the order and every step's start (the system page in step 1).
        ``resume_at``: the recorded composition with part ``resume_at`` replaced, which is
        the only one to differ: it starts from the last step recorded before that part."""
        q = 0
        cur: Lts | None = None
        if resume_at is None:
            order = composition_order([p.alphabet for p in parts])
        else:
            order = root_order
            where = order.index(resume_at)
            q, cur = max((step for step in root_steps if step[0] <= where),
                         key=lambda step: step[0])
        if record:
            root_order[:] = order
        left: dict[int, int] = {}
        for i in order[q:]:
            for t in parts[i].alphabet:
                left[t] = left.get(t, 0) + 1
        used_by: dict[int, set[int]] = {}
        for i, p in enumerate(parts):
            for t in p.alphabet:
                used_by.setdefault(t, set()).add(i)

        def interfaces(alphabet: frozenset[int]) -> list[frozenset[int]]:
            """The open actions grouped by the parts that use them (those composed and those
            still to come): one group per pair of neighbours."""
            by: dict[frozenset[int], set[int]] = {}
            for t in alphabet:
                by.setdefault(frozenset(used_by[t]), set()).add(t)
            return [frozenset(g) for g in by.values()]

        def take(i: int) -> None:
            for t in parts[i].alphabet:
                left[t] -= 1

        def closed(lts: Lts, keep: frozenset[int]) -> set[int]:
            return {t for t in lts.alphabet if left[t] == 0 and t not in visible
                    and t not in keep}

        while q < len(order):
            if record:
                root_steps.append((q, cur))
            take(order[q])
            segment = parts[order[q]]
            q += 1
            if cur is None:
                cur = minimized(segment.hide(closed(segment, frozenset())))
                continue
            # a connector between ``cur`` and the next part (a channel and the agent reading
            # it) is composed with that part first: ``cur`` never carries the channel's state
            # unconstrained by its reader, and there is one large reduction instead of two
            if (order[q - 1] in connectors and q < len(order)
                    and segment.alphabet <= cur.alphabet | parts[order[q]].alphabet):
                take(order[q])
                nxt = parts[order[q]]
                q += 1
                segment = compose(segment, nxt, closed(segment, cur.alphabet)
                                  | closed(nxt, cur.alphabet))
            hidden = closed(cur, frozenset()) | closed(segment, frozenset())
            if q == len(order) and not visible and k_root:
                # the whole net with nothing visible: its deadlocks and flags are read off
                # the product directly, a reduction would be wasted
                cur = counted(product(cur, segment, frozenset(hidden), max_states))
                continue
            cur = compose(cur, segment, hidden,
                          interfaces((cur.alphabet | segment.alphabet) - hidden))
        assert cur is not None
        return cur

    # 1. bottom-up: every page's subtree, the root's is the whole net with nothing visible;
    # a subtree equal to one built before up to renaming (another agent of a ring) is renamed
    built: dict[int, Lts] = {}
    seen: dict[Hashable, tuple[Lts, tuple[int, ...]]] = {}
    for k in range(len(nodes) - 1, -1, -1):
        key, transitions = subtree_key(nodes, k, nb, users, own_control, entries)
        if reuse and key in seen:
            lts, source = seen[key]
            built[k] = rename(lts, source, transitions)
            continue
        built[k] = build(k)
        seen[key] = (built[k], transitions)
    whole = built[0]
    assert not whole.alphabet, "every transition is hidden at the root"
    unsafe = any(f & UNSAFE for f in whole.flags)
    dead = any(_dead(whole, s) for s in range(whole.size))
    if any(f & VIOLATED for f in whole.flags):
        # the runs up to a violation are real: what they reach stands, nothing else does
        res.safe = False if unsafe else None
        res.deadlock_free = False if dead else None
        res.stopped = ("a page of the net can be entered while it is still busy, so the "
                       "compositional check does not apply")
        return
    res.safe = not unsafe
    res.deadlock_free = not dead
    res.complete = True
    if not detail:
        return

    # 2. for every subsystem: the whole net again, rebuilt along the path from the subsystem
    # to the root (every other subtree as built above), the subsystem's ITERATION
    # transitions visible and its places observed
    wanted = set(progress_subsystems) if progress_subsystems is not None else None

    def inspect(k: int) -> None:
        name = nodes[k].owner
        iterations = frozenset(t.index for t in net.transitions
                               if t.subsystem == name and t.role is Role.ITERATION)
        check = bool(iterations) and (wanted is None or name in wanted)
        behaviours = _behaviour_places(net, name)
        observe = (live_places(net, name) if check else 0, *behaviours.values())
        # a behaviour without places of its own is seen by its transitions firing
        placeless = {t.index: (name, t.behaviour) for t in net.transitions
                     if t.subsystem == name and t.behaviour is not None
                     and (name, t.behaviour) not in behaviours}
        keep = iterations | frozenset(placeless)
        tick("subsystems")
        graph = build(k, keep, observe)
        node = k
        while nodes[node].parent is not None:
            parent = nodes[node].parent
            assert parent is not None
            graph = build(parent, keep, (), (node, graph))
            node = parent
        seen = 0
        for f in graph.flags:
            seen |= f
        for i, key in enumerate(behaviours):
            if seen & (OBSERVED << (i + 1)):
                res.reached.add(key)
        for edges in graph.out:
            for a, _ in edges:
                if a in placeless:
                    res.reached.add(placeless[a])  # type: ignore[arg-type]
        if check:
            res.progress_checked.append(name)
            if _loses_progress(graph, iterations):
                res.progress_lost.append(name)

    for k, n in enumerate(nodes):
        if n.kind in SUBSYSTEM_KINDS:
            inspect(k)
    res.detail_complete = True


def _entries(nb: NetBits, inside: int) -> frozenset[int]:
    """Transitions that put a token into ``inside`` without taking one from it."""
    found: set[int] = set()
    for p in bits(inside):
        for t in bits(nb.producers[p]):
            if not nb.pre[t] & inside:
                found.add(t)
    return frozenset(found)


def _behaviour_places(net: FlatNet, subsystem: str) -> dict[tuple[str, str], int]:
    """Per behaviour of the subsystem (subsystem, behaviour): the mask of its places."""
    out: dict[tuple[str, str], int] = {}
    for place in net.places:
        if place.behaviour is not None and place.subsystem == subsystem:
            key = (subsystem, place.behaviour)
            out[key] = out.get(key, 0) | 1 << place.index
    return out


def _dead(lts: Lts, s: int) -> bool:
    return not lts.out[s] and not lts.flags[s] & (FINAL | SINK)


def _loses_progress(graph: Lts, iterations: frozenset[int]) -> bool:
    """Is there a reachable state where the component's subsystem is unfinished (flag
    ``OBSERVED``), from which no iteration of it and no deadlock can be reached?"""
    n = graph.size
    preds: list[list[int]] = [[] for _ in range(n)]
    sources: list[int] = []
    for s, edges in enumerate(graph.out):
        iterates = False
        for a, d in edges:
            preds[d].append(s)
            iterates = iterates or a in iterations
        if iterates:
            sources.append(s)
    can_dead = _backward([s for s in range(n) if _dead(graph, s)], preds)
    can_iterate = _backward(sources, preds)
    return any(graph.flags[s] & OBSERVED and not can_dead[s] and not can_iterate[s]
               for s in range(n))


def _backward(seeds: list[int], preds: list[list[int]]) -> list[bool]:
    seen = [False] * len(preds)
    stack = list(seeds)
    for s in seeds:
        seen[s] = True
    while stack:
        s = stack.pop()
        for p in preds[s]:
            if not seen[p]:
                seen[p] = True
                stack.append(p)
    return seen
