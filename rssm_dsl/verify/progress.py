"""Progress: can a subsystem get stuck for good while the rest of the system keeps running?

A global deadlock check calls a system fine as long as *something* can still move. This check
looks at each subsystem ``s`` that has ITERATION transitions (completing one iteration of one
of its behaviours) in the full reachability graph.

Definition. ``s`` *loses progress* when some reachable marking ``m`` has all three:

1. ``s`` is not finished in ``m``: some place of ``s`` marked in ``m`` can still lead to an
   ITERATION transition of ``s`` through ``s``'s own transitions (structurally, ignoring the
   other input places, except the places of tracked values that are empty in ``m`` and
   that no transition ever marks: a variant needing one of those can never fire again, e.g.
   a switch's variant for a value that ``m`` has left for good; ``unfinished_states``). A
   subsystem whose token has gone past its last iteration (to its output place) is
   finished, not stuck.
2. No firing sequence from ``m`` fires an ITERATION transition of ``s``: whatever the
   scheduling and whatever the data (conditions are free choices), ``s`` never completes an
   iteration again.
3. No firing sequence from ``m`` reaches a deadlock: the rest of the system keeps moving
   forever. (A run into a global deadlock is reported as a deadlock instead.)
4. No firing sequence from ``m`` finishes ``s`` (1 is structural: before a switch to ``end``
   whose guard the tracked values decide, ``s`` is unfinished and can only end).

Equivalently, with 2 to 4: every terminal strongly connected component reachable from ``m``
has edges, none of them is an ITERATION transition of ``s`` and ``s`` is unfinished in all
its markings. The check is the branching property "from every reachable marking where ``s``
is not finished, an iteration of ``s``, its end or a deadlock stays reachable"
(``AG (unfinished_s -> EF (iteration_s or finished_s or deadlock))``). Runs that merely
*could* starve ``s`` forever in a non-terminal component, while ``s`` can still iterate, are
not reported: they are scheduling choices (fairness), not design errors.

Computation, all vectorised on the graph: the markings that can reach a deadlock and, per
subsystem, those that can reach a source of an ITERATION edge of ``s`` (backward breadth-first
closures over the reversed edges). The first marking of the BFS order satisfying 1-3 is the
*point of no return* (a shortest path leads to it); from it we find a terminal component (by
alternating forward and backward closures) and a cycle in it, printed as what the system keeps
doing while ``s`` waits.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
import numpy.typing as npt

from rssm_core.records import dataclass
from rssm_dsl.hpn.flat import FlatNet, Role
from rssm_dsl.verify.budget import Budget, LimitReached
from rssm_dsl.verify.netbits import NetBits, bits, to_words
from rssm_dsl.verify.statespace import Graph, Ints, gather

Bools = npt.NDArray[np.bool_]
I64 = npt.NDArray[np.int64]


@dataclass(frozen=True, slots=True)
class ProgressViolation:
    subsystem: str
    point: int                      # state id of the point of no return
    prefix: tuple[int, ...]         # shortest firing sequence from the initial marking to it
    to_cycle: tuple[int, ...]       # from the point to a marking of a terminal component
    cycle: tuple[int, ...]          # a cycle in that component (what keeps running)
    cycle_marking: int              # the marking where the cycle starts


@dataclass(frozen=True, slots=True)
class ProgressResult:
    violations: tuple[ProgressViolation, ...]
    checked: tuple[str, ...]        # subsystems checked
    skipped: tuple[str, ...]        # subsystems without ITERATION transitions
    stopped: str | None = None      # a limit of the budget stopped the check (the
    #                                 violations found before it are real)


def subsystems_of(net: FlatNet) -> list[str]:
    """The subsystems to check: the net's list, else those owning an ITERATION transition."""
    if net.subsystems:
        return list(net.subsystems)
    seen: dict[str, None] = {}
    for t in net.transitions:
        if t.role is Role.ITERATION and t.subsystem is not None:
            seen.setdefault(t.subsystem)
    return list(seen)


