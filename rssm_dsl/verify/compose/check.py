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
from dataclasses import field

from rssm_core.records import dataclass
from rssm_dsl.hpn.flat import FlatNet, Role
from rssm_dsl.verify.budget import Budget, LimitReached
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
from rssm_dsl.verify.progress import fading_places, unfinished_masks


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
                  on_step: StepCallback | None = None, reuse: bool = True,
                  budget: Budget | None = None) -> ComposeResult:
    """``reuse``: rename the LTS of a subtree equal to one built before (``cache``).
    ``deadline`` (a ``time.monotonic()`` instant) applies only without a ``budget``."""
    res = ComposeResult()
    if budget is None:
        budget = Budget(None if deadline is None else max(0.0, deadline - time.monotonic()))
    with budget.running("the compositional check"):
        try:
            run = _Composer(net, nb, max_states, budget, on_step, res, detail)
            if run.verdict(reuse) and detail:
                run.details(progress_subsystems)
        except TooLarge as e:
            res.stopped = str(e)
        except LimitReached as e:
            res.stopped = e.stop.message
        except MemoryError:
            res.stopped = budget.out_of_memory().message
    return res


class _Composer:
    """One compositional check: the page tree of the net, the LTS of every subtree (step 1,
    ``verdict``), then per subsystem the whole net again (step 2, ``details``)."""

    def __init__(self, net: FlatNet, nb: NetBits, max_states: int, budget: Budget,
                 on_step: StepCallback | None, res: ComposeResult, detail: bool = True) -> None:
        self.net, self.nb, self.max_states, self.budget = net, nb, max_states, budget
        self.detail = detail          # step 2 follows: record the system page's composition
        self.on_step, self.res = on_step, res
        self.nodes = nodes = page_tree(net, nb)
        res.components = sum(1 for n in nodes if n.own is not None)
        # users[t]: pre-order numbers of the nodes whose own places t touches
        self.users: dict[int, list[int]] = {}
        for k, node in enumerate(nodes):
            if node.own is not None:
                for t in node.own.transitions:
                    self.users.setdefault(t, []).append(k)
        self.shared = frozenset(t for t, us in self.users.items() if len(us) > 1)
        # the structural assumption: a page's subtree is entered only while none of its
        # control places (all but the channels' fusion places) is marked
        control = 0
        for p in net.places:
            if not is_fusion(net, p.index):
                control |= 1 << p.index
        self.own_control = [(n.own.places & control) if n.own is not None else 0
                            for n in nodes]
        tree_control = self.own_control[:]
        for k in range(len(nodes) - 1, 0, -1):
            parent = nodes[k].parent
            assert parent is not None
            if nodes[k].kind != "device":     # a device net runs from the start, on its own
                tree_control[parent] |= tree_control[k]
        self.entries = [frozenset() if k == 0 else _entries(nb, tree_control[k])
                        for k in range(len(nodes))]
        self.done = 0
        self.built: dict[int, Lts] = {}
        # the system page's composition in step 1: its order, and what was composed before
        # each step, so that the progress check starts a subsystem's agent from there
        self.root_order: list[int] = []
        self.root_steps: list[tuple[int, Lts | None]] = []
        # ... and the system page's parts from each step on, composed (from the last back):
        # a subsystem's agent is then composed with what came before it and what comes
        # after, two compositions instead of the rest of the ring again
        self.root_suffix: dict[int, Lts] = {}

    # ------------------------------------------------------------------ step 1
    def verdict(self, reuse: bool) -> bool:
        """Bottom-up: every page's subtree, the root's is the whole net with nothing
        visible; a subtree equal to one built before up to renaming (another agent of a
        ring) is renamed. Safeness and deadlocks read off the root's; False when the check
        does not apply."""
        nodes, built, res = self.nodes, self.built, self.res
        seen: dict[Hashable, tuple[Lts, tuple[int, ...]]] = {}
        for k in range(len(nodes) - 1, -1, -1):
            key, transitions = subtree_key(nodes, k, self.nb, self.users, self.own_control,
                                           self.entries)
            if reuse and key in seen:
                lts, source = seen[key]
                built[k] = rename(lts, source, transitions)
                continue
            built[k] = self.build(k)
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
            return False
        res.safe = not unsafe
        res.deadlock_free = not dead
        res.complete = True
        return True

    # ------------------------------------------------------------------ step 2
    def details(self, progress_subsystems: list[str] | None) -> None:
        """For every subsystem: the whole net again, rebuilt along the path from the
        subsystem to the root (every other subtree as built in step 1), the subsystem's
        ITERATION transitions visible and its places observed."""
        wanted = set(progress_subsystems) if progress_subsystems is not None else None
        subsystems = [k for k, n in enumerate(self.nodes) if n.kind in SUBSYSTEM_KINDS]
        for i, k in enumerate(subsystems):
            with self.budget.running(f"the compositional check of subsystem "
                                     f"{self.nodes[k].owner}, {i + 1} of {len(subsystems)}"):
                self.inspect(k, wanted)
        self.res.detail_complete = True

    def inspect(self, k: int, wanted: set[str] | None) -> None:
        net, nodes, res = self.net, self.nodes, self.res
        name = nodes[k].owner
        iterations = frozenset(t.index for t in net.transitions
                               if t.subsystem == name and t.role is Role.ITERATION)
        check = bool(iterations) and (wanted is None or name in wanted)
        behaviours = _behaviour_places(net, name)
        # "unfinished" judged on the whole local state (progress.unfinished_states): the
        # live places for each set of the subtree's fading places found empty; observation
        # 0 has none gone, then the behaviours, the other sets and the fading places (a
        # fading place outside the subtree is not observed, so counts as markable)
        subtree = 0
        for c in range(nodes[k].first, nodes[k].last):
            own = nodes[c].own
            if own is not None:
                subtree |= own.places
        fading = fading_places(net, name, subtree) if check else ()
        masks = unfinished_masks(net, name, fading) if check else (0,)
        observe = (masks[0], *behaviours.values(), *masks[1:],
                   *(1 << p for p in fading))
        unfinished = _Unfinished(len(behaviours), len(fading))
        # a behaviour without places of its own is seen by its transitions firing
        placeless = {t.index: (name, t.behaviour) for t in net.transitions
                     if t.subsystem == name and t.behaviour is not None
                     and (name, t.behaviour) not in behaviours}
        keep = iterations | frozenset(placeless)
        self.tick("subsystems")
        graph = self.build(k, keep, observe)
        node = k
        while nodes[node].parent is not None:
            parent = nodes[node].parent
            assert parent is not None
            graph = self.build(parent, keep, (), (node, graph))
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
            if _loses_progress(graph, iterations, unfinished):
                res.progress_lost.append(name)

    # ------------------------------------------------------------------ building blocks
    def tick(self, phase: str) -> None:
        self.budget.check(self.res.states)
        self.done += 1
        if self.on_step is not None:
            self.on_step(phase, self.done, len(self.nodes))

    def counted(self, lts: Lts) -> Lts:
        self.res.states += lts.size
        self.res.largest = max(self.res.largest, lts.size)
        return lts

    def minimized(self, lts: Lts, groups: Sequence[frozenset[int]] = ()) -> Lts:
        return minimize(self.counted(lts), groups, self.budget)

    def compose(self, x: Lts, y: Lts, hidden: frozenset[int] | set[int],
                groups: Sequence[frozenset[int]] = ()) -> Lts:
        return self.minimized(product(x, y, frozenset(hidden), self.max_states, self.budget),
                              groups)

    def product(self, x: Lts, y: Lts, hidden: frozenset[int] | set[int]) -> Lts:
        """Unreduced (the whole net with nothing visible: its deadlocks and flags are read
        off the product directly, a reduction would be wasted)."""
        return self.counted(product(x, y, frozenset(hidden), self.max_states, self.budget))

    def leaves_subtree(self, t: int, k: int) -> bool:
        node = self.nodes[k]
        return any(not node.first <= u < node.last for u in self.users[t])

    def own_lts(self, k: int, keep: frozenset[int] = frozenset(),
                observe: tuple[int, ...] = ()) -> Lts | None:
        own = self.nodes[k].own
        if own is None:
            return None
        self.tick("components")
        return self.minimized(local_lts(self.nb, own, self.shared | keep, self.max_states,
                                        observe, self.own_control[k], self.entries[k],
                                        self.budget))

    def build(self, k: int, keep: frozenset[int] = frozenset(), observe: tuple[int, ...] = (),
              child: tuple[int, Lts] | None = None) -> Lts:
        """Node k's subtree composed, only ``keep`` and the transitions leaving it visible;
        with ``observe``, rebuilt all the way down; with ``child``, that child's LTS given."""
        nodes = self.nodes
        mine = self.own_lts(k, keep, observe)
        parts = ([mine] if mine is not None else []) + [
            child[1] if child is not None and c == child[0] else
            self.built[c] if not observe else self.build(c, keep, observe)
            for c in nodes[k].children]
        visible = frozenset(t for p in parts for t in p.alphabet
                            if t in keep or self.leaves_subtree(t, k))
        connectors = {i + (mine is not None) for i, c in enumerate(nodes[k].children)
                      if nodes[c].kind == "channel"}
        chain = _Chain(self, parts, visible, connectors, k == 0)
        if k == 0 and child is not None and self.root_order:
            # only the child differs from step 1: resume the recorded composition
            whole = chain.resume(nodes[k].children.index(child[0]) + (mine is not None))
        else:
            whole = chain.run(record=k == 0 and not keep and self.detail)
        result = self.guard(whole, self.entries[k])
        if nodes[k].kind == "device":     # its places are not its agent's control places
            result = self.minimized(Lts(result.init, [f & ~BUSY for f in result.flags],
                                        result.out, result.alphabet))
        return result

    def guard(self, lts: Lts, enter: frozenset[int]) -> Lts:
        """``lts`` with every firing of ``enter`` in a ``BUSY`` state sent to a
        ``VIOLATED`` sink."""
        if not enter or not any(lts.flags[s] & BUSY and any(a in enter for a, _ in edges)
                                for s, edges in enumerate(lts.out)):
            return lts
        sink = lts.size
        out = [[(a, sink if a in enter and lts.flags[s] & BUSY else d) for a, d in edges]
               for s, edges in enumerate(lts.out)]
        return self.minimized(Lts(lts.init, [*lts.flags, VIOLATED], [*out, []], lts.alphabet))


