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


def stall_together(net: FlatNet, group: Collection[str]) -> bool:
    """Does every subsystem of ``group`` stop for good once any one of them stops
    iterating (the module docstring)? False when some subsystem of the group has no
    ITERATION transition."""
    members = set(group)
    producers: list[set[int]] = [set() for _ in net.places]
    consumers: list[list[int]] = [[] for _ in net.places]
    posts: list[list[int]] = []
    for t in net.transitions:
        pre, post = set(t.pre), set(t.post)
        for p in post - pre:
            producers[p].add(t.index)
        for p in pre - post:
            consumers[p].append(t.index)
        posts.append(sorted(post - pre))
    mine = {t.index for t in net.transitions if t.subsystem in members}
    for s in sorted(members):
        seeds = [t.index for t in net.transitions
                 if t.subsystem == s and t.role is Role.ITERATION]
        if not seeds or not mine <= _finite_closure(seeds, posts, producers, consumers):
            return False
    return True


def _finite_closure(seeds: list[int], posts: list[list[int]], producers: list[set[int]],
                    consumers: list[list[int]]) -> set[int]:
    """The transitions finite in every infinite run in which ``seeds`` are (the module
    docstring): a worklist over the count of each place's producers not yet finite. A place
    nobody produces holds its initial tokens only: its consumers are finite from the start."""
    missing = [len(ps) for ps in producers]
    work = list(seeds)
    for p, count in enumerate(missing):
        if count == 0:
            work.extend(consumers[p])
    finite: set[int] = set()
    while work:
        t = work.pop()
        if t in finite:
            continue
        finite.add(t)
        for p in posts[t]:
            missing[p] -= 1
            if missing[p] == 0:
                work.extend(c for c in consumers[p] if c not in finite)
    return finite
