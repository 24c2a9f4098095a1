"""Reduced exploration with stubborn sets: exact deadlock and safeness verdicts, fewer states.

In each marking ``m`` only the enabled transitions of a *stubborn set* ``S`` are fired. ``S`` is
closed under the usual rules for place/transition nets:

* an enabled ``t`` in ``S`` brings every transition sharing an input place with it (test arcs
  included): nothing outside ``S`` can take its tokens, so ``t`` commutes with every sequence
  of transitions outside ``S`` (D1) and stays enabled along it (a key transition, D2);
* a disabled ``t`` in ``S`` brings every producer of one unmarked input place (its
  *scapegoat*): nothing outside ``S`` can enable it.

With a seed that is enabled, this preserves every reachable deadlock (Valmari): the set of
deadlocks found is exactly the set of reachable deadlocks, so the deadlock verdict and the
deadlock count are exact. Counterexamples are shortest in the reduced graph only.

Safeness. Let ``φ(m)``: some enabled ``t`` would put a token into a marked place ``p ∈
post(t) \\ pre(t)``. Every explored marking is tested for ``φ`` over *all* its enabled
transitions. To make sure a marking with ``φ`` is explored whenever one is reachable, ``S``
also contains an *up-set*: for every place ``p`` not already proved safe by a place invariant
and every producer ``t`` of ``p``, the producers of one unmarked place of ``{p} + pre(t)`` (one
of them must fire before ``φ`` can hold for ``(t, p)``). Proof sketch: take a shortest path from
``m`` to a ``φ``-marking; it contains a transition of ``S`` (up-set); the first one, ``u``,
commutes to the front (D1), and ``m[u>`` is explored and strictly closer. All markings on a
shortest such path are safe, so the bitset semantics is exact along it. When the invariants
cover every place the up-set is empty and the reduction is as strong as for deadlocks alone.

Choosing the set: an enabled transition in conflict with no other one is a stubborn set on its
own (most plumbing transitions of a layered net are); otherwise up to ``_MAX_SEEDS`` enabled
seeds are grown and the set with the fewest enabled transitions wins, each growth abandoned
as soon as it cannot beat the best so far. Subsystems interacting only through fusion places
get independent sets this way: the closure stops at the channel places.

Enabled sets are maintained incrementally: firing ``t`` can only disable the consumers of the
places it empties and can only enable the consumers of the places it fills.

Progress (``for_progress``): the reduced graph can also decide the progress property of
``progress.py`` when it satisfies the *cycle proviso*: every cycle of the reduced graph contains
a fully expanded marking. It is enforced after the search rather than during it (a per-state
test such as "a successor is already known" expands far too much in cyclic controllers): when
the queue is empty, the strongly connected components of the subgraph of partly expanded
markings are computed, markings meeting every cycle of them (the back-edge targets of a
depth-first search) are expanded fully, the search resumes on what that adds, and so on
until no cycle avoids a fully expanded marking.
With D1, D2 and the proviso, for every explored marking ``y``:

* a firing sequence from ``y`` to a deadlock exists in the full graph iff one exists in the
  reduced graph (deadlock preservation, D2 alone);
* a firing sequence from ``y`` that fires transition ``u`` (an ITERATION of ``s``) exists in
  the full graph iff one exists in the reduced graph: move the first stubborn transition of the
  full sequence to the front (D1), or fire a key transition first when it has none (D2); the
  remaining length decreases at every fully expanded marking, and an infinite run of key
  transitions would close a cycle of the reduced graph, which has a fully expanded marking;
* if some reachable marking can reach neither a deadlock nor an ITERATION of ``s``, the same
  argument leads to an explored marking that can reach neither (the property is preserved
  by firing more transitions).

So a loss of progress found in the reduced graph is real, and one exists in the full graph
only if one is found, with one caveat: "s is not finished" is judged at the explored marking,
which may lie a few extra firings later than the full graph's one (if those firings can finish
``s`` without an iteration, the violation is missed). Dead transitions and unreachable
behaviours are not preserved (they would need every transition visible).

State properties (``visible``, for the properties stated in the spec, verify/userprops.py):
a transition that can change an atom of the property is *visible*; a set holding an enabled
visible transition holds them all (V), and with the cycle proviso (L) no visible transition
is put off forever. The reduced graph then has, for every run of the full one, a run with
the same sequence of visible firings (stuttering equivalence, Valmari), so it reaches a
marking where the atoms have given values iff the full graph does: a state invariant over
the atoms holds in the reduced graph iff it holds in the full one. The argument of progress
above, with "an ITERATION of s" replaced by "a state where Q holds" (Q's transitions
visible), decides `whenever P eventually Q` on the reduced graph too (userprops.py). Each of
these conditions (the conflicts of an enabled transition, the scapegoat of a disabled one, V
and its exclusion from the lone-transition shortcut, the proviso, the up-set) has a test that
fails without it: bench/mutants.py, the stubborn-* mutants.

With ``reduce=False`` the same search fires every enabled transition: a plain Python
reference explorer for the tests.
"""

