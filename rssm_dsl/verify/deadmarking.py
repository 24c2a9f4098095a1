"""Deadlock freedom from the place invariants alone: no marking that the one-token semiflows
allow is dead.

Every reachable marking ``m`` of a net whose places are all covered by one-token 0/1
semiflows (``cover.one_token_semiflows``: sets ``F`` of places with exactly one marked in
the initial marking, and every transition taking from ``F`` as many tokens as it puts into
it) marks exactly one place of each semiflow. A reachable deadlock is a marking that is not
final (``m`` does not hold every place of ``net.final``) and enables no transition (every
transition has an unmarked input place). So when *no* marking at all has those properties,
the net has no reachable deadlock, whatever its state space: this module looks for such a
marking, by search over the semiflows.

It is a relaxation: a marking it finds may not be reachable (``Found``: nothing is decided),
and none found proves deadlock freedom (``Proved``). It decides systems whose blocking waits
cannot close a cycle, which no exploration can reach at scale: a coordinator that waits,
blocking, for the acknowledgement of each of seven robots, each robot waiting, blocking,
until its acknowledgement is taken. A robot can wait only while its channel is full, the
coordinator only while that channel is empty: no marking has both, and every other place of
theirs enables a step of their own.

The search is a Boolean satisfiability search with one variable per place ("marked"):

* exactly one place of each semiflow is marked;
* for each transition, some input place is unmarked (dead);
* some place of ``net.final`` is unmarked (not final; no clause when the net has no final
  marking);

by depth-first search with unit propagation, branching on the semiflow with the fewest
places still possible, its places tried in turn. It stops after ``max_nodes`` branchings or
when the budget says so (``Undecided``).
"""

from __future__ import annotations

import contextlib
from collections.abc import Sequence

from rssm_core.records import dataclass
from rssm_dsl.verify.budget import Budget
from rssm_dsl.verify.netbits import NetBits, bits

MAX_NODES = 20_000        # about a second; the relaxation decides quickly or not at all


@dataclass(frozen=True)
class DeadMarkings:
    """``proved``: no marking the semiflows allow is dead (the net is deadlock-free);
    ``found``: such a marking (a set of places; perhaps unreachable); neither: undecided
    (``why``)."""

    proved: bool
    found: frozenset[int] | None
    nodes: int
    why: str = ""


class _Conflict(Exception):
    pass