def live_places(net: FlatNet, subsystem: str, gone: frozenset[int] = frozenset()) -> int:
    """Places of ``subsystem`` from which its own transitions can reach an ITERATION one;
    with ``gone``, only through transitions that need none of those places (places empty
    for good in the marking at hand, see ``fading_places``)."""
    own = [t for t in net.transitions if t.subsystem == subsystem and gone.isdisjoint(t.pre)]
    owned = {p.index for p in net.places if p.subsystem == subsystem}
    if not owned:   # places not attributed: those its transitions touch, except shared ones
        owned = {p for t in own for p in (*t.pre, *t.post)
                 if net.places[p].channel is None and net.places[p].subsystem is None}
    live: set[int] = set()
    changed = True
    while changed:
        changed = False
        for t in own:
            if t.role is Role.ITERATION or live.intersection(t.post):
                for p in t.pre:
                    if p in owned and p not in live:
                        live.add(p)
                        changed = True
    mask = 0
    for p in live:
        mask |= 1 << p
    return mask


MAX_FADING = 4      # fading places judged per marking (2^k live sets); the rest count as
#                     markable, which only makes more markings unfinished (the safe side)


def fading_places(net: FlatNet, subsystem: str, within: int = -1) -> tuple[int, ...]:
    """Input places of ``subsystem``'s transitions that no transition ever marks (none has
    the place in its post set and not in its pre set): once such a place is empty it stays
    empty, and the transitions needing it are dead. The value places of a tracked value
    that is never written back to one of its values (valuenet.py) are the usual case: a
    ``switch ... otherwise`` variant for ``flag = false`` once ``flag`` is true for good.
    Only value places count (any other input place is ignored, as point 1 says: a
    subsystem waiting for good on a place nobody marks is stuck, not finished). At most
    ``MAX_FADING`` of them (the first in place order), of the mask ``within``."""
    marks = {p for t in net.transitions for p in t.post if p not in t.pre}
    out: dict[int, None] = {}
    for t in net.transitions:
        if t.subsystem == subsystem:
            for p in t.pre:
                if p not in marks and within >> p & 1 and _is_value(net, p):
                    out.setdefault(p)
    return tuple(sorted(out))[:MAX_FADING]


def _is_value(net: FlatNet, p: int) -> bool:
    """A place of a tracked value (valuenet.py)."""
    return (net.places[p].channel or "").startswith("value ")


def unfinished_masks(net: FlatNet, subsystem: str,
                     fading: tuple[int, ...]) -> tuple[int, ...]:
    """``live_places`` for each subset of ``fading`` gone: entry ``i`` has gone the places
    ``fading[j]`` with bit ``j`` of ``i`` set. A marking ``m`` leaves ``s`` unfinished iff
    it marks a place of the entry whose bits are the places of ``fading`` empty in ``m``."""
    return tuple(live_places(net, subsystem,
                             frozenset(p for j, p in enumerate(fading) if i >> j & 1))
                 for i in range(1 << len(fading)))


def unfinished_states(nb: NetBits, graph: Graph, subsystem: str) -> Bools:
    """Per state: is ``subsystem`` not finished there (point 1 of the module docstring),
    judged on the state's whole marking, value places included?"""
    fading = fading_places(nb.net, subsystem)
    masks = unfinished_masks(nb.net, subsystem, fading)
    if not fading:
        return marked_any(graph, masks[0], nb.nwords)
    key = np.zeros(graph.size, dtype=np.int64)
    for j, p in enumerate(fading):
        key |= (~marked_any(graph, 1 << p, nb.nwords)).astype(np.int64) << j
    out = np.zeros(graph.size, dtype=np.bool_)
    for i in np.unique(key).tolist():
        rows = key == i
        out |= rows & marked_any(graph, masks[int(i)], nb.nwords)
    return out


def _distinct(nodes: Ints, scratch: I64) -> Ints:
    """``nodes`` without repetitions (order kept), in linear time: the last writer wins."""
    if nodes.size < 2:
        return nodes
    pos = np.arange(nodes.size, dtype=np.int64)
    scratch[nodes] = pos
    out: Ints = nodes[scratch[nodes] == pos]
    return out


