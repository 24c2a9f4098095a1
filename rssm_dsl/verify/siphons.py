"""Partial deadlocks found as empty siphons, with a firing sequence for each.

A *siphon* is a set of places ``Q`` such that every transition putting a token into a place
of ``Q`` takes one from ``Q`` (test arcs included: a transition with ``p`` in its pre- and
post-set takes from ``Q`` when ``p`` is in it). Once no place of ``Q`` is marked, none ever is
again, and every transition with an input place in ``Q`` is dead for good. In a marking
``m`` the union of the siphons containing no marked place is a siphon (``empty_siphon``, a
fixpoint over bit sets: drop from the unmarked places every place that a transition with no
input among them produces, until none is left to drop).

So when, in a reachable marking ``m`` of a net ``N``, every ITERATION transition of a
subsystem ``s`` has an input place in the largest empty siphon and ``s`` is not finished
(``progress.live_places``), then no continuation of ``m``, whatever the scheduling and the
free choices, ever completes another iteration of ``s``: condition 2 of a loss of progress
(``progress``), in ``N``. This holds for strong and weak fairness alike; it is a statement
about every continuation.

How it is used (``sliced``): in a blocking group whose progress is not settled by its
deadlock check (``stalls``), before the stubborn sets with the cycle proviso that progress
needs (``find_stalls``):

* ``probe``: a few runs of the slice, every mover taking a step in turn (the lowest enabled
  one, then seeded random ones), the empty siphon tested at every power of two steps. A
  planted cycle of blocking sends is reached by any such run within a few hundred steps,
  where the stubborn sets need 100,000 markings and more at 20 agents;
* else the stubborn-set search *without* the cycle proviso, its graph kept (``_search``,
  20,000 markings at most): every marking it explores is reachable in the slice.

An empty siphon only grows along a firing sequence (the old one stays an empty siphon), so
what is dead in a marking is dead in every marking after it: the stuck subsystems of a graph
are those of one marking per terminal strongly connected component, and along a run or the
breadth-first path to a marking the earliest marking where ``s`` is stuck is found by
bisection. None of this is trusted as it is: the slice over-approximates the rest of the
system. The finding goes back to the whole net (``lift_stall``):

1. the group's steps are replayed in the whole net (``slicing.replay_group``, or with the
   values tracked ``sliced._Whole.replay``), reaching a marking ``M`` of the whole net;
2. the empty siphon is computed again, in the whole net (without the values: the net with
   the values tracked can do less than it, so what is dead without them is dead with them),
   at ``M``; ``s`` must be unfinished and every ITERATION of ``s`` dead there. That is
   condition 2 in the whole net;
3. from ``M`` everyone moves (``slicing.run_outside`` with no group held: each subsystem and
   the plumbing in turn, one enabled step each) until the marking repeats: the lasso's cycle,
   a run of the whole net in which the subsystems that can still move do move (the stuck
   ones' iterations are dead, so they are never in it). If it stops instead, nothing at all
   is enabled: a deadlock of the whole net, reported as one, with its firing sequence.

What is reported is then a firing sequence of the whole net to a point of no return and a
cycle of the whole net after it. As for the stuck groups ``sliced`` lifts, that no deadlock
is reachable from the point (condition 3) is not searched for: the deadlock verdict comes
from the slices (one deadlock-free slice makes the whole net deadlock-free), and either way
the system is in violation.
"""

from __future__ import annotations

import bisect
import dataclasses
import random
from collections.abc import Callable, Sequence
from typing import TYPE_CHECKING

from rssm_core.records import dataclass
from rssm_dsl.hpn.flat import FlatNet, Role
from rssm_dsl.verify.budget import Budget, LimitReached
from rssm_dsl.verify.cover import one_token_semiflows
from rssm_dsl.verify.datanet import track_new
from rssm_dsl.verify.netbits import NetBits, bits, to_mask
from rssm_dsl.verify.progress import live_places
from rssm_dsl.verify.report import (
    Counterexample,
    Verdict,
    VerifyReport,
    marking_labels,
    marking_where,
)
from rssm_dsl.verify.scc import components
from rssm_dsl.verify.slicing import ReplayError, Slice, fire_steps, replay_group, run_outside
from rssm_dsl.verify.stubborn import StubbornExplorer
from rssm_dsl.verify.valuenet import track_values

if TYPE_CHECKING:
    from rssm_dsl.verify.dataplan import ValuePlan
    from rssm_dsl.verify.sliced import _Whole