from __future__ import annotations

import time
from collections import deque
from collections.abc import Callable, Sequence

import numpy as np

from rssm_dsl.verify.budget import Budget, LimitReached
from rssm_dsl.verify.netbits import NetBits, bits, to_words
from rssm_dsl.verify.scc import components
from rssm_dsl.verify.statespace import Graph, Progress, ProgressCallback, SearchResult, Trace

_MAX_SEEDS = 8
_FLOWS_PER_PLACE = 4      # semiflows tried per unmarked place for a necessary enabling set


def _flows_of(nplaces: int, semiflows: Sequence[int]) -> list[list[int]]:
    """Per place, the one-token semiflows holding it: any of them gives a necessary
    enabling set, so only the few smallest are kept (a place lies in hundreds of them in a
    large net, and each is tried in every closure)."""
    out: list[list[int]] = [[] for _ in range(nplaces)]
    for flow in semiflows:
        for p in bits(flow):
            out[p].append(flow)
    for p, flows in enumerate(out):
        if len(flows) > _FLOWS_PER_PLACE:
            out[p] = sorted(set(flows), key=int.bit_count)[:_FLOWS_PER_PLACE]
    return out


class StubbornExplorer:
    """Stubborn-set breadth-first search over int markings."""

    def __init__(self, net_bits: NetBits, safe_places: int = 0, reduce: bool = True,
                 proviso: bool = False, visible: int = 0,
                 semiflows: Sequence[int] = ()) -> None:
        nb = net_bits
        self.nb = nb
        self.reduce = reduce
        self.proviso = proviso
        self.visible = visible
        self.pre = nb.pre
        self.post = nb.post
        self.produce = nb.produce
        self.producers = nb.producers
        # firing t may disable the consumers of what it empties, may enable those of what it fills
        self.disable = [0] * nb.ntrans
        self.wake = [0] * nb.ntrans
        for t in range(nb.ntrans):
            for p in bits(nb.consume[t]):
                self.disable[t] |= nb.consumers[p]
            for p in bits(nb.produce[t]):
                self.wake[t] |= nb.consumers[p]
        # the up-set is needed only for places the invariants did not prove safe
        all_places = (1 << nb.nplaces) - 1
        self.watched: list[tuple[int, int, list[int]]] = []   # (place, its bit, producers)
        for p in bits(all_places & ~safe_places):
            if nb.producers[p]:
                self.watched.append((p, 1 << p, bits(nb.producers[p])))
        # one-token semiflows (place masks): a place of one is marked only after the token
        # has left the place of it marked now (``leave``), see ``scapegoat``
        self.flows_of = _flows_of(nb.nplaces, semiflows)
        self.leave = [0] * nb.nplaces       # per place: transitions emptying it
        for t in range(nb.ntrans):
            for p in bits(nb.consume[t]):
                self.leave[p] |= 1 << t
        # dependent[t]: t and the transitions that can take a token t needs (they empty one
        # of its input places) or need a token t takes (it empties one of theirs); two that
        # only read a place (take it and put it back: a tracked value) commute
        self.dependent = [1 << t for t in range(nb.ntrans)]
        for t in range(nb.ntrans):
            for p in bits(nb.pre[t]):
                self.dependent[t] |= self.leave[p]
            for p in bits(nb.consume[t]):
                self.dependent[t] |= nb.consumers[p]
        self.lonely = 0             # transitions dependent on no other one
        for t in range(nb.ntrans):
            if self.dependent[t] == 1 << t and not visible >> t & 1:
                self.lonely |= 1 << t

    def initial_enabled(self, m: int) -> int:
        en = 0
        for t, pre in enumerate(self.pre):
            if m & pre == pre:
                en |= 1 << t
        return en

    def successor_enabled(self, m2: int, en: int, t: int) -> int:
        en &= ~self.disable[t]
        pre = self.pre
        for u in bits(self.wake[t] & ~en):
            if m2 & pre[u] == pre[u]:
                en |= 1 << u
        return en

    def up_set(self, m: int) -> int:
        up = 0
        pre, producers = self.pre, self.producers
        for p, pbit, makers in self.watched:
            if not m & pbit:
                up |= producers[p]
                continue
            for t in makers:
                missing = pre[t] & ~m
                if missing:     # t disabled (enabled would be an unsafe firing, found first)
                    low = missing & -missing
                    up |= producers[low.bit_length() - 1]
        return up

    def closure(self, m: int, seed: int, en: int, limit: int) -> int | None:
        """The stubborn set grown from ``seed``, or None once it has ``limit`` enabled
        transitions (it cannot beat the best set found so far)."""
        pre, dependent, producers = self.pre, self.dependent, self.producers
        s = seed
        work = seed
        count = (seed & en).bit_count()
        if count >= limit:
            return None
        while work:
            low = work & -work
            work ^= low
            t = low.bit_length() - 1
            missing = pre[t] & ~m
            if not missing:
                add = dependent[t]
                if self.visible >> t & 1:       # V: one enabled visible brings them all
                    add |= self.visible
            else:       # disabled: the scapegoat bringing the fewest new transitions
                add = -1
                best = -1
                while missing:
                    low_q = missing & -missing
                    missing ^= low_q
                    q = low_q.bit_length() - 1
                    for makers in (producers[q], *self._leaving(m, q)):
                        extra = (makers & ~s).bit_count()
                        if best < 0 or extra < best:
                            best, add = extra, makers
                            if extra == 0:
                                break
                    if best == 0:
                        break
            new = add & ~s
            if new:
                s |= new
                work |= new
                count += (new & en).bit_count()
                if count >= limit:
                    return None
        return s

    def _leaving(self, m: int, p: int) -> list[int]:
        """Necessary enabling sets of the unmarked place ``p`` besides its producers: for
        each one-token semiflow holding ``p``, the transitions that empty the place of it
        marked in ``m`` (the token must leave that place before ``p`` can be marked)."""
        flows = self.flows_of[p]
        if not flows:
            return []
        out = []
        for flow in flows:
            here = m & flow
            if here and here & (here - 1) == 0:
                out.append(self.leave[here.bit_length() - 1])
        return out

    def stubborn(self, m: int, en: int) -> int:
        """The enabled transitions of a small stubborn set of ``m`` (``en`` != 0)."""
        if not self.reduce or en & (en - 1) == 0:
            return en
        up = self.up_set(m) if self.watched else 0
        if not up:
            lonely = en & self.lonely
            if lonely:              # enabled and in conflict with nothing: a stubborn set alone
                return lonely & -lonely
        best = en
        best_count = en.bit_count()
        for tried, t in enumerate(bits(en)):
            if tried >= _MAX_SEEDS:
                break
            found = self.closure(m, (1 << t) | up, en, best_count)
            if found is not None:
                best = found & en
                best_count = best.bit_count()
                if best_count == 1:
                    break
        return best

    def explore(
        self,
        max_states: int = 5_000_000,
        time_limit: float | None = None,
        max_counterexamples: int = 3,
        progress: ProgressCallback | None = None,
        keep_graph: bool = False,
        budget: Budget | None = None,
    ) -> SearchResult:
        """``time_limit`` applies only without a ``budget``."""
        proviso = self.proviso and self.reduce
        keep_graph = keep_graph or proviso
        limits = budget if budget is not None else Budget(time_limit)
        clock = _Clock(time.monotonic(), progress, "stubborn" if self.reduce else "python")
        m0 = self.nb.initial
        st = _Search(m0, self.initial_enabled(m0))
        expand = self._expander(st, keep_graph, proviso)
        stopped: str | None = None
        with limits.running("the stubborn-set exploration" if self.reduce
                            else "the explicit exploration"):
            try:
                while True:
                    stopped = self._breadth_first(st, expand, max_states, clock, limits,
                                                  proviso)
                    if stopped is not None or not proviso:
                        break
                    # cycle proviso: every cycle of partly expanded markings gets one
                    # expanded fully
                    if not self._expand_cycles(st, expand, limits):
                        break
            except LimitReached as e:
                stopped = e.stop.message
            except MemoryError:
                stopped = limits.out_of_memory().message
            if stopped is not None:         # free what only the graph needed
                st.e_src, st.e_dst, st.e_trans = [], [], []
                st.index.clear()
            return self._result(st, stopped, keep_graph, max_counterexamples, clock.start,
                                limits)

    def _expander(self, st: _Search, keep_graph: bool, proviso: bool,
                  ) -> Callable[[int, int, int, int], int]:
        """The function that fires a set of transitions in a marking and records what it
        finds in `st` (its lists bound once: it runs for every state)."""
        pre, post = self.pre, self.post
        index, markings, parent, via, depth_of = st.index, st.markings, st.parent, st.via, \
            st.depth_of
        enabled_of, fired_of, queue = st.enabled_of, st.fired_of, st.queue
        e_src, e_dst, e_trans = st.e_src, st.e_dst, st.e_trans
        successor_enabled = self.successor_enabled

        def expand(i: int, m: int, en: int, fire: int) -> int:
            """Fire ``fire`` in marking ``m`` (state ``i``); the number of firings."""
            for t in bits(fire):
                m2 = (m & ~pre[t]) | post[t]
                k = index.get(m2)
                if k is None:
                    k = len(markings)
                    index[m2] = k
                    markings.append(m2)
                    parent.append(i)
                    via.append(t)
                    depth_of.append(depth_of[i] + 1)
                    en2 = successor_enabled(m2, en, t)
                    if proviso:
                        enabled_of.append(en2)
                        fired_of.append(0)
                    queue.append((m2, en2, k))
                if keep_graph:
                    e_src.append(i)
                    e_dst.append(k)
                    e_trans.append(t)
            return fire.bit_count()

        return expand

    def _breadth_first(self, st: _Search, expand: Callable[[int, int, int, int], int],
                       max_states: int, clock: _Clock, budget: Budget,
                       proviso: bool) -> str | None:
        """Explore the queue to its end; why the search stopped early, or None."""
        nb, produce, stubborn = self.nb, self.produce, self.stubborn
        queue, markings, fired_of = st.queue, st.markings, st.fired_of
        count = 0
        while queue:
            m, en, i = queue.popleft()
            count += 1
            if en == 0:
                if nb.is_final(m):
                    st.final_deadlocks += 1
                else:
                    st.deadlocks.append(i)
                continue
            for t in bits(en):
                clash = m & produce[t]
                if clash:
                    st.unsafe = (i, t, clash)
                    return "stopped at the first unsafe firing"
            fire = stubborn(m, en)
            if proviso:
                fired_of[i] = fire
            st.edges += expand(i, m, en, fire)
            if len(markings) > max_states:
                return f"state limit of {max_states} states reached"
            if count & 63 == 0:
                budget.check(len(markings))
                clock.report(st, i)
        return None

    def _expand_cycles(self, st: _Search, expand: Callable[[int, int, int, int], int],
                       budget: Budget) -> bool:
        """Expand fully one marking of each cycle of partly expanded markings; False when
        there is no such cycle (the search is over)."""
        n = len(st.markings)
        breakers = _cycle_breakers(n, st.e_src, st.e_dst,
                                   [st.fired_of[v] != st.enabled_of[v] for v in range(n)],
                                   budget)
        for v in breakers:
            rest = st.enabled_of[v] & ~st.fired_of[v]
            st.fired_of[v] = st.enabled_of[v]
            st.full_expansions += 1
            st.edges += expand(v, st.markings[v], st.enabled_of[v], rest)
        return bool(breakers)

    def _result(self, st: _Search, stopped: str | None, keep_graph: bool,
                max_counterexamples: int, start: float, budget: Budget) -> SearchResult:
        markings = st.markings
        traces = [Trace(st.path(k), markings[k]) for k in st.deadlocks[:max_counterexamples]]
        unsafe_trace = None
        if st.unsafe is not None:
            k, t, clash = st.unsafe
            unsafe_trace = Trace((*st.path(k), t), markings[k], t, clash)
        graph = None
        if keep_graph and stopped is None:
            # a limit reached here leaves the search complete, without its graph
            try:
                graph = _graph(st, self.nb.nwords, budget)
            except LimitReached:
                pass
            except MemoryError:
                budget.out_of_memory()
        return SearchResult(
            method="stubborn" if self.reduce else "python", states=len(markings),
            edges=st.edges,
            depth=max(st.depth_of), complete=stopped is None, stopped=stopped,
            seconds=time.monotonic() - start, deadlocks=traces,
            deadlock_count=len(st.deadlocks), final_deadlock_count=st.final_deadlocks,
            unsafe=unsafe_trace, graph=graph, full_expansions=st.full_expansions,
        )


