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
"""

from __future__ import annotations

from collections.abc import Collection

from rssm_dsl.hpn.flat import FlatNet, Role


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


def stall_together(net: FlatNet, group: Collection[str]) -> bool:
    """:meth:`StallTest.together` for one group."""
    return StallTest(net).together(group)