class _Chain:
    """Compose ``parts`` one at a time (``composition_order``), hiding every action not in
    ``visible`` as soon as all parts using it are in. A connector (a channel) that links
    what is composed to the next part goes in together with that part."""

    def __init__(self, run: _Composer, parts: list[Lts], visible: frozenset[int],
                 connectors: set[int], k_root: bool) -> None:
        self.c, self.parts, self.visible = run, parts, visible
        self.connectors, self.k_root = connectors, k_root
        self.left: dict[int, int] = {}
        self.used_by: dict[int, set[int]] = {}
        for i, p in enumerate(parts):
            for t in p.alphabet:
                self.used_by.setdefault(t, set()).add(i)

    def run(self, record: bool) -> Lts:
        """``record``: keep the order and every step's start (the system page in step 1),
        and the composition of the parts from each step on (``suffixes``)."""
        order = composition_order([p.alphabet for p in self.parts])
        if record:
            self.c.root_order[:] = order
        whole = self._steps(order, 0, None, record)
        if record:
            self.suffixes()
        return whole

    def suffixes(self) -> None:
        """For each recorded step but the first, the parts from it to the end composed,
        backwards, each action hidden once every part using it is in."""
        c, parts, order = self.c, self.parts, self.c.root_order
        starts = [q for q, _ in c.root_steps] + [len(order)]
        inside: dict[int, int] = {}

        def closed(lts: Lts, keep: frozenset[int] = frozenset()) -> set[int]:
            return {t for t in lts.alphabet if inside[t] == len(self.used_by[t])
                    and t not in self.visible and t not in keep}

        cur: Lts | None = None
        for i in range(len(starts) - 2, 0, -1):
            segment: Lts | None = None
            for j in order[starts[i]:starts[i + 1]]:
                for t in parts[j].alphabet:
                    inside[t] = inside.get(t, 0) + 1
            later = cur.alphabet if cur is not None else frozenset()
            for j in order[starts[i]:starts[i + 1]]:
                segment = parts[j] if segment is None else c.compose(
                    segment, parts[j], closed(segment, later) | closed(parts[j], later))
            assert segment is not None
            if cur is None:
                cur = c.minimized(segment.hide(closed(segment)))
            else:
                hidden = closed(cur) | closed(segment)
                cur = c.compose(segment, cur, hidden,
                                self._interfaces((cur.alphabet | segment.alphabet) - hidden))
            c.root_suffix[starts[i]] = cur

    def resume(self, replaced: int) -> Lts:
        """The recorded composition with part ``replaced`` replaced, which is the only one
        to differ: from the last step recorded before that part, that step, then the
        composition of the steps after it (``suffixes``)."""
        c, order = self.c, self.c.root_order
        where = order.index(replaced)
        i = max(k for k, (q, _) in enumerate(c.root_steps) if q <= where)
        q, cur = c.root_steps[i]
        end = c.root_steps[i + 1][0] if i + 1 < len(c.root_steps) else len(order)
        suffix = c.root_suffix.get(end)
        if suffix is None:
            return self._steps(order, q, cur, False)
        for j in order[end:]:
            for t in self.parts[j].alphabet:
                self.left[t] = self.left.get(t, 0) + 1
        head = self._steps(order, q, cur, False, stop=end)
        for j in order[end:]:
            self._take(j)
        hidden = self._closed(head, frozenset()) | self._closed(suffix, frozenset())
        if self.k_root:
            # the whole net: its flags and edges are read off once, a reduction is wasted
            return c.product(head, suffix, hidden)
        return c.compose(head, suffix, hidden,
                         self._interfaces((head.alphabet | suffix.alphabet) - hidden))

    def _interfaces(self, alphabet: frozenset[int]) -> list[frozenset[int]]:
        """The open actions grouped by the parts that use them (those composed and those
        still to come): one group per pair of neighbours."""
        by: dict[frozenset[int], set[int]] = {}
        for t in alphabet:
            by.setdefault(frozenset(self.used_by[t]), set()).add(t)
        return [frozenset(g) for g in by.values()]

    def _take(self, i: int) -> Lts:
        part = self.parts[i]
        for t in part.alphabet:
            self.left[t] -= 1
        return part

    def _closed(self, lts: Lts, keep: frozenset[int]) -> set[int]:
        return {t for t in lts.alphabet if self.left[t] == 0 and t not in self.visible
                and t not in keep}

    def _steps(self, order: list[int], q: int, cur: Lts | None, record: bool,
               stop: int | None = None) -> Lts:
        """Compose the parts ``order[q:stop]`` onto ``cur`` (the parts after ``stop`` are
        counted as still to come: what they use stays visible)."""
        c, parts = self.c, self.parts
        end = len(order) if stop is None else stop
        for i in order[q:end]:
            for t in parts[i].alphabet:
                self.left[t] = self.left.get(t, 0) + 1
        while q < end:
            if record:
                c.root_steps.append((q, cur))
            segment = self._take(order[q])
            q += 1
            if cur is None:
                cur = c.minimized(segment.hide(self._closed(segment, frozenset())))
                continue
            # a connector between ``cur`` and the next part (a channel and the agent reading
            # it) is composed with that part first: ``cur`` never carries the channel's state
            # unconstrained by its reader, and there is one large reduction instead of two
            if (order[q - 1] in self.connectors and q < end
                    and segment.alphabet <= cur.alphabet | parts[order[q]].alphabet):
                nxt = self._take(order[q])
                q += 1
                segment = c.compose(segment, nxt, self._closed(segment, cur.alphabet)
                                    | self._closed(nxt, cur.alphabet))
            hidden = self._closed(cur, frozenset()) | self._closed(segment, frozenset())
            if q == len(order) and stop is None and not self.visible and self.k_root:
                cur = c.product(cur, segment, hidden)
                continue
            cur = c.compose(cur, segment, hidden,
                            self._interfaces((cur.alphabet | segment.alphabet) - hidden))
        assert cur is not None
        return cur


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