class _Search:
    """The state of one search: the markings found (state k is ``markings[k]``), how each
    was first reached, what was enabled and fired in each (for the cycle proviso), the
    edges (for the graph and the proviso), the queue and what was found."""

    def __init__(self, m0: int, en0: int) -> None:
        self.index: dict[int, int] = {m0: 0}
        self.markings: list[int] = [m0]
        self.parent: list[int] = [-1]
        self.via: list[int] = [-1]
        self.depth_of: list[int] = [0]
        self.enabled_of: list[int] = [en0]        # kept for the proviso's re-expansions
        self.fired_of: list[int] = [0]
        self.queue: deque[tuple[int, int, int]] = deque([(m0, en0, 0)])
        self.e_src: list[int] = []
        self.e_dst: list[int] = []
        self.e_trans: list[int] = []
        self.edges = 0
        self.full_expansions = 0
        self.deadlocks: list[int] = []
        self.final_deadlocks = 0
        self.unsafe: tuple[int, int, int] | None = None   # (state, transition, places)

    def path(self, k: int) -> tuple[int, ...]:
        steps: list[int] = []
        while k > 0:
            steps.append(self.via[k])
            k = self.parent[k]
        return tuple(reversed(steps))


def _graph(st: _Search, nw: int, budget: Budget) -> Graph:
    """The explored graph as arrays (the markings converted a chunk at a time, the budget
    checked between chunks)."""
    markings = st.markings
    states = np.zeros((len(markings), nw), dtype=np.uint64)
    budget.check(extra=states.nbytes + 12 * len(st.e_src))
    chunk = 1 << 16
    for lo in range(0, len(markings), chunk):
        part = markings[lo:lo + chunk]
        states[lo:lo + len(part)] = np.array([to_words(x, nw) for x in part],
                                             dtype=np.uint64).reshape(len(part), nw)
        budget.check()
    return Graph(states=states, parent=np.array(st.parent, dtype=np.int32),
                 via=np.array(st.via, dtype=np.int32), src=np.array(st.e_src, dtype=np.int32),
                 dst=np.array(st.e_dst, dtype=np.int32),
                 trans=np.array(st.e_trans, dtype=np.int32))


