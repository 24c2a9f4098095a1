"""Groups that stall together: progress from deadlock freedom.

A control subsystem of a ring receives, blocking, what its predecessor sends, once per
iteration. If one of them stops iterating, its successor gets at most one more message and
stops too, and so on round the ring: nobody in the group can run on without the others. For
such a group, a loss of progress is always a *stuck group*, and a stuck group is a deadlock
of its slice (``slicing``). So the slice's deadlock check, which is far cheaper than one
progress check per subsystem (``compose.check`` rebuilds the whole net for each), decides
progress as well.

The structural test, :func:`stall_together`, proves "nobody runs on alone" from the net
alone. Call a transition *finite* in a run when it fires finitely often. A place whose
producers are all finite receives finitely many tokens, so each of its consumers is finite
too (a transition with the place in both its pre- and post-set, a test arc, neither adds a
token nor takes one: it is neither).
Starting from "the ITERATION transitions of ``s`` are finite" and closing under that rule
gives the transitions that are finite in *every* infinite run of the whole net in which
``s`` iterates finitely often. If that closure holds every transition of every subsystem of
the group, for every ``s`` of the group, then (strong-fairness reading of progress, the
default):

    Let s lose progress: a reachable marking X, s unfinished, from which s never iterates.
    Fire only the group's transitions from X, as long as one is enabled. This cannot go on
    forever: it would be an infinite run in which s never iterates and the group's
    transitions fire infinitely often. It stops in a marking Z where no transition of the
    group is enabled and s is unfinished. The group waits only on itself (its channels to
    the rest are non-blocking, so its ends there are always enabled), and the slice can do
    what the group does in the whole net; the environment of the slice then makes finitely
    many moves. The slice reaches a dead marking that is not final: a deadlock.

So a deadlock-free slice means that no subsystem of the group loses progress; a slice
deadlock is lifted to the whole net as a stuck group (``sliced``), a loss of progress with a
lasso. Under weak fairness the reading differs (a subsystem can be starved at a non-blocking
end whose data keep changing), and this test is not used.

**The stall order** (:meth:`StallTest.ordered`), for a group that does not stall together
(an effector serving its controller, a controller with non-blocking links on both sides).

A. The argument above is per subsystem: it needs only that the closure of ``s``'s iterations
   holds every transition of the group. So a deadlock-free slice proves that ``s`` never
   loses progress for every such ``s`` (``stops(s)`` is the whole group), whether or not the
   others are like it.

B. The others, bottom-up. Let ``P`` be the subsystems proved so far, and ``r`` one that is
   not, such that (structurally, in the net explored, conditions as free choices):

   1. the closure of ``r``'s iterations holds all of ``r``'s transitions (``r`` cannot move
      forever without iterating), and a step of ``r`` that leaves its live places
      (``progress.live_places``: it finishes) is an ITERATION;
   2. ``r``'s steps take only ``r``'s own places and the ``full``/``empty`` places of its
      channels (no plumbing, nobody else's places);
   3. for each channel ``c`` at which ``r`` can wait (a blocking end: a step with no sibling
      taking the channel's other place, ``slicing``), the peer ``q`` is in ``P``; ``q`` never
      finishes (no step puts ``q``'s token into a place that is not live) and nothing but
      the system's start, which nothing else competes for, starts it; and ``q`` meets ``c``
      once in every iteration: in ``q``'s own control flow (a step reached when any of its
      inputs is), every path from an ITERATION to the next passes a step of ``c``
      completing ``q``'s part (a send's end putting ``full``, a receive's end putting
      ``empty``), and after it no step of ``q`` takes ``c``'s ``full`` or ``empty`` before
      the next ITERATION.

   Then ``r`` never loses progress. Suppose it does: a reachable ``X``, ``r`` unfinished, no
   continuation iterates ``r``, none reaches a deadlock. Build a run from ``X``: (a) while a
   step of ``r`` is enabled, fire one; (b) otherwise, for the next peer ``q`` in turn, start
   it if it has not started, then twice: ``q`` is unfinished (it never finishes), no deadlock
   is reachable, and ``q`` never loses progress, so some continuation completes an iteration
   of ``q``: fire it, to that ITERATION. The run is infinite and never iterates ``r``, so by
   1 ``r`` moves finitely often: after some point ``T`` its places stay as they are and no
   step of ``r`` is enabled when (b) starts. ``r`` is not finished (1), so some step ``t`` of
   ``r`` has all its own input places marked (the pages are series-parallel blocks: a join
   waits only for branches that are running); by 2 it waits on a channel ``c``, and at a
   non-blocking end a sibling taking the other place of ``c`` (one of ``full``/``empty`` is
   always marked) would be enabled: ``c`` is one of 3's, with peer ``q``. Take ``q``'s phase
   after ``T``. Between its two ITERATIONs ``q`` completes its part of ``c``, and nothing
   takes it back before the second: ``r`` does not move, and only the two ends take ``c``'s
   places. If ``r`` consumes (a blocking receive waiting for ``full``), ``q``'s send end
   leaves ``full`` marked; if ``r`` produces (a blocking send waiting for ``empty``, its
   value in ``full`` since before ``T``), ``q``'s receive finds ``full``, so it takes (the
   "nothing new" variant needs ``empty``) and its end leaves ``empty`` marked. Either way
   ``t`` is enabled when (b) ends: a contradiction.

   The argument holds for the net with its conditions as free choices (what every engine
   explores when no value is tracked); with values tracked a guard may disable a step of
   ``r`` and the order is not used (``sliced``). The environment of the slice plays no part
   in B: everything is about the whole net, and ``P`` comes from A, whose slice argument is
   the one above.

So when A and B together prove every subsystem of the group, the slice's deadlock check
decides the group's progress, as for a group that stalls together.
"""