def backward_closure(graph: Graph, seeds: Bools, within: Bools | None = None,
                     budget: Budget | None = None) -> Bools:
    """States from which some seed state is reachable (seeds included), optionally only
    through states of ``within``."""
    ptr, order = graph.backward()
    reached = seeds.copy()
    scratch = np.zeros(graph.size, dtype=np.int64)
    frontier: Ints = np.flatnonzero(reached)
    while frontier.size:
        if budget is not None:
            budget.check()
        preds: Ints = graph.src[gather(ptr, order, frontier)]
        keep = ~reached[preds]
        if within is not None:
            keep &= within[preds]
        preds = _distinct(preds[keep], scratch)
        if preds.size == 0:
            break
        reached[preds] = True
        frontier = preds
    return reached


def forward_closure(graph: Graph, start: int, budget: Budget | None = None) -> Bools:
    """States reachable from ``start`` (all of them from the initial state 0)."""
    if start == 0:
        return np.ones(graph.size, dtype=np.bool_)
    ptr, order = graph.forward()
    reached = np.zeros(graph.size, dtype=np.bool_)
    reached[start] = True
    scratch = np.zeros(graph.size, dtype=np.int64)
    frontier: Ints = np.array([start], dtype=np.int64)
    while frontier.size:
        if budget is not None:
            budget.check()
        succ: Ints = graph.dst[gather(ptr, order, frontier)]
        succ = _distinct(succ[~reached[succ]], scratch)
        if succ.size == 0:
            break
        reached[succ] = True
        frontier = succ
    return reached


def shortest_path(graph: Graph, start: int, goal: Bools, allow_empty: bool = True,
                  within: Bools | None = None) -> tuple[tuple[int, ...], int]:
    """A shortest firing sequence from ``start`` to a state in ``goal``, and that state; with
    ``within``, through states of it only (the goal state itself may lie outside).

    With ``allow_empty=False`` the path has at least one step (a cycle when ``goal`` is start).
    """
    if allow_empty and goal[start]:
        return (), start
    ptr, order = graph.forward()
    parent_edge = np.full(graph.size, -1, dtype=np.int64)
    seen = np.zeros(graph.size, dtype=np.bool_)
    seen[start] = True
    frontier: Ints = np.array([start], dtype=np.int64)
    while frontier.size:
        edges = gather(ptr, order, frontier)
        hits = edges[goal[graph.dst[edges]]]
        if hits.size:
            e = int(hits[0])
            steps = [int(graph.trans[e])]
            node = int(graph.src[e])
            while node != start:
                pe = int(parent_edge[node])
                steps.append(int(graph.trans[pe]))
                node = int(graph.src[pe])
            return tuple(reversed(steps)), int(graph.dst[e])
        dst = graph.dst[edges]
        fresh = ~seen[dst]
        if within is not None:
            fresh &= within[dst]
        edges, dst = edges[fresh], dst[fresh]
        if dst.size == 0:
            break
        dst, first = np.unique(dst, return_index=True)
        parent_edge[dst] = edges[first]
        seen[dst] = True
        frontier = dst
    raise ValueError("goal not reachable")


def terminal_component(graph: Graph, start: int, budget: Budget | None = None,
                       ) -> tuple[int, Bools]:
    """A state of a terminal strongly connected component reachable from ``start``, and it."""
    x = start
    while True:
        reach = forward_closure(graph, x, budget)
        seed = np.zeros(graph.size, dtype=np.bool_)
        seed[x] = True
        back = backward_closure(graph, seed, None if reach.all() else reach, budget)
        outside = reach & ~back
        if not outside.any():
            return x, reach
        x = int(np.flatnonzero(outside)[0])


def marked_any(graph: Graph, mask: int, nwords: int) -> Bools:
    """Per state: does it mark some place of ``mask``?"""
    words = to_words(mask, nwords)
    out = np.zeros(graph.size, dtype=np.bool_)
    for w, value in enumerate(words):
        if value:
            out |= (graph.states[:, w] & np.uint64(value)) != 0
    return out


