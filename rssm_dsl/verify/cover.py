"""Safeness proofs when the minimal P-semiflows are too many to enumerate: one-token semiflows
found by search.

The Farkas algorithm (``invariants``) enumerates *every* minimal semiflow; a net with many
parallel blocks behind choices has exponentially many, and the enumeration stops at its row
limit with part of the places unproved. To prove a place ``p`` safe, one semiflow is enough:
a set of places ``Y`` containing ``p`` with, for every transition ``t``,

    |consume(t) ∩ Y| == |produce(t) ∩ Y|        (test arcs count on neither side)

and at most one place of ``Y`` initially marked. Its indicator vector ``y`` is a P-semiflow
(``y . C = 0``) carrying ``y . m0 <= 1`` token, so every place of ``Y`` holds at most one token
in every reachable marking (none at all when ``y . m0 == 0``).

``Y`` is found by depth-first search with backtracking, starting from ``{p}``: while some
transition is unbalanced, take the one with the fewest ways to balance it and add, in turn,
each place of the short side not yet in ``Y`` (places of the same subsystem first). A set
violating the token bound or a transition that cannot be balanced any more is a dead end. The
search per place is bounded by a number of choice points; every place of a set found is proved
at once, so most places cost nothing.
"""

from __future__ import annotations

import sys
from collections.abc import Callable, Iterable

from rssm_dsl.hpn.flat import FlatNet
from rssm_dsl.verify.invariants import Invariant

MAX_CHOICES = 4_000          # choice points tried per place before giving up on it
MAX_SUPPORT = 3_000          # places in one semiflow at most (the search recurses per place)


def one_token_semiflows(net: FlatNet, places: Iterable[int],
                        stop: Callable[[], bool] = lambda: False,
                        max_choices: int = MAX_CHOICES) -> list[Invariant]:
    """One-token 0/1 semiflows covering as many of ``places`` as the search finds (each
    place is tried unless an earlier semiflow already covers it). ``stop`` is polled between
    places and every few hundred choice points."""
    search = _Search(net, max_choices, stop)
    found: list[Invariant] = []
    covered: set[int] = set()
    for p in places:
        if p in covered:
            continue
        if stop():
            break
        ys = search.from_place(p)
        if ys is None:
            continue
        covered.update(ys)
        tokens = sum(1 for q in ys if q in net.initial)
        found.append(Invariant(tuple((q, 1) for q in sorted(ys)), tokens))
    return found


class _Search:
    def __init__(self, net: FlatNet, max_choices: int, stop: Callable[[], bool]) -> None:
        rule = net.rule
        self.consume = [frozenset(c) for c in rule.consume]
        self.produce = [frozenset(p) for p in rule.produce]
        n = len(net.places)
        self.takers: list[list[int]] = [[] for _ in range(n)]    # t with p in consume(t)
        self.makers: list[list[int]] = [[] for _ in range(n)]    # t with p in produce(t)
        for t, ps in enumerate(self.consume):
            for p in ps:
                self.takers[p].append(t)
        for t, ps in enumerate(self.produce):
            for p in ps:
                self.makers[p].append(t)
        self.marked = [p in net.initial for p in range(n)]
        self.owner = [pl.subsystem for pl in net.places]
        self.max_choices = max_choices
        self.stop = stop

    def from_place(self, p0: int) -> set[int] | None:
        """A one-token semiflow's support containing ``p0``, or None."""
        self.ys: set[int] = set()
        self.balance: dict[int, int] = {}   # t -> |consume ∩ Y| - |produce ∩ Y|, if not 0
        self.tokens = 0
        self.choices = 0
        self.home = self.owner[p0]
        self._add(p0)
        limit = sys.getrecursionlimit()
        sys.setrecursionlimit(max(limit, 2 * MAX_SUPPORT + 200))
        try:
            return set(self.ys) if self._solve() else None
        except _GiveUp:
            return None
        finally:
            sys.setrecursionlimit(limit)

    def _add(self, p: int) -> None:
        self.ys.add(p)
        self.tokens += self.marked[p]
        bal = self.balance
        for t in self.takers[p]:
            v = bal.get(t, 0) + 1
            if v:
                bal[t] = v
            else:
                del bal[t]
        for t in self.makers[p]:
            v = bal.get(t, 0) - 1
            if v:
                bal[t] = v
            else:
                del bal[t]

    def _remove(self, p: int) -> None:
        self.ys.discard(p)
        self.tokens -= self.marked[p]
        bal = self.balance
        for t in self.takers[p]:
            v = bal.get(t, 0) - 1
            if v:
                bal[t] = v
            else:
                del bal[t]
        for t in self.makers[p]:
            v = bal.get(t, 0) + 1
            if v:
                bal[t] = v
            else:
                del bal[t]

    def _options(self, t: int) -> list[int]:
        side = self.produce[t] if self.balance[t] > 0 else self.consume[t]
        return [q for q in side if q not in self.ys]

    def _solve(self) -> bool:
        if self.tokens > 1:
            return False
        if len(self.ys) > MAX_SUPPORT:
            raise _GiveUp
        if not self.balance:
            return True
        # the most constrained unbalanced transition
        best: list[int] | None = None
        for t in self.balance:
            opts = self._options(t)
            if best is None or len(opts) < len(best):
                best = opts
                if len(best) <= 1:
                    break
        assert best is not None
        if not best:
            return False
        home = self.home
        best.sort(key=lambda q: (self.owner[q] != home, self.marked[q], q))
        for q in best:
            self.choices += 1
            if self.choices > self.max_choices or (self.choices & 255 == 0 and self.stop()):
                raise _GiveUp
            self._add(q)
            if self._solve():
                return True
            self._remove(q)
        return False


class _GiveUp(Exception):
    pass