from __future__ import annotations

from collections.abc import Collection

from rssm_dsl.hpn.flat import FlatNet, Role
from rssm_dsl.verify.progress import live_places
from rssm_dsl.verify.slicing import _never_waits as never_waits
from rssm_dsl.verify.slicing import channels


class StallTest:
    """The net's producers and consumers, indexed once; :meth:`together` per group."""

    def __init__(self, net: FlatNet) -> None:
        self.net = net
        self.producers: list[int] = [0] * len(net.places)   # producers of each place
        self.consumers: list[list[int]] = [[] for _ in net.places]
        self.posts: list[list[int]] = []
        self.iterations: dict[str, list[int]] = {}
        self.of: dict[str, list[int]] = {}
        for t in net.transitions:
            pre, post = set(t.pre), set(t.post)
            for p in post - pre:
                self.producers[p] += 1
            for p in pre - post:
                self.consumers[p].append(t.index)
            self.posts.append(sorted(post - pre))
            if t.subsystem is not None:
                self.of.setdefault(t.subsystem, []).append(t.index)
                if t.role is Role.ITERATION:
                    self.iterations.setdefault(t.subsystem, []).append(t.index)
        # a place nobody produces holds its initial tokens only: its consumers are finite
        self.unproduced = [t for p, n in enumerate(self.producers) if n == 0
                           for t in self.consumers[p]]
        self._wait_cache: dict[str, list[tuple[int, int, str, bool]]] | None = None
        self.takers: list[list[int]] = [[] for _ in net.places]     # test arcs included
        for t in net.transitions:
            for p in t.pre:
                self.takers[p].append(t.index)

    def together(self, group: Collection[str]) -> bool:
        """Does every subsystem of ``group`` stop for good once any one of them stops
        iterating (the module docstring)? False when some subsystem of the group has no
        ITERATION transition."""
        mine = {t for s in group for t in self.of.get(s, ())}
        for s in sorted(group):
            seeds = self.iterations.get(s)
            if not seeds or not self._covers(seeds, mine):
                return False
        return True

    def ordered(self, group: Collection[str]) -> list[str] | None:
        """The subsystems of ``group`` in an order A, then B (the module docstring) proves
        them, assuming the group's slice deadlock-free; None when some are left."""
        mine = {t for s in group for t in self.of.get(s, ())}
        proved = [s for s in sorted(group)
                  if self.iterations.get(s) and self._covers(self.iterations[s], mine)]
        left = [s for s in sorted(group) if s not in proved]
        waits = self._waits()
        changed = True
        while left and changed:
            changed = False
            for r in list(left):
                if self._fed(r, set(proved), waits):
                    proved.append(r)
                    left.remove(r)
                    changed = True
        return None if left else proved

    def _waits(self) -> dict[str, list[tuple[int, int, str, bool]]]:
        """Per subsystem, the channels it can wait on: (full, empty, peer, it consumes)."""
        if self._wait_cache is None:
            net = self.net
            out: dict[str, list[tuple[int, int, str, bool]]] = {}
            for c in channels(net):
                for me, peer, consumes in ((c.consumer, c.producer, True),
                                           (c.producer, c.consumer, False)):
                    if me is None or peer is None:
                        continue
                    own = [t for t in net.transitions if t.subsystem == me]
                    pres = {frozenset(t.pre) for t in own}
                    if not never_waits(own, pres, c.full, c.empty):
                        out.setdefault(me, []).append((c.full, c.empty, peer, consumes))
            self._wait_cache = out
        return self._wait_cache

    def _fed(self, r: str, proved: set[str],
             waits: dict[str, list[tuple[int, int, str, bool]]]) -> bool:
        """B (the module docstring): conditions 1 to 3 for ``r``."""
        net = self.net
        own = set(self.of.get(r, ()))
        seeds = self.iterations.get(r)
        if not seeds or not self._covers(seeds, own):
            return False
        mine = {p.index for p in net.places if p.subsystem == r}
        mine_waits = waits.get(r, [])
        chans = {p for c in channels(net) if r in (c.producer, c.consumer)
                 for p in (c.full, c.empty)}
        for t in own:
            if any(p not in mine and p not in chans for p in net.transitions[t].pre):
                return False
        if not self._no_quiet_end(r):
            return False
        for full, empty, q, consumes in mine_waits:
            if q not in proved or not self._endless(q) \
                    or not self._once(q, full, empty, consumes):
                return False
        return True

    def _no_quiet_end(self, s: str) -> bool:
        """A step of ``s`` that puts its token into a place that is not live is an
        ITERATION, and only ``s`` takes its live places (1)."""
        live = live_places(self.net, s)
        if any(self.net.transitions[t].subsystem != s for p in bits_of(live)
               for t in self.takers[p]):
            return False
        for t in self.of.get(s, ()):
            tr = self.net.transitions[t]
            if tr.role is Role.ITERATION:
                continue
            if any(self.net.places[p].subsystem == s and not live >> p & 1 for p in tr.post):
                return False
        return True

    def _endless(self, q: str) -> bool:
        """``q`` never finishes once started, and only the system's start, which nothing
        competes for, starts it (3)."""
        net = self.net
        live = live_places(net, q)
        starters: list[int] = []
        for t in net.transitions:
            into = [p for p in t.post if net.places[p].subsystem == q]
            if not into:
                continue
            if any(not live >> p & 1 for p in into):
                return False            # a step puts q's token where it is finished
            if t.subsystem is None:
                starters.append(t.index)
        seen: set[int] = set()
        while starters:
            k = starters.pop()
            if k in seen:
                continue
            seen.add(k)
            for p in net.transitions[k].pre:
                if net.places[p].subsystem is not None or self.takers[p] != [k]:
                    return False        # a start that waits for, or competes with, others
                for u in net.transitions:
                    if p in u.post and p not in u.pre:
                        if u.subsystem is not None:
                            return False
                        starters.append(u.index)
        return True

    def _once(self, q: str, full: int, empty: int, consumes: bool) -> bool:
        """``q`` meets the channel (``full``, ``empty``) once in every iteration, its part
        completed before the ITERATION (3; ``consumes``: the waiting end consumes, so ``q``
        produces)."""
        net = self.net
        own = [net.transitions[t] for t in self.of.get(q, ())]
        mine = {p.index for p in net.places if p.subsystem == q}
        pair = {full, empty}
        done = full if consumes else empty
        steps = [t for t in own if pair & set(t.pre) or pair & set(t.post)]
        completes = {t.index for t in steps if done in t.post and done not in t.pre}
        # what takes the waiting end's place away (a test arc leaves it)
        touches = {t.index for t in steps if done in t.pre and done not in t.post}
        # while r waits, the other place of the pair stays marked until q completes, so
        # q's steps that need ``done`` cannot fire before it (an overwriting send, a receive
        # finding nothing new)
        idle = {t.index for t in steps if done in t.pre}
        if not completes:
            return False

        def reach(starts: set[int], blocked: set[int]) -> set[int]:
            """Transitions of q reached from places ``starts`` through q's own places, a step
            reached when any of its inputs is, not through ``blocked``."""
            places, out = set(starts), set()
            work = list(starts)
            while work:
                p = work.pop()
                for t in self.takers[p]:
                    if t in out or t in blocked or net.transitions[t].subsystem != q:
                        continue
                    out.add(t)
                    for p2 in net.transitions[t].post:
                        if p2 in mine and p2 not in places:
                            places.add(p2)
                            work.append(p2)
            return out

        iters = set(self.iterations.get(q, ()))
        after_iter = {p for t in iters for p in net.transitions[t].post if p in mine}
        if self._fires(q, mine, after_iter, completes | idle, iters) & iters:
            return False                # an iteration without the channel's part
        after_done = {p for t in completes for p in net.transitions[t].post if p in mine}
        return not reach(after_done, iters) & touches

    def _fires(self, q: str, mine: set[int], starts: set[int], blocked: set[int],
               iters: set[int]) -> set[int]:
        """Transitions of ``q`` that can fire from ``q``'s places ``starts`` (``mine``: all
        of them), not through ``blocked``: a step once all its own input places are reached
        (a join waits for every branch); the ITERATIONs ``iters`` reached, not gone
        through."""
        net = self.net
        places, out = set(starts), set()
        work = list(starts)
        while work:
            p = work.pop()
            for t in self.takers[p]:
                tr = net.transitions[t]
                if t in out or t in blocked or tr.subsystem != q or any(
                        x in mine and x not in places for x in tr.pre):
                    continue
                out.add(t)
                if t in iters:
                    continue
                for p2 in tr.post:
                    if p2 in mine and p2 not in places:
                        places.add(p2)
                        work.append(p2)
        return out

    def _covers(self, seeds: list[int], mine: set[int]) -> bool:
        """Is every transition of ``mine`` finite in every infinite run in which ``seeds``
        are (the module docstring)? A worklist over the count of each place's producers not
        yet finite, stopped as soon as ``mine`` is covered."""
        missing = self.producers[:]
        work = [*seeds, *self.unproduced]
        finite: set[int] = set()
        left = len(mine)
        while work:
            t = work.pop()
            if t in finite:
                continue
            finite.add(t)
            if t in mine:
                left -= 1
                if left == 0:
                    return True
            for p in self.posts[t]:
                missing[p] -= 1
                if missing[p] == 0:
                    work.extend(c for c in self.consumers[p] if c not in finite)
        return left == 0


def bits_of(mask: int) -> list[int]:
    """The set bits of ``mask``."""
    out = []
    while mask:
        low = mask & -mask
        out.append(low.bit_length() - 1)
        mask ^= low
    return out


def stall_together(net: FlatNet, group: Collection[str]) -> bool:
    """:meth:`StallTest.together` for one group."""
    return StallTest(net).together(group)