def check_progress(nb: NetBits, graph: Graph, subsystems: list[str] | None = None,
                   budget: Budget | None = None, fairness: str = "strong") -> ProgressResult:
    """Subsystems that can lose progress (see the module docstring), with lassos. A limit
    of the budget ends the check: the subsystems checked before it and their violations are
    returned, with ``stopped``. With ``fairness="weak"`` (the graph must be the full one:
    every enabled transition an edge), also a subsystem that a weakly fair run starves
    (``weak_starvation``)."""
    net = nb.net
    names = subsystems_of(net) if subsystems is None else subsystems
    violations: list[ProgressViolation] = []
    checked: list[str] = []
    skipped = [s for s in names if not nb.iteration_mask(s)]
    limits = budget if budget is not None else Budget()
    with limits.running("the progress check"):
        try:
            _check_subsystems(nb, graph, [s for s in names if s not in skipped], limits,
                              violations, checked, fairness == "weak")
        except LimitReached as e:
            return ProgressResult(tuple(violations), tuple(checked), tuple(skipped),
                                  e.stop.message)
        except MemoryError:
            return ProgressResult(tuple(violations), tuple(checked), tuple(skipped),
                                  limits.out_of_memory().message)
    return ProgressResult(tuple(violations), tuple(checked), tuple(skipped))


def _check_subsystems(nb: NetBits, graph: Graph, names: list[str], budget: Budget,
                      violations: list[ProgressViolation], checked: list[str],
                      weak: bool = False) -> None:
    """``check_progress`` for the subsystems ``names`` (all with ITERATION transitions):
    each is appended to ``checked`` once decided, its violation (if any) first."""
    n = graph.size
    outdeg = np.bincount(graph.src, minlength=n)
    can_deadlock = (backward_closure(graph, outdeg == 0, None, budget) if not outdeg.all()
                    else np.zeros(n, dtype=np.bool_))
    # Fast path: one terminal component that every state reaches and that has edges; a
    # subsystem iterating inside it can always iterate again.
    unique_terminal: Bools | None = None
    if graph.src.size and not (outdeg == 0).any():
        _, component = terminal_component(graph, 0, budget)
        if component.all() or backward_closure(graph, component, None, budget).all():
            unique_terminal = component
    for s in names:
        budget.check(len(checked))
        is_it = np.zeros(nb.ntrans, dtype=np.bool_)
        is_it[bits(nb.iteration_mask(s))] = True
        if not weak and unique_terminal is not None and (
                unique_terminal[graph.src] & is_it[graph.trans]).any():
            checked.append(s)
            continue
        # a state from which s can still finish (end by design) is not a point of no
        # return either: "unfinished" is structural and holds before a switch to `end`
        # whose guard the tracked values decide (no iteration can follow it)
        unfinished = unfinished_states(nb, graph, s)
        seeds = ~unfinished
        seeds[graph.src[is_it[graph.trans]]] = True
        can_iterate = backward_closure(graph, seeds, None, budget)
        stuck = ~can_iterate & ~can_deadlock & unfinished
        hits = np.flatnonzero(stuck)
        if hits.size:
            violations.append(_lasso(graph, s, int(hits[0]), budget))
        elif weak:
            found = weak_starvation(graph, s, unfinished, is_it, budget)
            if found is not None:
                violations.append(found)
        checked.append(s)


