"""Full state-space exploration: breadth first, a whole BFS level at a time, in numpy.

Markings are bitsets split into 64-bit words (``NetBits``). For every level of the BFS the
enabled matrix (frontier states x transitions) is computed in one vectorised expression, the
successors of all enabled pairs are formed at once and looked up in (or added to) a hash table
of visited markings that is itself driven by whole arrays (``_Table``): no Python code runs per
state. Because whole levels are expanded in order, the parent pointers give shortest
counterexamples.

Found on the way: deadlocks (a state with nothing enabled, final or not; the caller decides),
the first unsafe firing (a transition that would put a second token into a marked place; the
exploration stops there, because the bitset semantics ends at the first unsafe marking), the
transitions enabled somewhere, the places marked somewhere, and optionally the reachability
graph (edges ``src -> dst`` labelled with the transition) for the progress check.

Limits: ``max_states`` and the run's ``budget`` (deadline, memory, Ctrl-C; ``budget.py``) or,
without one, ``time_limit`` stop the search with ``complete = False`` and a reason. The budget
is checked after every block of a level, and before every batch insertion with the memory
that insertion will take. ``progress`` is called after every level.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import field

import numpy as np
import numpy.typing as npt

from rssm_core.records import dataclass
from rssm_dsl.verify.budget import Budget, LimitReached
from rssm_dsl.verify.netbits import NetBits, from_words, to_words

I64 = npt.NDArray[np.int64]
I32 = npt.NDArray[np.int32]
Ints = npt.NDArray[np.int32] | npt.NDArray[np.int64]
U64 = npt.NDArray[np.uint64]
Bools = npt.NDArray[np.bool_]

_CELLS = 1 << 22          # frontier rows x transitions x words per enabled-matrix block


@dataclass(frozen=True, slots=True)
class Progress:
    """What a long run reports after each BFS level."""

    states: int
    edges: int
    depth: int
    frontier: int
    seconds: float
    method: str


ProgressCallback = Callable[[Progress], None]


@dataclass(frozen=True, slots=True)
class Trace:
    """A firing sequence from the initial marking (transition indices) and where it ends."""

    steps: tuple[int, ...]
    marking: int                    # the marking reached after the steps
    transition: int | None = None   # for an unsafe firing: the transition that would double-mark
    places: int = 0                 # for an unsafe firing: the places it would double-mark


@dataclass
class Graph:
    """The reachability graph: states in BFS order (0 is the initial marking), labelled edges."""

    states: U64                     # (nstates, nwords)
    parent: I32                     # BFS tree: parent state, -1 for the root
    via: I32                        # BFS tree: transition from the parent, -1 for the root
    src: I32                        # edges (int32 to halve the memory of large graphs)
    dst: I32
    trans: I32
    _fwd: tuple[I64, Ints] | None = field(default=None, repr=False)
    _bwd: tuple[I64, Ints] | None = field(default=None, repr=False)

    @property
    def size(self) -> int:
        return int(self.states.shape[0])

    def marking(self, state: int) -> int:
        return from_words([int(w) for w in self.states[state]])

    def path(self, state: int) -> tuple[int, ...]:
        steps: list[int] = []
        while state > 0:
            steps.append(int(self.via[state]))
            state = int(self.parent[state])
        return tuple(reversed(steps))

    def forward(self) -> tuple[I64, Ints]:
        """CSR of the edges by source: (row pointers, edge ids)."""
        if self._fwd is None:
            ptr = np.zeros(self.size + 1, dtype=np.int64)
            np.cumsum(np.bincount(self.src, minlength=self.size), out=ptr[1:])
            order: Ints
            if self.src.size < 2 or bool((self.src[1:] >= self.src[:-1]).all()):
                order = np.arange(self.src.size, dtype=np.int64)   # BFS order: already sorted
            else:
                order = np.argsort(self.src, kind="stable").astype(np.int32)
            self._fwd = (ptr, order)
        return self._fwd

    def backward(self) -> tuple[I64, Ints]:
        """CSR of the edges by target."""
        if self._bwd is None:
            order: I32 = np.argsort(self.dst).astype(np.int32)
            ptr = np.zeros(self.size + 1, dtype=np.int64)
            np.cumsum(np.bincount(self.dst, minlength=self.size), out=ptr[1:])
            self._bwd = (ptr, order)
        return self._bwd


def gather(ptr: I64, order: Ints, nodes: Ints) -> Ints:
    """The edge ids of the CSR rows ``nodes``, concatenated."""
    starts = ptr[nodes]
    counts = ptr[nodes + 1] - starts
    total = int(counts.sum())
    if total == 0:
        return np.zeros(0, dtype=np.int64)
    shift = np.repeat(starts - np.cumsum(counts) + counts, counts)
    out: Ints = order[shift + np.arange(total, dtype=np.int64)]
    return out


@dataclass
class SearchResult:
    """What an exploration found. Shared by the full and the reduced explorer."""

    method: str                      # "full" or "stubborn"
    states: int
    edges: int
    depth: int
    complete: bool                   # False: stopped by a limit or at an unsafe firing
    stopped: str | None              # why it stopped early
    seconds: float
    deadlocks: list[Trace]           # the first few, shortest first
    deadlock_count: int
    final_deadlock_count: int        # deadlocks in a final marking (the system finished)
    unsafe: Trace | None
    fired: frozenset[int] | None = None   # transitions enabled in some state (full only)
    ever_marked: int | None = None        # places marked in some state (full only)
    graph: Graph | None = None
    full_expansions: int = 0              # stubborn search: markings expanded fully (proviso)


def explore_full(
    bits: NetBits,
    max_states: int = 5_000_000,
    time_limit: float | None = None,
    keep_graph: bool = True,
    max_counterexamples: int = 3,
    progress: ProgressCallback | None = None,
    budget: Budget | None = None,
) -> SearchResult:
    """Every reachable marking, breadth first (see the module docstring). ``time_limit``
    applies only without a ``budget``."""
    start = time.monotonic()
    limits = budget if budget is not None else Budget(time_limit)
    nw, nt = bits.nwords, bits.ntrans
    kernel = _Kernel(bits)
    init = np.array([to_words(bits.initial, nw)], dtype=np.uint64)
    visited = _Table(nw)
    visited.lookup_insert(kernel.keys(init), init)
    level_parent: list[I32] = [np.array([-1], dtype=np.int32)]
    level_via: list[I32] = [np.array([-1], dtype=np.int32)]
    edges: tuple[list[I32], list[I32], list[I32]] = ([], [], [])
    dead_states: list[I64] = []
    fired = np.zeros(nt, dtype=np.bool_)
    frontier, base, depth, nedges = init, 0, 0, 0
    stopped: str | None = None
    unsafe_at: tuple[int, int, int] | None = None     # (state, transition, places)
    block = max(1, _CELLS // max(1, nt))

    with limits.running("the full exploration"):
        try:
            while frontier.shape[0]:
                limits.check(visited.size)
                level = _expand(kernel, frontier, base, block, limits, dead_states)
                if level.unsafe_at is not None:
                    unsafe_at = level.unsafe_at
                    break
                src, trans = level.src, level.trans
                fired[trans] = True
                nedges += int(src.shape[0])
                base += frontier.shape[0]
                if src.shape[0] == 0:
                    frontier = np.zeros((0, nw), np.uint64)
                    continue
                ids, new_pos = _insert(visited, kernel, level.succ, limits,
                                       12 * src.shape[0] if keep_graph else 0)
                if keep_graph:
                    edges[0].append(src.astype(np.int32))
                    edges[2].append(trans.astype(np.int32))
                    edges[1].append(ids.astype(np.int32))
                frontier = visited.store[visited.size - new_pos.size:visited.size]
                if new_pos.size:
                    depth += 1                      # the BFS depth of the deepest state so far
                level_parent.append(src[new_pos].astype(np.int32))
                level_via.append(trans[new_pos].astype(np.int32))
                if progress is not None:
                    progress(Progress(visited.size, nedges, depth, frontier.shape[0],
                                      time.monotonic() - start, "full"))
                if visited.size > max_states:
                    stopped = f"state limit of {max_states} states reached"
                    break
        except LimitReached as e:
            stopped = e.stop.message
        except MemoryError:
            stopped = limits.out_of_memory().message
        if stopped is not None:             # free the graph's edges at once
            edges = ([], [], [])

    return _full_result(bits, visited, level_parent, level_via, edges,
                        dead_states, fired, unsafe_at, stopped, nedges, depth, start,
                        keep_graph, max_counterexamples)


@dataclass
class _Level:
    """The successors of one BFS level, in parts (or the unsafe firing that stopped its
    expansion)."""

    succ: list[U64]
    src: I64
    trans: I64
    unsafe_at: tuple[int, int, int] | None = None


_BATCH = 1 << 18          # successors looked up in the visited table at once


def _insert(visited: _Table, kernel: _Kernel, parts: list[U64], budget: Budget,
            graph_bytes: int) -> tuple[I64, I64]:
    """Look up (and add) the successors of a level, a batch at a time, the budget checked
    before each batch with the memory it will take: (id per successor, positions of the new
    ones in id order)."""
    ids_parts: list[I64] = []
    new_parts: list[I64] = []
    offset = 0
    k = 0
    while k < len(parts):
        group = [parts[k]]
        size = parts[k].shape[0]
        k += 1
        while k < len(parts) and size + parts[k].shape[0] <= _BATCH:
            group.append(parts[k])
            size += parts[k].shape[0]
            k += 1
        batch = group[0] if len(group) == 1 else np.concatenate(group)
        budget.check(visited.size, extra=visited.growth(size) + batch.nbytes + graph_bytes)
        ids, new = visited.lookup_insert(kernel.keys(batch), batch)
        ids_parts.append(ids)
        new_parts.append(new + offset)
        offset += size
    if len(ids_parts) == 1:
        return ids_parts[0], new_parts[0]
    return np.concatenate(ids_parts), np.concatenate(new_parts)


def _expand(kernel: _Kernel, frontier: U64, base: int, block: int, budget: Budget,
            dead_states: list[I64]) -> _Level:
    """Fire every enabled transition of every state of ``frontier`` (numbered from
    ``base``), in blocks; dead states are added to ``dead_states``. The budget is checked
    after every block, with the memory the level's successors take."""
    succ_parts: list[U64] = []
    src_parts: list[I64] = []
    t_parts: list[I64] = []
    empty = _Level([], np.zeros(0, np.int64), np.zeros(0, np.int64))
    held = 0
    for lo in range(0, frontier.shape[0], block):
        f = frontier[lo:lo + block]
        si, ti = np.nonzero(kernel.enabled(f))
        outdeg = np.bincount(si, minlength=f.shape[0])
        if not outdeg.all():
            dead_states.append(np.flatnonzero(outdeg == 0).astype(np.int64) + base + lo)
        succ, clash = kernel.fire(f, si, ti)
        if clash is not None:
            k = int(np.flatnonzero(clash)[0])
            empty.unsafe_at = (base + lo + int(si[k]), int(kernel.perm[ti[k]]),
                               kernel.clash_places(f[si[k]], int(ti[k])))
            return empty
        succ_parts.append(succ)
        src_parts.append(si.astype(np.int64) + base + lo)
        t_parts.append(kernel.perm[ti])
        held += 16 * si.shape[0]
        budget.check(extra=held)          # joining src and trans takes as much again
    if not succ_parts:
        return empty
    return _Level(succ_parts, np.concatenate(src_parts), np.concatenate(t_parts))