class _Search:
    def __init__(self, nb: NetBits, flows: Sequence[int], empty: int) -> None:
        self.nb = nb
        self.empty = empty
        self.flows = list(flows)
        self.flows_of: list[list[int]] = [[] for _ in range(nb.nplaces)]
        for i, f in enumerate(self.flows):
            for p in bits(f):
                self.flows_of[p].append(i)
        self.pre = nb.pre
        self.needs: list[list[int]] = [[] for _ in range(nb.nplaces)]  # p -> t with p in pre
        for t, pre in enumerate(nb.pre):
            for p in bits(pre):
                self.needs[p].append(t)
        # branch first on the semiflows with the most places (a subsystem's control flow:
        # choosing where it stands decides the channels it waits on), then the smallest
        self.weight = [f.bit_count() for f in self.flows]
        self.final = nb.final
        self.nodes = 0

    def propagate(self, on: int, off: int, todo: list[tuple[int, bool]]) -> tuple[int, int]:
        """``on``/``off``: places marked/unmarked so far; ``todo``: decisions to apply.
        Raises _Conflict."""
        while todo:
            p, marked = todo.pop()
            bit = 1 << p
            if (on if marked else off) & bit:
                continue
            if (off if marked else on) & bit:
                raise _Conflict
            if marked:
                on, off = self._mark(p, on, off, todo)
            else:
                off |= bit
                todo.extend(self._after_off(p, on, off))
        return on, off

    def _mark(self, p: int, on: int, off: int,
              todo: list[tuple[int, bool]]) -> tuple[int, int]:
        """``p`` marked: the other places of its semiflows unmarked, and each transition
        needing ``p`` keeps an unmarked input (the last one left is unmarked)."""
        bit = 1 << p
        on |= bit
        for f in self.flows_of[p]:
            others = self.flows[f] & ~bit
            if others & on:
                raise _Conflict
            new_off = others & ~off
            off |= new_off
            for q in bits(new_off):
                todo.extend(self._after_off(q, on, off))
        clauses = [self.pre[t] for t in self.needs[p]]
        if self.final and self.final >> p & 1:
            clauses.append(self.final)
        for places in clauses:
            open_ = places & ~on
            if not open_:
                raise _Conflict            # a transition enabled, or the final marking
            if not open_ & off and open_ & (open_ - 1) == 0:
                todo.append((open_.bit_length() - 1, False))
        return on, off

    def _after_off(self, p: int, on: int, off: int) -> list[tuple[int, bool]]:
        """What unmarking ``p`` forces: the last possible place of one of its semiflows."""
        out: list[tuple[int, bool]] = []
        for f in self.flows_of[p]:
            flow = self.flows[f]
            if flow & on:
                continue
            left = flow & ~off
            if not left:
                raise _Conflict
            if left & (left - 1) == 0:
                out.append((left.bit_length() - 1, True))
        return out

    def solve(self, budget: Budget | None, max_nodes: int) -> DeadMarkings:
        try:
            on, off = self.propagate(0, 0, self._units())
        except _Conflict:
            return DeadMarkings(True, None, 0)
        stack: list[tuple[int, int]] = [(on, off)]
        while stack:
            on, off = stack.pop()
            self.nodes += 1
            if self.nodes > max_nodes:
                return DeadMarkings(False, None, self.nodes,
                                    f"{max_nodes:,} branchings without an answer")
            if budget is not None and self.nodes & 255 == 0:
                budget.check()
            flow = self._branch(on, off)
            if flow is None:
                if self._dead(on):
                    return DeadMarkings(False, frozenset(bits(on)), self.nodes)
                continue
            for p in reversed(bits(self.flows[flow] & ~off)):
                with contextlib.suppress(_Conflict):
                    stack.append(self.propagate(on, off, [(p, True)]))
        return DeadMarkings(True, None, self.nodes)

    def _units(self) -> list[tuple[int, bool]]:
        """The transitions with one input place: that place is unmarked."""
        out = [(pre.bit_length() - 1, False) for pre in self.pre if pre & (pre - 1) == 0
               and pre]
        out += [(p, False) for p in bits(self.empty)]
        if any(not pre for pre in self.pre):
            raise _Conflict                        # a transition always enabled
        return out

    def _branch(self, on: int, off: int) -> int | None:
        """The semiflow with no marked place and the fewest possible ones (None: every
        semiflow has its place)."""
        best, best_key = None, (0, 0)
        for i, f in enumerate(self.flows):
            if f & on:
                continue
            n = (f & ~off).bit_count()
            if n <= 1:
                return i
            key = (-self.weight[i], n)
            if best is None or key < best_key:
                best, best_key = i, key
        return best

    def _dead(self, on: int) -> bool:
        return (all(pre & ~on for pre in self.pre)
                and (not self.final or bool(self.final & ~on)))


def dead_markings(nb: NetBits, flows: Sequence[int], empty: int = 0,
                  budget: Budget | None = None, max_nodes: int = MAX_NODES) -> DeadMarkings:
    """Look for a non-final dead marking that marks exactly one place of each of the
    one-token semiflows ``flows`` (place masks) and none of ``empty`` (the places of
    semiflows without a token: never marked). Together they must cover every place of the
    net (else nothing is decided)."""
    covered = empty
    for f in flows:
        covered |= f
    if covered != (1 << nb.nplaces) - 1:
        return DeadMarkings(False, None, 0, "the semiflows do not cover every place")
    return _Search(nb, flows, empty).solve(budget, max_nodes)