def weak_starvation(graph: Graph, s: str, unfinished: Bools, is_it: Bools,
                    budget: Budget | None = None) -> ProgressViolation | None:
    """A weakly fair run that starves ``s``: a strongly connected set C of states where
    ``s`` is unfinished, joined by moves other than ``s``'s iterations, in which every
    transition enabled in all states of C is taken (weak fairness: a move enabled for good
    is taken). A run round all of C is then weakly fair and never iterates ``s``; a smaller
    cycle inside C would only have more moves enabled throughout and fewer taken, so C is
    the only candidate in its component. ``graph`` must be complete (every enabled
    transition of a state is one of its edges)."""
    from rssm_dsl.verify.scc import components

    n = graph.size
    src, dst, trans = (graph.src.astype(np.int64), graph.dst.astype(np.int64),
                       graph.trans.astype(np.int64))
    inner = unfinished[src] & unfinished[dst] & ~is_it[trans]
    succ: list[list[int]] = [[] for _ in range(n)]
    for a, b in zip(src[inner].tolist(), dst[inner].tolist(), strict=True):
        succ[a].append(b)
    check = budget.check if budget is not None else None
    comp_list, _ = components(succ, check)
    comp = np.array(comp_list, dtype=np.int64)
    internal = inner & (comp[src] == comp[dst])
    if not internal.any():
        return None
    nt = int(trans.max()) + 1
    size = np.bincount(comp, minlength=int(comp.max()) + 1)
    # (component, transition): in how many of its states enabled; taken inside it
    pairs = np.unique(src[unfinished[src]] * nt + trans[unfinished[src]])
    at, t_of = pairs // nt, pairs % nt
    keys, counts = np.unique(comp[at] * nt + t_of, return_counts=True)
    everywhere = keys[counts == size[keys // nt]]
    taken = np.unique(comp[src[internal]] * nt + trans[internal])
    unfair = np.unique(everywhere[~np.isin(everywhere, taken)] // nt)
    candidates = np.setdiff1d(np.unique(comp[src[internal]]), unfair)
    if candidates.size == 0:
        return None
    c = int(candidates[0])
    members = np.flatnonzero(comp == c)
    entry = int(members.min())                # the first in BFS order: shortest prefix
    needed = set((everywhere[everywhere // nt == c] % nt).tolist())
    cycle = _fair_cycle(graph, entry, comp == c, internal, needed)
    return ProgressViolation(subsystem=s, point=entry, prefix=graph.path(entry), to_cycle=(),
                             cycle=cycle, cycle_marking=graph.marking(entry))


def _fair_cycle(graph: Graph, entry: int, inside: Bools, internal: Bools,
                needed: set[int]) -> tuple[int, ...]:
    """A cycle from ``entry`` through states of ``inside`` along ``internal`` edges that
    takes every transition of ``needed`` (at least one step)."""
    edges = np.flatnonzero(internal & inside[graph.src])
    out: dict[int, list[tuple[int, int]]] = {}
    for e in edges.tolist():
        out.setdefault(int(graph.src[e]), []).append((int(graph.trans[e]), int(graph.dst[e])))

    def path(a: int, goal: Callable[[int, int, int], bool]) -> tuple[list[int], int]:
        """BFS from ``a`` to the first edge (x, t, y) with goal(x, t, y): its steps, y."""
        prev: dict[int, tuple[int, int]] = {a: (-1, -1)}
        frontier = [a]
        while frontier:
            nxt = []
            for x in frontier:
                for t, y in out.get(x, []):
                    if goal(x, t, y):
                        steps = [t]
                        while x != a:
                            px, pt = prev[x]
                            steps.append(pt)
                            x = px
                        return steps[::-1], y
                    if y not in prev:
                        prev[y] = (x, t)
                        nxt.append(y)
            frontier = nxt
        raise ValueError("no such edge inside the component")

    cycle: list[int] = []
    here = entry
    def labelled(wanted: int) -> Callable[[int, int, int], bool]:
        return lambda x, t, y: t == wanted

    def back(x: int, t: int, y: int) -> bool:
        return y == entry

    for t_needed in sorted(needed):
        steps, here = path(here, labelled(t_needed))
        cycle += steps
    if here != entry or not cycle:
        steps, here = path(here, back)
        cycle += steps
    return tuple(cycle)


def _lasso(graph: Graph, s: str, point: int, budget: Budget) -> ProgressViolation:
    """The violation of ``s`` at its point of no return: the path to it, then to a
    terminal component, and a cycle there."""
    _, component = terminal_component(graph, point, budget)
    to_cycle, entry = shortest_path(graph, point, component)
    goal = np.zeros(graph.size, dtype=np.bool_)
    goal[entry] = True
    cycle, _ = shortest_path(graph, entry, goal, allow_empty=False)
    return ProgressViolation(
        subsystem=s, point=point, prefix=graph.path(point), to_cycle=to_cycle,
        cycle=cycle, cycle_marking=graph.marking(entry))