@dataclass(frozen=True)
class _Unfinished:
    """Reads "the subsystem is unfinished" off a state's observation flags (the layout of
    ``Check.inspect``'s ``observe``)."""

    behaviours: int
    fading: int

    def __call__(self, flags: int) -> bool:
        gone = 0
        for j in range(self.fading):
            bit = 1 + self.behaviours + (1 << self.fading) - 1 + j
            if not flags & (OBSERVED << bit):
                gone |= 1 << j
        live = 0 if gone == 0 else self.behaviours + gone
        return bool(flags & (OBSERVED << live))


def _loses_progress(graph: Lts, iterations: frozenset[int],
                    unfinished: Callable[[int], bool] = lambda f: bool(f & OBSERVED)) -> bool:
    """Is there a reachable state where the component's subsystem is unfinished (read off
    its flags by ``unfinished``), from which no iteration of it, no state where it has
    finished and no deadlock can be reached?"""
    n = graph.size
    preds: list[list[int]] = [[] for _ in range(n)]
    sources: list[int] = []
    for s, edges in enumerate(graph.out):
        iterates = False
        for a, d in edges:
            preds[d].append(s)
            iterates = iterates or a in iterations
        if iterates or not unfinished(graph.flags[s]):
            sources.append(s)   # it iterates, or has finished (see progress.py, point 4)
    can_dead = _backward([s for s in range(n) if _dead(graph, s)], preds)
    can_iterate = _backward(sources, preds)
    return any(unfinished(graph.flags[s]) and not can_dead[s] and not can_iterate[s]
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