class _Clock:
    """The progress reports of a search."""

    def __init__(self, start: float, progress: ProgressCallback | None, method: str) -> None:
        self.start = start
        self.progress = progress
        self.method = method
        self.last_report = 0.0

    def report(self, st: _Search, i: int) -> None:
        now = time.monotonic()
        if self.progress is not None and now - self.last_report > 0.5:
            self.last_report = now
            self.progress(Progress(len(st.markings), st.edges, st.depth_of[i], len(st.queue),
                                   now - self.start, self.method))


def _cycle_breakers(n: int, src: list[int], dst: list[int], partial: list[bool],
                    budget: Budget | None = None) -> list[int]:
    """Markings that meet every cycle of the subgraph of partly expanded markings (a
    feedback vertex set: the back-edge targets of a depth-first search of each cyclic
    strongly connected component, and the markings with a self-loop)."""
    succ: list[list[int]] = [[] for _ in range(n)]
    selfloop = [False] * n
    for k, (a, b) in enumerate(zip(src, dst, strict=True)):
        if partial[a] and partial[b]:
            if a == b:
                selfloop[a] = True
            else:
                succ[a].append(b)
        if budget is not None and k & 0xFFFF == 0:
            budget.check()
    comp, ncomp = components(succ, budget.check if budget is not None else None)
    lowest = [n] * ncomp
    size = [0] * ncomp
    for v in range(n):
        c = comp[v]
        size[c] += 1
        lowest[c] = min(lowest[c], v)
    # a depth-first search of each cyclic component from its lowest marking: the targets of
    # its back edges meet every cycle of the component (and the self-loops theirs), so one
    # round breaks them all instead of one per component
    breakers = {v for v in range(n) if selfloop[v]}
    state = [0] * n             # 0 not seen, 1 on the stack, 2 done
    for c in range(ncomp):
        root = lowest[c]
        if size[c] < 2 or state[root]:
            continue
        state[root] = 1
        stack = [(root, iter(succ[root]))]
        while stack:
            v, edges = stack[-1]
            for w in edges:
                if comp[w] != c:
                    continue
                if state[w] == 1:
                    breakers.add(w)
                elif state[w] == 0:
                    state[w] = 1
                    stack.append((w, iter(succ[w])))
                    break
            else:
                state[v] = 2
                stack.pop()
    return sorted(breakers)


def explore_reduced(
    net_bits: NetBits,
    safe_places: int = 0,
    max_states: int = 5_000_000,
    time_limit: float | None = None,
    max_counterexamples: int = 3,
    progress: ProgressCallback | None = None,
    reduce: bool = True,
    for_progress: bool = False,
    budget: Budget | None = None,
    visible: int = 0,
    semiflows: Sequence[int] = (),
) -> SearchResult:
    """Deadlocks and safeness by stubborn-set search (see the module docstring).

    ``safe_places`` is the mask of places already proved safe (by place invariants). With
    ``for_progress`` the cycle proviso is applied and the reduced graph is kept, for the
    progress check (``progress.check_progress`` runs on it unchanged). ``visible``: the
    transitions that can change the atoms of a state property (the V condition; use it with
    ``for_progress`` for the proviso).
    """
    explorer = StubbornExplorer(net_bits, safe_places, reduce, proviso=for_progress,
                                visible=visible, semiflows=semiflows)
    return explorer.explore(max_states, time_limit, max_counterexamples, progress,
                            keep_graph=for_progress, budget=budget)