def _full_result(bits: NetBits, visited: _Table, level_parent: list[I32], level_via: list[I32],
                 edges: tuple[list[I32], list[I32], list[I32]], dead_states: list[I64],
                 fired: npt.NDArray[np.bool_], unsafe_at: tuple[int, int, int] | None,
                 stopped: str | None, nedges: int, depth: int, start: float,
                 keep_graph: bool, max_counterexamples: int) -> SearchResult:
    """The search result of a finished (or stopped) full exploration."""
    e_src, e_dst, e_trans = edges
    states = visited.store[:visited.size]
    parent = np.concatenate(level_parent)
    via = np.concatenate(level_via)
    z = np.zeros(0, dtype=np.int32)
    graph = Graph(
        states=states, parent=parent, via=via,
        src=np.concatenate(e_src) if e_src else z,
        dst=np.concatenate(e_dst) if e_dst else z,
        trans=np.concatenate(e_trans) if e_trans else z,
    )
    dead = np.concatenate(dead_states) if dead_states else np.zeros(0, dtype=np.int64)
    final = np.zeros(dead.shape[0], dtype=np.bool_)
    if bits.final and dead.size:
        words = np.array(to_words(bits.final, bits.nwords), dtype=np.uint64)
        final = ((states[dead] & words) == words).all(axis=1)
    final_count = int(final.sum())
    deadlocks = [Trace(graph.path(s), graph.marking(s))
                 for s in dead[~final][:max_counterexamples].tolist()]
    unsafe = None
    if unsafe_at is not None:
        s, t, places = unsafe_at
        unsafe = Trace((*graph.path(s), t), graph.marking(s), t, places)
        stopped = "stopped at the first unsafe firing"
    ever = 0
    if states.shape[0]:
        ever = from_words([int(x) for x in np.bitwise_or.reduce(states, axis=0)])
    return SearchResult(
        method="full", states=int(states.shape[0]), edges=nedges, depth=depth,
        complete=stopped is None, stopped=stopped, seconds=time.monotonic() - start,
        deadlocks=deadlocks, deadlock_count=int(dead.shape[0]) - final_count,
        final_deadlock_count=final_count, unsafe=unsafe,
        fired=frozenset(np.flatnonzero(fired).tolist()), ever_marked=ever,
        graph=graph if keep_graph and stopped is None else None,
    )