PROBE_STEPS = 20_000    # steps of each run of ``probe``
PROBE_SEEDS: tuple[int | None, ...] = (None, 1, 2)   # its runs: the lowest step, random
SEARCH_STATES = 20_000  # the deadlock-only stubborn-set search at most
STALL = "stall"     # kind of a slice's counterexample found by an empty siphon, before lifting


class SiphonTest:
    """A net's pre- and post-sets as bit sets, indexed once; the largest empty siphon of a
    marking (the module docstring) and the subsystems it stops for good."""

    def __init__(self, net: FlatNet) -> None:
        self.net = net
        self.pre = [to_mask(t.pre) for t in net.transitions]
        # what a transition puts into a place it does not take from (a test arc's place
        # is in its pre-set too, so it never drops a place of a siphon)
        self.adds = [to_mask(tuple(set(t.post) - set(t.pre))) for t in net.transitions]
        self.producers: list[list[int]] = [[] for _ in net.places]
        self.consumers: list[list[int]] = [[] for _ in net.places]
        for t in net.transitions:
            for p in set(t.post) - set(t.pre):
                self.producers[p].append(t.index)
            for p in t.pre:
                self.consumers[p].append(t.index)
        self.iterations: dict[str, list[int]] = {}
        for t in net.transitions:
            if t.role is Role.ITERATION and t.subsystem is not None:
                self.iterations.setdefault(t.subsystem, []).append(t.index)
        self.live = {s: live_places(net, s) for s in self.iterations}

    def empty_siphon(self, marking: int) -> int:
        """The largest siphon with no place marked in ``marking`` (a bit set of places)."""
        q = ((1 << len(self.net.places)) - 1) & ~marking
        pre, adds, consumers = self.pre, self.adds, self.consumers
        work = [t for p in bits(q) for t in self.producers[p]]
        while work:
            t = work.pop()
            gone = adds[t] & q
            if not gone or pre[t] & q:
                continue
            q &= ~gone
            for p in bits(gone):
                work += consumers[p]
        return q

    def stuck(self, marking: int, among: Sequence[str] | None = None) -> list[str]:
        """The subsystems (of ``among``; default all) not finished in ``marking`` whose
        ITERATION transitions all have an input place in its largest empty siphon: none of
        them ever completes another iteration."""
        q = self.empty_siphon(marking)
        if not q:
            return []
        names = sorted(self.iterations) if among is None else among
        return [s for s in names if s in self.iterations and self.live[s] & marking
                and all(self.pre[t] & q for t in self.iterations[s])]


@dataclass(frozen=True)
class StallSearch:
    """What ``find_stalls`` found: per stuck subsystem a counterexample of the slice (kind
    ``STALL``: the steps to the earliest marking of its path where it is stuck), and the
    states the search explored (0 when it did not complete)."""

    found: tuple[Counterexample, ...]
    states: int
    complete: bool


def find_stalls(sl: Slice, values: ValuePlan | None, budget: Budget,
                max_states: int) -> StallSearch:
    """The subsystems of ``sl``'s group that an empty siphon stops for good: first along
    a few runs of the slice (``probe``), then in the markings of the deadlock-only
    stubborn-set search of the slice (the module docstring)."""
    try:
        found = probe(sl, budget)
        if found:
            return StallSearch(tuple(found), 0, False)
        return _search(sl, values, budget, min(max_states, SEARCH_STATES))
    except LimitReached:
        # the budget keeps the stop (the run's, or a cap's): the caller sees it
        return StallSearch((), 0, False)


def probe(sl: Slice, budget: Budget, steps: int = PROBE_STEPS,
          seeds: Sequence[int | None] = PROBE_SEEDS) -> list[Counterexample]:
    """Runs of the slice in which every mover (each subsystem, the plumbing and the
    environment) takes one enabled step in turn (the lowest, or with a seed a random one),
    ``steps`` at most, the largest empty siphon tested at every power of two steps and at
    the end: the subsystems of the group stopped for good, each with the run's steps to the
    earliest marking where it is (stuck stays stuck along a run: bisection)."""
    net = sl.net
    nb = NetBits.of(net)
    test = SiphonTest(net)
    group = sorted(s for s in sl.keep if s in test.iterations)
    movers: dict[str | None, list[int]] = {}
    for tr in net.transitions:
        movers.setdefault(tr.subsystem, []).append(tr.index)
    order = list(movers.values())
    for seed in seeds:
        rng = random.Random(seed) if seed is not None else None
        m = nb.initial
        marks = [m]
        path: list[int] = []
        checked = 0                 # the last marking tested and found with nobody stuck
        nxt = 1
        stuck: list[str] = []
        while len(path) < steps:
            moved = False
            for ts in order:
                ready = [t for t in ts if m & nb.pre[t] == nb.pre[t]]
                if not ready:
                    continue
                t = rng.choice(ready) if rng is not None else ready[0]
                m = (m & ~nb.pre[t]) | nb.post[t]
                path.append(t)
                marks.append(m)
                moved = True
            if not moved:
                break               # a deadlock of the slice: the deadlock check's case
            if len(path) >= nxt or len(path) >= steps:
                budget.check()
                stuck = test.stuck(m, group)
                if stuck:
                    break
                checked = len(path)
                nxt *= 2
        if not stuck:
            continue
        # the earliest marking where all of them are stuck (one point, lifted once)
        k = checked + bisect.bisect_left(range(checked, len(marks)), True,
                                         key=_stuck_at(test, marks, stuck))
        mm = nb.marking_of(marks[k])
        steps_k = tuple(net.transitions[t] for t in path[:k])
        return [Counterexample(STALL, steps_k, marking_labels(net, mm), subsystem=s,
                               where=marking_where(net, mm)) for s in stuck]
    return []


def _search(sl: Slice, values: ValuePlan | None, budget: Budget,
            max_states: int) -> StallSearch:
    """``find_stalls`` in the markings of the deadlock-only stubborn-set search."""
    tracked = track_values(track_new(sl.net), values)
    net = tracked.net
    safe = 0
    for f in one_token_semiflows(net, range(len(net.places)),
                                 lambda: budget.poll() is not None):
        safe |= to_mask(tuple(f.support))
    nb = NetBits.of(net)
    try:
        r = StubbornExplorer(nb, safe, True, proviso=False).explore(
            max_states, max_counterexamples=1, keep_graph=True, budget=budget)
    except LimitReached:
        return StallSearch((), 0, False)
    if not r.complete or r.graph is None:
        return StallSearch((), r.states, False)
    graph = r.graph
    test = SiphonTest(net)
    group = sorted(s for s in sl.keep if s in test.iterations)
    succ: list[list[int]] = [[] for _ in range(graph.size)]
    for a, b in zip(graph.src.tolist(), graph.dst.tolist(), strict=True):
        if a != b:
            succ[a].append(b)
    comp, ncomp = components(succ, budget.check)
    leaves = [True] * ncomp
    for a in range(graph.size):
        if any(comp[b] != comp[a] for b in succ[a]):
            leaves[comp[a]] = False
    first_of: dict[int, int] = {}
    for v in range(graph.size):
        if leaves[comp[v]]:
            first_of.setdefault(comp[v], v)
    where: dict[str, int] = {}          # a terminal marking where each subsystem is stuck
    for v in sorted(first_of.values()):
        budget.check()
        for s in test.stuck(graph.marking(v), group):
            where.setdefault(s, v)
    found: list[Counterexample] = []
    for s, v in sorted(where.items()):
        path = list(graph.path(v))
        marks = [nb.initial]
        for t in path:
            marks.append((marks[-1] & ~nb.pre[t]) | nb.post[t])
        # stuck is kept along the path: the earliest marking of it where s is stuck
        k = bisect.bisect_left(range(len(marks)), True, key=_stuck_at(test, marks, [s]))
        m = frozenset(q for p in bits(marks[k]) if (q := tracked.place_origin[p]) is not None)
        found.append(Counterexample(
            STALL, tracked.steps(net.transitions[t] for t in path[:k]),
            marking_labels(sl.net, m), subsystem=s, where=marking_where(sl.net, m)))
    return StallSearch(tuple(found), r.states, True)


def lift_stall(net: FlatNet, whole: _Whole, sl: Slice, cx: Counterexample,
               ) -> tuple[list[Counterexample], list[Counterexample]]:
    """A stall of ``sl`` (``find_stalls``) as the whole net's: the deadlocks and the losses
    of progress it shows, each with its firing sequence (the module docstring);
    ``ReplayError`` when the whole net does not confirm it. The stalls of one slice found
    at one point share its replay and its cycle (computed once)."""
    assert cx.subsystem is not None
    s = cx.subsystem
    key = (id(net), id(whole), sl.keep, tuple(t.index for t in cx.steps))
    point = _POINTS.get(key)
    if point is None or point.net is not net:
        if len(_POINTS) > 16:
            _POINTS.clear()
        point = _POINTS[key] = _lift_point(net, whole, sl, cx)
    if s not in point.stuck:
        raise ReplayError(f"after the group's steps, the whole net has no empty siphon that "
                          f"stops {s} for good")
    if point.deadlock is not None:
        first, point.deadlock = [point.deadlock], None
        return first, []
    if point.progress is None:
        return [], []           # the whole net's deadlock, reported with the first one
    return [], [dataclasses.replace(point.progress, subsystem=s)]