_MIX = np.array([0x9E3779B97F4A7C15, 0xC2B2AE3D27D4EB4F, 0x165667B19E3779F9,
                 0xD6E8FEB86659FD93, 0xFF51AFD7ED558CCD, 0xC4CEB9FE1A85EC53],
                dtype=np.uint64)


class _Kernel:
    """The vectorised enabled test and firing rule of one net.

    Transitions are permuted so that those whose pre-set lies in one 64-bit word form a
    contiguous block per word: for them the enabled test reads one word instead of all.
    """

    def __init__(self, bits: NetBits) -> None:
        nw = bits.nwords
        self.nw = nw
        home = []
        for t in range(bits.ntrans):
            words = {p // 64 for p in bits.net.transitions[t].pre}
            home.append(words.pop() if len(words) == 1 else (0 if not words else nw))
        self.perm: I64 = np.array(sorted(range(bits.ntrans), key=lambda t: (home[t], t)),
                                  dtype=np.int64)
        self.pre: U64 = np.ascontiguousarray(bits.pre_words[self.perm])
        self.post: U64 = np.ascontiguousarray(bits.post_words[self.perm])
        self.notpre: U64 = ~self.pre
        self.groups: list[tuple[int, int, int]] = []      # (word or nw for several, lo, hi)
        lo = 0
        sorted_home = [home[int(t)] for t in self.perm]
        while lo < len(sorted_home):
            hi = lo
            while hi < len(sorted_home) and sorted_home[hi] == sorted_home[lo]:
                hi += 1
            self.groups.append((sorted_home[lo], lo, hi))
            lo = hi
        self.mix = _MIX[:nw] if nw <= len(_MIX) else np.resize(_MIX, nw) | np.uint64(1)

    def enabled(self, f: U64) -> Bools:
        """(states x permuted transitions): enabled?"""
        nf = ~f
        k = f.shape[0]
        if len(self.groups) == 1 and self.groups[0][0] < self.nw:
            w = self.groups[0][0]
            out: Bools = (nf[:, w, None] & self.pre[None, :, w]) == 0
            return out
        en = np.empty((k, self.pre.shape[0]), dtype=np.bool_)
        for w, lo, hi in self.groups:
            if w < self.nw:
                en[:, lo:hi] = (nf[:, w, None] & self.pre[None, lo:hi, w]) == 0
            else:
                acc = nf[:, 0, None] & self.pre[None, lo:hi, 0]
                for v in range(1, self.nw):
                    acc |= nf[:, v, None] & self.pre[None, lo:hi, v]
                en[:, lo:hi] = acc == 0
        return en

    def fire(self, f: U64, si: I64, ti: I64) -> tuple[U64, Bools | None]:
        """Successor markings, and the unsafe-firing mask when some firing is unsafe."""
        rest = f[si] & self.notpre[ti]
        post = self.post[ti]
        clash = (rest[:, 0] & post[:, 0]) != 0
        for v in range(1, self.nw):
            clash |= (rest[:, v] & post[:, v]) != 0
        rest |= post
        return rest, (clash if clash.any() else None)

    def clash_places(self, marking: U64, t: int) -> int:
        rest = marking & self.notpre[t]
        return from_words([int(x) for x in rest & self.post[t]])

    def keys(self, succ: U64) -> U64:
        """One uint64 per marking: the marking itself for one word, else a hash."""
        if self.nw == 1:
            first: U64 = np.ascontiguousarray(succ[:, 0])
            return first
        h: U64 = succ[:, 0] * self.mix[0]
        for v in range(1, self.nw):
            h ^= (succ[:, v] * self.mix[v]) + (h >> np.uint64(29))
        return h


class _Table:
    """The visited markings: an open-addressing hash table driven by whole arrays.

    ``slots`` holds state ids (-1 = free); the markings themselves are in ``store`` by id, so a
    probe compares the candidate marking with the stored one (exact, whatever the hash).
    ``lookup_insert`` handles a batch of candidate markings (duplicates allowed) in rounds: a
    candidate at a free slot claims it (one winner per slot, the others look again), at an
    equal marking it is found, at another marking it moves to the next slot (linear probing).
    The table doubles when half full.
    """

    def __init__(self, nw: int, capacity: int = 1 << 12) -> None:
        self.nw = nw
        self.size = 0
        self.slots: I32 = np.full(capacity, -1, dtype=np.int32)
        self.owner: I32 = np.zeros(capacity, dtype=np.int32)
        self.store: U64 = np.zeros((1024, nw), dtype=np.uint64)
        self.hashes: U64 = np.zeros(1024, dtype=np.uint64)

    def growth(self, n: int) -> int:
        """Bytes ``lookup_insert`` of ``n`` candidates may allocate (a larger table, a
        larger store, its working arrays)."""
        extra = 48 * n
        if 2 * (self.size + n) > self.slots.shape[0]:
            cap = self.slots.shape[0]
            while 2 * (self.size + n) > cap:
                cap *= 2
            extra += 8 * cap + 24 * self.size
        if self.size + n > self.store.shape[0]:
            extra += 8 * (self.nw + 1) * max(self.size + n, 2 * self.store.shape[0])
        return extra

    def _grow_store(self, need: int) -> None:
        if need <= self.store.shape[0]:
            return
        cap = max(need, 2 * self.store.shape[0])
        store = np.zeros((cap, self.nw), dtype=np.uint64)
        store[:self.size] = self.store[:self.size]
        hashes = np.zeros(cap, dtype=np.uint64)
        hashes[:self.size] = self.hashes[:self.size]
        self.store, self.hashes = store, hashes

    def _rehash(self, capacity: int) -> None:
        self.slots = np.full(capacity, -1, dtype=np.int32)
        self.owner = np.zeros(capacity, dtype=np.int32)
        ids = np.arange(self.size, dtype=np.int64)
        slot = self._slot(self.hashes[:self.size])
        while ids.size:                       # all distinct: claim free slots, probe on
            free = self.slots[slot] < 0
            cand, at = ids[free], slot[free]
            self.owner[at] = cand
            won = self.owner[at] == cand
            self.slots[at[won]] = cand[won]
            placed = np.zeros(ids.size, dtype=np.bool_)
            placed[np.flatnonzero(free)[won]] = True
            ids, slot = ids[~placed], slot[~placed]
            moved = self.slots[slot] >= 0
            slot[moved] = (slot[moved] + 1) & (self.slots.shape[0] - 1)

    def _slot(self, hashes: U64) -> I64:
        shift = np.uint64(64 - (self.slots.shape[0].bit_length() - 1))
        mixed = (hashes * np.uint64(0x9E3779B97F4A7C15)) >> shift
        return mixed.astype(np.int64)

    def lookup_insert(self, hashes: U64, rows: U64) -> tuple[I64, I64]:
        """State ids of the candidate markings ``rows``; new ones are added.

        Returns (id per candidate, candidate positions of the new markings in id order).
        """
        n = rows.shape[0]
        if 2 * (self.size + n) > self.slots.shape[0]:
            cap = self.slots.shape[0]
            while 2 * (self.size + n) > cap:
                cap *= 2
            self._rehash(cap)
        self._grow_store(self.size + n)
        mask = self.slots.shape[0] - 1
        ids = np.full(n, -1, dtype=np.int64)
        active = np.arange(n, dtype=np.int64)
        slot = self._slot(hashes)
        winners: list[I64] = []
        slots, owner, store = self.slots, self.owner, self.store
        while active.size:
            at = slot[active]
            held = slots[at]
            free = held < 0
            if free.any():
                cand, cat = active[free], at[free]
                owner[cat[::-1]] = cand[::-1]        # the first candidate wins a slot
                won = owner[cat] == cand
                new = cand[won]
                new_ids = np.arange(self.size, self.size + new.size, dtype=np.int64)
                slots[cat[won]] = new_ids
                store[new_ids] = rows[new]
                self.hashes[new_ids] = hashes[new]
                ids[new] = new_ids
                self.size += new.size
                winners.append(new)
                held = slots[at]                 # the losers now see the winner
            same = (store[held, 0] == rows[active, 0])
            for v in range(1, self.nw):
                same &= store[held, v] == rows[active, v]
            hit = same & (ids[active] < 0)
            ids[active[hit]] = held[hit]
            done = same
            rest = active[~done]
            slot[rest] = (slot[rest] + 1) & mask
            active = rest
        order = np.concatenate(winners) if winners else np.zeros(0, dtype=np.int64)
        return ids, order