@dataclasses.dataclass
class _Point:
    """A point of no return in the whole net (``lift_stall``): who is stuck there, and the
    counterexample it gives (a deadlock, reported once; or a loss of progress, the subsystem
    filled in per stuck subsystem)."""

    net: FlatNet
    stuck: frozenset[str]
    deadlock: Counterexample | None
    progress: Counterexample | None


_POINTS: dict[tuple[int, int, frozenset[str], tuple[int, ...]], _Point] = {}


def _lift_point(net: FlatNet, whole: _Whole, sl: Slice, cx: Counterexample) -> _Point:
    test = _test(net)
    group_steps = sl.whole_steps(cx.steps)
    if whole.net is None:
        steps, m = replay_group(sl, group_steps)
        starts = []
    else:
        ends = whole.replay(sl, group_steps)
        best = max(ends, key=lambda n: len(test.stuck(to_mask(tuple(whole.raw(n.marking))))))
        starts = [best]
        m = whole.raw(best.marking)
        steps = []
    stuck = frozenset(test.stuck(to_mask(tuple(m)), sorted(sl.keep)))
    if not stuck:
        raise ReplayError("after the group's steps, the whole net has no empty siphon that "
                          "stops a subsystem of the group for good")
    to_cycle, cycle, stopped = run_outside(net, m, frozenset())
    if whole.net is None:
        at = fire_steps(net, m, to_cycle)
        if stopped:
            return _Point(net, stuck, Counterexample(
                "deadlock", _steps(net, steps + to_cycle), marking_labels(net, at)), None)
        return _Point(net, stuck, None, Counterexample(
            "progress", _steps(net, steps), marking_labels(net, m), subsystem=None,
            where=marking_where(net, m), to_cycle=_steps(net, to_cycle),
            cycle=_steps(net, cycle), cycle_marking=marking_labels(net, at)))
    after = whole.after_stall(net, starts, to_cycle, cycle, stopped)
    if isinstance(after, Counterexample):
        return _Point(net, stuck, after, None)
    start, turn, back = after
    prefix, into = start.path(), turn.path()
    m = whole.raw(start.marking)
    return _Point(net, stuck, None, Counterexample(
        "progress", whole.steps(prefix), marking_labels(net, m), subsystem=None,
        where=marking_where(net, m), to_cycle=whole.steps(into[len(prefix):]),
        cycle=whole.steps(back.path()[len(into):]), values=whole.values(back.path()),
        cycle_marking=marking_labels(net, whole.raw(turn.marking))))


def _stuck_at(test: SiphonTest, marks: Sequence[int], who: Sequence[str],
              ) -> Callable[[int], bool]:
    def stuck(i: int) -> bool:
        return len(test.stuck(marks[i], who)) == len(who)
    return stuck


_TESTS: dict[int, tuple[FlatNet, SiphonTest]] = {}


def _test(net: FlatNet) -> SiphonTest:
    """The whole net's ``SiphonTest``, built once per net."""
    cached = _TESTS.get(id(net))
    if cached is not None and cached[0] is net:
        return cached[1]
    if len(_TESTS) > 8:
        _TESTS.clear()
    test = SiphonTest(net)
    _TESTS[id(net)] = (net, test)
    return test


def _steps(net: FlatNet, steps: Sequence[int]) -> tuple:  # type: ignore[type-arg]
    return tuple(net.transitions[t] for t in steps)


def with_stalls(r: VerifyReport, stalls: StallSearch) -> VerifyReport:
    """A slice's report ``r`` with the stalls ``find_stalls`` found in it: its losses of
    progress, to be lifted to the whole net (``lift_stall``) before they count (progress
    stays open in the slice's report: the lift says whether it is a loss of progress or a
    deadlock of the whole net, or neither)."""
    names = ", ".join(c.subsystem or "" for c in stalls.found)
    return dataclasses.replace(
        r, verdict=Verdict.VIOLATED, progress_ok=None, progress=stalls.found,
        progress_requested=True,
        notes=(*(n for n in r.notes
                 if "--no-progress-check" not in n and "progress not decided" not in n),
               f"an empty siphon stops {names} for good (deadlock-only stubborn-set search, "
               f"{stalls.states:,} states)"))
