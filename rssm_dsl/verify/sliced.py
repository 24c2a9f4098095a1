"""Verification group by group (``slicing``): each blocking group's slice is verified on its
own, and what the slices find is lifted back to the whole net.

Why the verdicts carry over (``slicing`` has the argument): every place lies in some slice and
a slice can do all its group does in the whole net, so all slices safe means the whole net is
safe; a deadlock of the whole net is one of every slice, so one deadlock-free slice means the
whole net is deadlock-free; a subsystem that loses progress in the whole net does so in its
slice (it never waits on the environment, which a slice only over-approximates). In the other
direction nothing is taken on trust: every violation found in a slice is replayed in the whole
net (``replay_group``, the rest of the system standing still) and reported only as the firing
sequence of the whole net it becomes:

* a deadlock of a slice in which some subsystem of the group is not finished: the group is
  stuck for good. From the replayed marking the rest of the system runs (``run_outside``): if
  it stops too, the whole net is in a deadlock (reported as such, with the rest's steps);
  otherwise every unfinished subsystem of the group loses progress, and the counterexample is a
  lasso: the replayed steps, then what the rest does until it repeats, then the repeating part;
* a loss of progress inside a slice: its steps and its cycle are replayed (the cycle until the
  whole net's marking repeats);
* an unsafe firing: its steps are replayed and the last one must put a second token somewhere.

The replay (``replay_group``) moves tokens: it passes over the plumbing that also waits for
subsystems outside the group (an agent's end) and lets the rest move first, a bounded
search, when a step of the group is not enabled. A slice's environment also gives any value,
so with values tracked the lift is done in the whole net with its values (``_Whole``): the
producers outside run until they have sent what the slice took from its environment, any
value they can, and a step whose values do not hold cannot be taken; a stuck group is
claimed only once none of its moves is enabled there. A slice that cut free channels inside
its group and found violations the whole net does not confirm is verified again with them
whole. A violation that still is not lifted is never reported as one: the report names it
(``report.Unconfirmed``: what, the group, why, what was tried, the slice's firing sequence)
and the verdict stays open.
"""

from __future__ import annotations

import dataclasses
import functools
import time
from collections.abc import Callable, Collection, Sequence
from typing import TYPE_CHECKING

from rssm_core.records import dataclass
from rssm_dsl.hpn.flat import FlatNet, FlatTransition, Role
from rssm_dsl.verify.budget import Budget
from rssm_dsl.verify.datanet import track_new
from rssm_dsl.verify.progress import live_places
from rssm_dsl.verify.report import (
    Counterexample,
    StepValue,
    Unconfirmed,
    Verdict,
    VerifyReport,
    marking_labels,
    marking_where,
)
from rssm_dsl.verify.siphons import STALL, find_stalls, lift_stall, with_stalls
from rssm_dsl.verify.slicing import (
    OUTSIDE_STATES,
    Channel,
    ReplayError,
    Slice,
    channels,
    fire_steps,
    replay_group,
    run_outside,
    slice_net,
)
from rssm_dsl.verify.stalls import StallTest
from rssm_dsl.verify.valuenet import track_values

if TYPE_CHECKING:
    from rssm_dsl.verify.dataplan import ValuePlan
    from rssm_dsl.verify.verifier import VerifyOptions

Verifier = Callable[[FlatNet, "VerifyOptions"], VerifyReport]
CYCLE_PASSES = 6            # replays of a slice's cycle to find the whole net's cycle
STUBBORN_STATES = 100_000   # a slice's stubborn-set search at most
SMALL_SLICE = 10_000        # a slice explored whole when it has no more states
COMPOSE_SHARE = 1 / 2       # of the time left, for each later try on a slice
MANY = 4                    # subsystems: a group of this many is composed first
FEED_STATES = (1_000, 10_000)   # markings searched for the outside to send what the
#                             slice's environment wrote: a first try, then a wider one
LAYER = 64                  # markings kept per step when a lifted sequence is checked
#                             against the values (_Whole.realise)
FUTURE_STATES = 50_000      # markings explored at most to confirm that a subsystem never
#                             iterates again in the whole net (values tracked)


def verify_sliced(net: FlatNet, groups: Sequence[tuple[str, ...]], opts: VerifyOptions,
                  budget: Budget, verify: Verifier) -> VerifyReport:
    """The report on ``net`` from its groups' slices, each verified by ``verify`` with
    ``opts`` (slicing off, the run's ``budget`` shared)."""
    start = time.monotonic()
    check_progress = opts.check_progress
    slices = [slice_net(net, group) for group in groups]
    quick = dataclasses.replace(opts, check_progress=False)
    # smallest first: a limit reached on a large group leaves the others decided
    found: dict[int, VerifyReport] = {}
    stalls = StallTest(net)
    for i in sorted(range(len(slices)), key=lambda i: len(slices[i].net.transitions)):
        if budget.stop is not None:
            break
        sl = slices[i]
        if check_progress and opts.fairness == "strong" and stalls.together(sl.keep):
            found[i] = _by_deadlocks(sl, quick, budget, verify)
            continue
        if check_progress and opts.fairness == "strong" and opts.values is None \
                and stalls.ordered(sl.keep) is not None:
            # progress by the stall order (stalls.py): the slice's deadlock check decides
            found[i] = _by_deadlocks(sl, quick, budget, verify, ORDERED)
            continue
        r = _decide(sl, opts if check_progress else quick, verify)
        if r.verdict is Verdict.INCONCLUSIVE and check_progress and budget.stop is None:
            # progress not decided: at least safeness and deadlocks
            first = _decide(sl, quick, verify)
            r = dataclasses.replace(first, progress_requested=True, verdict=(
                first.verdict if first.verdict is Verdict.VIOLATED else Verdict.INCONCLUSIVE),
                notes=(*r.notes, *first.notes), why_undecided=r.why_undecided)
        found[i] = r
    whole = _Whole(net, opts.values, budget)
    refined: list[str] = []
    for i, r in list(found.items()):
        sl = slices[i]
        if not sl.cut or budget.stop is not None or not _violations(r):
            continue
        probe = _Lifted(net, whole)
        probe.lift_all(sl, r)
        if not probe.failed:
            continue
        # a violation the whole net does not confirm, in a slice that cut free channels
        # inside its group (their values, there, are free): the slice again with them whole
        sl = slice_net(net, tuple(sorted(sl.keep)), cut=False)
        opts_i = opts if check_progress else quick
        if check_progress and opts.fairness == "strong" and stalls.together(sl.keep):
            r = _by_deadlocks(sl, quick, budget, verify)
        else:
            r = _decide(sl, opts_i, verify)
        slices[i], found[i] = sl, r
        refined.append(f"the slice of {_names(sl.keep)} found {len(probe.failed)} "
                       "violation(s) the whole net does not confirm; it was verified again "
                       "with the free channels inside the group whole ("
                       + ", ".join(slices_cut(probe)) + ")")
    parts = [(slices[i], found[i]) for i in range(len(slices)) if i in found]
    return _combine(net, groups, parts, budget, start, check_progress, whole, refined)


def slices_cut(lifted: _Lifted) -> list[str]:
    """The channels the slices of ``lifted``'s failures cut (for a note)."""
    return list(dict.fromkeys(c for u in lifted.cut_by for c in u))


def _violations(r: VerifyReport) -> bool:
    return bool(r.deadlocks or r.progress or r.unsafe is not None)


def _decide(sl: Slice, opts: VerifyOptions, verify: Verifier) -> VerifyReport:
    """A slice's report: explored whole when it is small (``SMALL_SLICE`` states: dead
    transitions and unreachable behaviours come with it), else by stubborn sets (with
    counterexamples) up to ``STUBBORN_STATES`` states; a slice they do not decide within
    that leaves the sliced verdict open, and ``verify`` goes on with the whole net."""
    small = verify(sl.net, dataclasses.replace(opts, reduction="off", max_states=SMALL_SLICE))
    if small.complete or small.verdict is Verdict.VIOLATED:
        return small
    cap = min(opts.max_states, STUBBORN_STATES)
    if opts.check_progress and opts.budget is not None:
        # partial deadlocks first, as empty siphons of the deadlock-only search (siphons.py)
        stalls = find_stalls(sl, opts.values, opts.budget, cap)
        if stalls.found:
            return with_stalls(small, stalls)
    return verify(sl.net, dataclasses.replace(opts, max_states=cap))


ORDERED = ("progress follows from deadlock freedom by the stall order: the subsystems whose "
           "stall stops the whole group by it, then, bottom-up, each whose blocking waits are "
           "on subsystems proved before, which meet it in every iteration")


def _by_deadlocks(sl: Slice, quick: VerifyOptions, budget: Budget,
                  verify: Verifier, why: str | None = None) -> VerifyReport:
    """A group that stalls together (``stalls``): its slice's deadlock check decides its
    progress too. Explored whole when small; else by stubborn sets and compositionally (one
    composition of the slice, no per-subsystem one), the composition first for a group of
    ``MANY`` subsystems or more (a ring: the stubborn sets lose in the races of many alike
    subsystems, the composition decides it in a second or two), each at most
    ``COMPOSE_SHARE`` of the time left. A deadlock the composition finds gets its firing
    sequence from the stubborn sets."""
    r = verify(sl.net, dataclasses.replace(quick, reduction="off", max_states=SMALL_SLICE))
    if not r.complete and r.verdict is not Verdict.VIOLATED and budget.stop is None:
        notes = r.notes
        # the place invariants of the first try hold for the composition (the stubborn
        # sets compute them again: the safe places they prove make the stubborn sets smaller)
        composed = dataclasses.replace(quick, invariants=False, reduction="compositional")
        stubborn = dataclasses.replace(quick, max_states=min(quick.max_states, STUBBORN_STATES))
        tries = [composed, stubborn] if len(sl.keep) >= MANY else [stubborn, composed]
        first = r
        for opts in tries:
            if opts is composed and len(sl.keep) == 1:
                continue            # one subsystem: no races for the stubborn sets to lose
            left = budget.remaining()
            with budget.capped(COMPOSE_SHARE * left if left is not None else float("inf")) as cap:
                r = verify(sl.net, opts)
            notes = (*notes, *r.notes)
            if budget.stop is not None or r.deadlocks \
                    or (r.complete and not cap.hit and r.verdict is not Verdict.VIOLATED):
                break
        r = dataclasses.replace(r, notes=notes)
        if not r.invariants:
            r = dataclasses.replace(
                r, invariants=first.invariants, invariants_complete=first.invariants_complete,
                invariants_message=first.invariants_message,
                uncovered_places=first.uncovered_places)
    # the slice's own check ran without progress on purpose: its notes must not say so
    r = dataclasses.replace(r, notes=tuple(n for n in r.notes if "--no-progress-check" not in n))
    if r.verdict is Verdict.VERIFIED_WITHOUT_PROGRESS:
        checked = tuple(s for s in sorted(sl.keep) if any(
            t.subsystem == s and t.role is Role.ITERATION for t in sl.net.transitions))
        return dataclasses.replace(
            r, verdict=Verdict.VERIFIED, progress_ok=True, progress_requested=True,
            progress_checked=checked, notes=(*r.notes, why or (
                "progress follows from deadlock freedom: no subsystem of the group can run "
                "on once another stops iterating, so a loss of progress would be a deadlock "
                "of the slice")))
    return dataclasses.replace(r, progress_requested=True)


@dataclass(frozen=True)
class _Node:
    """A marking of the whole net with its values (``_Whole``), and how it was reached;
    ``skip``: steps of the group's sequence to pass over when their turn comes (the end of
    a receive that found no new data here where the slice took some)."""

    marking: frozenset[int]
    parent: _Node | None
    step: int
    skip: frozenset[int] = frozenset()

    def path(self) -> list[int]:
        """The steps (of the tracked net) from the root to here."""
        out: list[int] = []
        at: _Node | None = self
        while at is not None and at.step >= 0:
            out.append(at.step)
            at = at.parent
        return out[::-1]


class _Whole:
    """The whole net with the finite values the slices tracked (valuenet.py). The replay
    of a slice's steps (``slicing.replay_group``) moves tokens only; here a lifted firing
    sequence is checked against the data: each step must have a variant whose values hold,
    and a claim that a subsystem never iterates again must hold with those values. None of
    this is needed when no value is tracked (``net`` is None)."""

    def __init__(self, source: FlatNet, plan: ValuePlan | None,
                 budget: Budget | None = None) -> None:
        t = track_values(track_new(source), plan) if plan is not None else None
        self.source = source
        self.budget = budget
        self.net: FlatNet | None = t.net if t is not None and t.values else None
        self.chosen = t.chosen if self.net is not None and t is not None else {}
        self.origin: tuple[int, ...] = t.origin if t is not None else ()
        self.place_origin: tuple[int | None, ...] = t.place_origin if t is not None else ()
        self.variants: dict[int, list[int]] = {}
        if t is not None and self.net is not None:
            for u, o in enumerate(t.origin):
                self.variants.setdefault(o, []).append(u)
        # siblings, steps that lead to the same place and decide no control flow: another
        # data case of a partial function (and the end of that case), a non-blocking send
        # that starts on an empty buffer or overwrites a full one
        self.siblings: dict[int, list[int]] = {t.index: [] for t in source.transitions}
        case_ops = {p for t in source.transitions if t.role is Role.CASE for p in t.post}
        by: dict[tuple[str | None, str, tuple[int, ...]], list[int]] = {}
        for tr in source.transitions:
            key: tuple[str | None, str, tuple[int, ...]] | None = None
            if tr.role is Role.CASE:
                key = (tr.subsystem, "case", tr.pre)
            elif tr.role is Role.SEND:
                key = (tr.subsystem, "send", tr.post)
            elif tr.role is Role.STRUCTURE and len(tr.pre) == 1 and tr.pre[0] in case_ops:
                key = (tr.subsystem, "case end", tr.post)
            if key is not None:
                by.setdefault(key, []).append(tr.index)
        for alike in by.values():
            for x in alike:
                self.siblings[x] = [u for u in alike if u != x]
        self.value_places = frozenset(
            p.index for p in (self.net.places if self.net is not None else ())
            if (p.channel or "").startswith("value "))

    def steps(self, nodes_path: Sequence[int]) -> tuple[FlatTransition, ...]:
        """A path of the tracked net as the flat net's transitions."""
        return tuple(self.source.transitions[self.origin[u]] for u in nodes_path)

    def values(self, nodes_path: Sequence[int]) -> tuple[StepValue, ...]:
        """The values chosen along a path of the tracked net (``TrackedNet.choices``)."""
        return tuple((i, *c) for i, u in enumerate(nodes_path) for c in self.chosen.get(u, ()))

    def _fire(self, node: _Node, raws: Sequence[int], out: dict[frozenset[int], _Node],
              skip: frozenset[int] | None = None) -> None:
        assert self.net is not None
        rule = self.net.rule
        for raw in raws:
            for u in self.variants.get(raw, ()):
                if node.marking.issuperset(rule.pre[u]):
                    m2 = node.marking.difference(rule.consume[u]).union(rule.produce[u])
                    out.setdefault(m2, _Node(m2, node, u,
                                             node.skip if skip is None else skip))

    def search(self, starts: Sequence[_Node], movers: Collection[str | None],
               goal: Callable[[frozenset[int]], bool], max_states: int,
               every_value: bool = False) -> list[_Node]:
        """Breadth-first over the moves of ``movers`` from ``starts`` (together): the
        markings where ``goal`` holds (at most LAYER; not searched beyond). With
        ``every_value``, the first one of each valuation, searched on and beyond (up to
        ``max_states``) for the others: what the outside sends may be any value it can,
        a later send overwriting an earlier one."""
        assert self.net is not None
        rule = self.net.rule
        moves = [t.index for t in self.net.transitions if t.subsystem in movers]
        seen = {n.marking for n in starts}
        frontier = list(starts)
        found: dict[object, _Node] = {}

        def keep(n: _Node) -> None:
            key = n.marking & self.value_places if every_value else n.marking
            found.setdefault(key, n)

        for n in starts:
            if goal(n.marking):
                keep(n)
        while frontier and len(seen) < max_states and (every_value or len(found) < LAYER):
            nxt: list[_Node] = []
            for n in frontier:
                if goal(n.marking) and not every_value:
                    continue
                for u in moves:
                    if n.marking.issuperset(rule.pre[u]):
                        m2 = n.marking.difference(rule.consume[u]).union(rule.produce[u])
                        if m2 in seen:
                            continue
                        seen.add(m2)
                        if self.stopped(len(seen)):
                            return list(found.values())[:LAYER]
                        child = _Node(m2, n, u, n.skip)
                        if goal(m2):
                            keep(child)
                        if every_value or not goal(m2):
                            nxt.append(child)
            frontier = nxt
        return list(found.values())[:LAYER]

    def replay(self, sl: Slice, steps: Sequence[int]) -> list[_Node]:
        """``_replay`` with the outside's searches small first, then wider."""
        for k, feed in enumerate(FEED_STATES):
            try:
                return self._replay(sl, steps, feed)
            except ReplayError:
                if k == len(FEED_STATES) - 1:
                    raise
        raise AssertionError("unreachable")

    def _replay(self, sl: Slice, steps: Sequence[int], feed: int) -> list[_Node]:
        """The group's moves ``steps`` (the flat net's, from the slice's sequence) in the
        whole net with the values tracked: where the slice took data its environment wrote,
        the producer outside (and what feeds it) runs until it has sent some; a step not
        enabled is replaced by a sibling (another data case, an overwriting send, a receive
        that finds nothing new when nothing comes), or the rest of the system moves first
        (a bounded search). The markings reached (at most LAYER); ReplayError when a step
        cannot be taken."""
        assert self.net is not None
        net = self.source
        chans = {c.name: c for c in channels(net)}
        feeds = {c.name: _upstream(net, c, sl.keep, chans) for c in chans.values()
                 if c.free and c.consumer in sl.keep and c.producer not in sl.keep}
        layer = [self.root()]
        everyone = {t.subsystem for t in net.transitions}
        outside = everyone - set(sl.keep)
        # nodes alike for the group (its places, the channels', the values) are one: what
        # the rest does differently is searched again when it matters
        theirs = frozenset(p.index for p in self.net.places
                           if p.subsystem is not None and p.subsystem not in sl.keep)
        for i, t in enumerate(steps):
            tr = net.transitions[t]
            nxt: dict[frozenset[int], _Node] = {}
            passed = [n for n in layer if t in n.skip]
            for n in passed:
                nxt.setdefault(n.marking, _Node(n.marking, n.parent, n.step, n.skip - {t}))
            layer = [n for n in layer if t not in n.skip]
            if not layer:
                layer = list(nxt.values())
                continue
            chan = chans.get(tr.channel or "")
            if chan is not None and tr.role is Role.RECEIVE and tr.channel in feeds and (
                    chan.full in tr.pre or chan.empty in tr.pre):
                self._receive(layer, t, chan, feeds[chan.name], nxt, feed)
            else:
                for n in layer:
                    self._fire(n, [t], nxt)
                if not nxt:
                    for n in layer:
                        self._fire(n, self.siblings[t], nxt)
                if not nxt and tr.subsystem is None and _waits_outside(net, t, sl.keep):
                    # plumbing waiting for the outside too (an agent's end): passed over
                    continue
                if not nxt:
                    ready = self.search(layer, outside, functools.partial(self._enabled, t=t),
                                        OUTSIDE_STATES)
                    for n in ready:
                        self._fire(n, [t, *self.siblings[t]], nxt)
            if not nxt:
                raise ReplayError(
                    f"with the values tracked, the whole net cannot take step {i + 1} of "
                    f"{len(steps)} of the group, {tr.label}, even after the other "
                    "subsystems' moves")
            alike: dict[frozenset[int], _Node] = {}
            for n in nxt.values():
                alike.setdefault(n.marking - theirs, n)
            layer = list(alike.values())[:LAYER]
        return layer

    def _receive(self, layer: list[_Node], t: int, chan: Channel, feeders: set[str | None],
                 nxt: dict[frozenset[int], _Node], feed: int) -> None:
        """A non-blocking receive from the outside, whichever the slice took: nothing new
        (when the channel is empty), or what the outside sends, any value it can."""
        net = self.source
        tr = net.transitions[t]
        took = chan.full in tr.pre
        take = [t] if took else self._variant_pre(t, chan.empty, chan.full)
        nonew = self._variant_pre(t, chan.full, chan.empty) if took else [t]
        end = _end_of_take(net, take[0]) if take else -1
        for n in layer:
            self._fire(n, nonew, nxt, n.skip | {end} if took else None)
        if not take:
            return
        empty = [n for n in layer if chan.full not in n.marking]
        fed = self.search(empty, feeders, _has(chan.full), feed,
                          every_value=True) if empty else []
        taken: dict[frozenset[int], _Node] = {}
        for n in [*fed, *(n for n in layer if chan.full in n.marking)]:
            self._fire(n, take, taken)
        if took:
            nxt.update(taken)
        else:               # the slice found nothing new: the end of the take now
            for n in taken.values():
                self._fire(n, [end], nxt)

    def _variant_pre(self, t: int, drop: int, add: int) -> list[int]:
        """The step of ``t``'s subsystem taking ``add`` instead of ``drop`` from the same
        places."""
        tr = self.source.transitions[t]
        want = frozenset(tr.pre) - {drop} | {add}
        return [u.index for u in self.source.transitions
                if u.subsystem == tr.subsystem and frozenset(u.pre) == want]

    def _enabled(self, m: frozenset[int], *, t: int) -> bool:
        assert self.net is not None
        pre = self.net.rule.pre
        return any(m.issuperset(pre[u]) for r in (t, *self.siblings[t])
                   for u in self.variants.get(r, ()))

    def stopped(self, searched: int) -> bool:
        """The run's limit reached (polled every 256 markings searched)."""
        return (searched & 255 == 0 and self.budget is not None
                and self.budget.poll() is not None)

    def root(self) -> _Node:
        assert self.net is not None
        return _Node(frozenset(self.net.initial), None, -1)

    def raw(self, marking: frozenset[int]) -> frozenset[int]:
        """A marking of the tracked net as the flat net's (new(x)'s and the values' places
        left out)."""
        origin = self.place_origin
        return frozenset(q for p in marking if (q := origin[p]) is not None)

    def realise(self, steps: Sequence[int], starts: Sequence[_Node],
                ) -> tuple[list[_Node], int | None]:
        """The markings (at most ``LAYER`` per step) reached from ``starts`` by ``steps``
        (the flat net's transitions, or a sibling: another data case) with the values
        tracked; the index of the first step that cannot be taken (the list is then
        empty)."""
        layer = list(starts)
        for i, raw in enumerate(steps):
            nxt: dict[frozenset[int], _Node] = {}
            for node in layer:
                self._fire(node, [raw], nxt)
            if not nxt:
                for node in layer:
                    self._fire(node, self.siblings[raw], nxt)
            if not nxt:
                return [], i
            layer = list(nxt.values())[:LAYER]
        return layer, None

    def after_stall(self, net: FlatNet, starts: Sequence[_Node], to_cycle: Sequence[int],
                    cycle: Sequence[int], stopped: bool,
                    ) -> Counterexample | tuple[_Node, _Node, _Node]:
        """What follows a stuck point with the values tracked, from ``starts`` (the
        markings reached there), the rest's run (``slicing.run_outside``: ``to_cycle``,
        ``cycle``) replayed: when the rest stops too (``stopped``), the deadlock's
        counterexample; else the lasso's start, turn and way back (``lasso``)."""
        if stopped:
            everyone = {t.subsystem for t in net.transitions}
            done, _ = self.realise(to_cycle, starts)
            end = next((n for n in done if not self.moves(n.marking, everyone)), None)
            if end is None:
                raise ReplayError("with the values tracked, the rest of the system does not "
                                  "stop where it stops with tokens only")
            return Counterexample("deadlock", self.steps(end.path()),
                                  marking_labels(net, self.raw(end.marking)),
                                  values=self.values(end.path()))
        found = self.lasso(starts, to_cycle, cycle)
        if found is None:
            raise ReplayError("with the values tracked, what the rest of the system does "
                              "once it is stuck does not repeat")
        return found

    def moves(self, marking: frozenset[int], subsystems: Collection[str | None]) -> bool:
        """Some transition of ``subsystems`` is enabled in ``marking``."""
        assert self.net is not None
        pre = self.net.rule.pre
        return any(t.subsystem in subsystems and marking.issuperset(pre[t.index])
                   for t in self.net.transitions)

    def iterates(self, start: frozenset[int], subsystem: str) -> bool | None:
        """From ``start``, can ``subsystem`` complete an iteration (an ITERATION
        transition of it enabled somewhere)? None: not decided within FUTURE_STATES."""
        assert self.net is not None
        rule = self.net.rule
        iteration = [t.index for t in self.net.transitions
                     if t.subsystem == subsystem and t.role is Role.ITERATION]
        seen = {start}
        frontier = [start]
        while frontier:
            nxt = []
            for m in frontier:
                if any(m.issuperset(rule.pre[u]) for u in iteration):
                    return True
                for u in range(len(rule.pre)):
                    if m.issuperset(rule.pre[u]):
                        m2 = m.difference(rule.consume[u]).union(rule.produce[u])
                        if m2 not in seen:
                            if len(seen) >= FUTURE_STATES or self.stopped(len(seen)):
                                return None
                            seen.add(m2)
                            nxt.append(m2)
            frontier = nxt
        return False

    def lasso(self, starts: Sequence[_Node], to_cycle: Sequence[int],
              cycle: Sequence[int]) -> tuple[_Node, _Node, _Node] | None:
        """``to_cycle`` then ``cycle`` from one of ``starts``, the cycle back to the marking
        it started from (with its values), in one pass or, after one more, in the next:
        the start, the node where the cycle starts and where it ends; None."""
        for start in starts[:LAYER // 4]:
            ends, _ = self.realise(to_cycle, [start])
            for at in ends[:LAYER // 4]:
                after, _ = self.realise(cycle, [at])
                back = next((n for n in after if n.marking == at.marking), None)
                if back is not None:
                    return start, at, back
                for again in after[:LAYER // 4]:
                    twice, _ = self.realise(cycle, [again])
                    back = next((n for n in twice if n.marking == again.marking), None)
                    if back is not None:
                        return start, again, back
        return None

    def label(self, net: FlatNet, steps: Sequence[int], i: int) -> str:
        return f"step {i + 1} of {len(steps)}, {net.transitions[steps[i]].label}"


class _Lifted:
    """The violations of the slices as the whole net's firing sequences."""

    def __init__(self, net: FlatNet, whole: _Whole | None = None) -> None:
        self.net = net
        self.whole = whole if whole is not None else _Whole(net, None)
        self.deadlocks: list[Counterexample] = []
        self.progress: list[Counterexample] = []
        self.unsafe: Counterexample | None = None
        self.failed: list[Unconfirmed] = []
        self.cut_by: list[tuple[str, ...]] = []

    def _steps(self, steps: Sequence[int]) -> tuple[FlatTransition, ...]:
        return tuple(self.net.transitions[t] for t in steps)

    def _labels(self, m: frozenset[int]) -> tuple[str, ...]:
        return marking_labels(self.net, m)

    def slice_deadlock(self, sl: Slice, cx: Counterexample) -> None:
        if self.whole.net is not None:
            self._deadlock_with_values(sl, cx)
            return
        net = self.net
        steps, m = replay_group(sl, sl.whole_steps(cx.steps))
        stuck = [s for s in sl.net.subsystems if live_places(net, s) & _mask(m)]
        if not stuck:
            return                  # the group has finished; the rest decides
        rule = net.rule
        if any(t.subsystem in sl.keep and m.issuperset(rule.pre[t.index])
               for t in net.transitions):
            raise ReplayError("after the group's steps, the group can still move in the "
                              "whole net")
        to_cycle, cycle, stopped = run_outside(net, m, sl.keep)
        if stopped:
            end = fire_steps(net, m, to_cycle)
            self.deadlocks.append(Counterexample("deadlock", self._steps(steps + to_cycle),
                                                 self._labels(end)))
            return
        at_cycle = fire_steps(net, m, to_cycle)
        for s in stuck:
            self.progress.append(Counterexample(
                "progress", self._steps(steps), self._labels(m), subsystem=s,
                where=marking_where(self.net, m),
                to_cycle=self._steps(to_cycle), cycle=self._steps(cycle),
                cycle_marking=self._labels(at_cycle)))

    def _deadlock_with_values(self, sl: Slice, cx: Counterexample) -> None:
        """A stuck group lifted with the values tracked (``_Whole.replay``). The group's
        moves wait on nothing outside it (its channels to the rest are free, and what it
        reads from them it reads whatever the value), so once none of them is enabled in
        the whole net, none ever is: the group is stuck for good."""
        w, net = self.whole, self.net
        ends = w.replay(sl, sl.whole_steps(cx.steps))
        live = {s: live_places(net, s) for s in sl.net.subsystems}
        at = [n for n in ends if not w.moves(n.marking, sl.keep)]
        if not at:
            raise ReplayError("with the values tracked, the group can still move in the "
                              "whole net after its steps")
        m = w.raw(at[0].marking)
        stuck = [s for s in sl.net.subsystems if live[s] & _mask(m)]
        if not stuck:
            return                  # the group has finished; the rest decides
        to_cycle, cycle, stopped = run_outside(net, m, sl.keep)
        after = w.after_stall(net, at, to_cycle, cycle, stopped)
        if isinstance(after, Counterexample):
            self.deadlocks.append(after)
            return
        start, turn, back = after
        prefix = start.path()
        into = turn.path()
        m = w.raw(start.marking)
        stuck = [s for s in sl.net.subsystems if live[s] & _mask(m)]
        for s in stuck:
            self.progress.append(Counterexample(
                "progress", w.steps(prefix), self._labels(m), subsystem=s,
                where=marking_where(net, m), to_cycle=w.steps(into[len(prefix):]),
                cycle=w.steps(back.path()[len(into):]), values=w.values(back.path()),
                cycle_marking=self._labels(w.raw(turn.marking))))

    def slice_progress(self, sl: Slice, cx: Counterexample) -> None:
        steps, m = replay_group(sl, sl.whole_steps(cx.steps))
        to_cycle, at = replay_group(sl, sl.whole_steps(cx.to_cycle), m)
        group_cycle = sl.whole_steps(cx.cycle)
        seen = {at: len(to_cycle)}
        passes: list[int] = list(to_cycle)
        for _ in range(CYCLE_PASSES):
            fired, at = replay_group(sl, group_cycle, at)
            passes += fired
            if at in seen:
                k = seen[at]
                if self.whole.net is not None and cx.subsystem is not None:
                    self._progress_with_values(sl, cx, passes[:k], passes[k:])
                    return
                self.progress.append(Counterexample(
                    "progress", self._steps(steps), self._labels(m), subsystem=cx.subsystem,
                    where=marking_where(self.net, m),
                    to_cycle=self._steps(passes[:k]), cycle=self._steps(passes[k:]),
                    cycle_marking=self._labels(at)))
                return
            seen[at] = len(passes)
        raise ReplayError(f"the cycle of {cx.subsystem} does not repeat in the whole net "
                          f"within {CYCLE_PASSES} passes")

    def _progress_with_values(self, sl: Slice, cx: Counterexample, to_cycle: Sequence[int],
                              cycle: Sequence[int]) -> None:
        """The slice's loss of progress lifted with the values tracked: its steps
        (``_Whole.replay``), the claim that the subsystem never iterates again checked in
        the whole net (the values the slice left free may let it go on), the cycle."""
        assert cx.subsystem is not None
        subsystem = cx.subsystem
        w = self.whole
        starts = w.replay(sl, sl.whole_steps(cx.steps))[:4]
        never = []
        undecided = False
        for n in starts:
            verdict = self.whole.iterates(n.marking, subsystem)
            if verdict is False:
                never.append(n)
            undecided |= verdict is None
        if not never:
            raise ReplayError(
                f"with the values tracked, whether {subsystem} iterates again from there "
                f"is not decided within {FUTURE_STATES:,} markings of the whole net"
                if undecided else
                f"with the values tracked, {subsystem} can still iterate in the whole net")
        found = w.lasso(never, to_cycle, cycle)
        if found is None:
            raise ReplayError("with the values tracked, the cycle does not repeat in the "
                              "whole net")
        start, turn, back = found
        prefix, into = start.path(), turn.path()
        m = w.raw(start.marking)
        self.progress.append(Counterexample(
            "progress", w.steps(prefix), self._labels(m), subsystem=subsystem,
            where=marking_where(self.net, m), to_cycle=w.steps(into[len(prefix):]),
            cycle=w.steps(back.path()[len(into):]), values=w.values(back.path()),
            cycle_marking=self._labels(w.raw(turn.marking))))

    def slice_unsafe(self, sl: Slice, cx: Counterexample) -> None:
        net = self.net
        group_steps = sl.whole_steps(cx.steps)
        if not group_steps:
            raise ReplayError("the unsafe firing is the environment's")
        steps, m = replay_group(sl, group_steps[:-1])
        last = group_steps[-1]
        if not m.issuperset(net.transitions[last].pre):
            raise ReplayError(f"{net.transitions[last].label} cannot fire")
        doubled = frozenset(net.rule.produce[last]) & m
        if not doubled:
            raise ReplayError("the last firing puts no second token anywhere in the whole net")
        if self.whole.net is not None:
            ends = self.whole.replay(sl, group_steps)
            steps = [self.whole.origin[u] for u in ends[0].path()[:-1]]
            last = self.whole.origin[ends[0].path()[-1]]
            m = self.whole.raw(ends[0].parent.marking if ends[0].parent else ends[0].marking)
            doubled = frozenset(net.rule.produce[last]) & m
            if not doubled:
                raise ReplayError("with the values tracked, the last firing puts no second "
                                  "token anywhere in the whole net")
        self.unsafe = Counterexample("unsafe", self._steps([*steps, last]), self._labels(m),
                                     doubled=self._labels(doubled))

    def lift(self, what: str, fn: Callable[[Slice, Counterexample], None], sl: Slice,
             cx: Counterexample) -> None:
        try:
            fn(sl, cx)
        except ReplayError as e:
            if self.whole.net is not None:
                tried = ("the group's steps replayed in the whole net with the values tracked: "
                         "where the slice's environment wrote data, the subsystems outside "
                         "that produce it run until they have sent some, any value they can "
                         f"(up to {FEED_STATES[-1]:,} markings each time); wherever a step was "
                         f"not enabled, a search of up to {OUTSIDE_STATES:,} markings of the "
                         "other subsystems' moves")
            else:
                tried = ("the group's steps replayed in the whole net with the other "
                         "subsystems standing still, and wherever a step was not enabled a "
                         f"search of up to {OUTSIDE_STATES:,} markings of their moves")
            if sl.whole_inside:
                tried += ("; the slice again with the free channels inside the group whole ("
                          + ", ".join(sl.whole_inside) + ")")
            self.failed.append(Unconfirmed(cx.kind, what, tuple(sorted(sl.keep)), str(e),
                                           tried, cx))
            self.cut_by.append(sl.cut)

    def without_trace(self, sl: Slice, r: VerifyReport) -> None:
        """What a slice's compositional check found without a firing sequence (a stuck
        group, a loss of progress): nothing to lift, so unconfirmed."""
        tried = ("the slice's compositional check found it; no firing sequence of the slice "
                 "leading to it was found within the limits, so there is nothing to replay in "
                 "the whole net")
        group = tuple(sorted(sl.keep))
        if r.deadlock_free is False and not r.deadlocks:
            self.failed.append(Unconfirmed("deadlock", "a stuck group", group,
                                           "no firing sequence to lift", tried, None))
        for s in r.progress_lost:
            self.failed.append(Unconfirmed("progress", f"a loss of progress of {s}", group,
                                           "no firing sequence to lift", tried, None))

    def slice_stall(self, sl: Slice, cx: Counterexample) -> None:
        """A subsystem an empty siphon stops for good in the slice (siphons.py)."""
        deadlocks, progress = lift_stall(self.net, self.whole, sl, cx)
        self.deadlocks += deadlocks
        self.progress += progress

    def lift_all(self, sl: Slice, r: VerifyReport) -> None:
        """Every violation of ``sl``'s report ``r``."""
        for cx in r.deadlocks:
            self.lift("a stuck group", self.slice_deadlock, sl, cx)
        for cx in r.progress:
            self.lift(f"a loss of progress of {cx.subsystem}",
                      self.slice_stall if cx.kind == STALL else self.slice_progress, sl, cx)
        if r.unsafe is not None:
            self.lift("an unsafe firing", self.slice_unsafe, sl, r.unsafe)


def _has(place: int) -> Callable[[frozenset[int]], bool]:
    def has(m: frozenset[int]) -> bool:
        return place in m
    return has


def _upstream(net: FlatNet, c: Channel, group: frozenset[str],
              chans: dict[str, Channel]) -> set[str | None]:
    """The subsystems outside ``group`` that can make ``c``'s producer send something new:
    the producer, and whoever feeds it (outside the group), transitively."""
    out: set[str | None] = set()
    todo = [c.producer]
    while todo:
        s = todo.pop()
        if s is None or s in out or s in group:
            continue
        out.add(s)
        todo += [d.producer for d in chans.values() if d.consumer == s]
    return out


def _end_of_take(net: FlatNet, take: int) -> int:
    """The step after a receive's ``in + full -> op``: the one from its op place."""
    op = set(net.transitions[take].post)
    sub = net.transitions[take].subsystem
    return next((u.index for u in net.transitions
                 if u.subsystem == sub and set(u.pre) == op), -1)


def _waits_outside(net: FlatNet, t: int, group: frozenset[str]) -> bool:
    return any(net.places[p].subsystem is not None and net.places[p].subsystem not in group
               for p in net.transitions[t].pre)


def _names(group: Collection[str], shown: int = 4) -> str:
    """A group's subsystems for a note: all of a small group, the first few of a large one
    (a ring of 100 agents would fill the report)."""
    names = sorted(group)
    if len(names) <= shown + 1:
        return ", ".join(names)
    return f"{', '.join(names[:shown])} and {len(names) - shown} more"


def _mask(m: frozenset[int]) -> int:
    out = 0
    for p in m:
        out |= 1 << p
    return out


def _combine(net: FlatNet, groups: Sequence[tuple[str, ...]],
             parts: list[tuple[Slice, VerifyReport]], budget: Budget, start: float,
             check_progress: bool, whole: _Whole | None = None,
             refined: Sequence[str] = ()) -> VerifyReport:
    lifted = _Lifted(net, whole)
    for sl, r in parts:
        lifted.lift_all(sl, r)
        lifted.without_trace(sl, r)
    reports = [r for _, r in parts]
    done = len(parts) == len(groups)
    safe, deadlock_free, progress_ok, verdict = _verdicts(reports, lifted, done, check_progress)
    shared = [f"{_names(g)} ({r.method}, {r.states:,} states)"
              for g, (_, r) in zip(groups, parts, strict=False) if len(g) > 1]
    alone = [r.states for g, (_, r) in zip(groups, parts, strict=False) if len(g) == 1]
    if alone:
        shared.append(f"{len(alone)} subsystem(s) alone ({sum(alone):,} states in all)")
    notes = ["sliced at the channels nobody waits on: "
             f"{len(groups)} blocking group(s), each verified on its own: " + "; ".join(shared)]
    notes += refined
    notes += [u.headline() for u in lifted.failed]
    for (sl, r) in parts:
        if len(sl.keep) == 1 and r.verdict is not Verdict.INCONCLUSIVE:
            continue            # the free-running ones: their notes say nothing new
        label = _names(sl.keep)
        notes += [f"[{label}] {n}" for n in r.notes]
    why = next((r.why_undecided for r in reports if r.why_undecided), None)
    if why is None and lifted.failed:
        why = _open(lifted.failed)
    if why is None and not done:
        why = "not every group was verified"
    dead = None
    if all(r.dead_transitions is not None for r in reports) and done:
        dead = tuple(sorted({sl.transition_of[t.index]: net.transitions[sl.transition_of[
            t.index]] for sl, r in parts for t in (r.dead_transitions or ())
            if sl.transition_of[t.index] >= 0}.values(), key=lambda t: t.index))
    unreachable = None
    if all(r.unreachable_behaviours is not None for r in reports) and done:
        unreachable = tuple(dict.fromkeys(b for r in reports
                                          for b in (r.unreachable_behaviours or ())))
    free = {c.text(): c for r in reports for c in r.free_conditions}
    return VerifyReport(
        system=net.system,
        verdict=verdict,
        safe=safe,
        safe_by=("slices: " + ", ".join(sorted({r.safe_by for r in reports if r.safe_by})))
        if safe else ("found in a slice, replayed in the whole net" if safe is False else None),
        invariants=tuple(i for r in reports for i in r.invariants),
        invariants_complete=done and all(r.invariants_complete for r in reports),
        invariants_message="; ".join(dict.fromkeys(r.invariants_message for r in reports
                                                   if r.invariants_message)) or None,
        uncovered_places=_uncovered(parts),
        method="sliced(" + "+".join(dict.fromkeys(r.method for r in reports)) + ")",
        states=sum(r.states for r in reports),
        edges=sum(r.edges for r in reports),
        depth=max((r.depth for r in reports), default=0),
        complete=done and all(r.complete for r in reports),
        deadlock_free=deadlock_free,
        deadlock_count=len(lifted.deadlocks),
        deadlocks=tuple(lifted.deadlocks),
        unsafe=lifted.unsafe,
        progress_ok=progress_ok if check_progress else None,
        progress=tuple({c.subsystem: c for c in reversed(lifted.progress)}.values())[::-1],
        progress_checked=tuple(s for r in reports for s in r.progress_checked),
        progress_lost=(),       # a slice's, without a trace: unconfirmed (without_trace)
        dead_transitions=dead,
        unreachable_behaviours=unreachable,
        seconds=time.monotonic() - start,
        notes=tuple(notes),
        stop=budget.stop,
        progress_requested=check_progress,
        fairness=reports[0].fairness if reports else "strong",
        why_undecided=why if verdict is Verdict.INCONCLUSIVE else None,
        time_limit=budget.time_limit,
        max_memory=budget.max_memory,
        peak_memory=budget.peak_resident(),
        new_tracked_cases=sum(r.new_tracked_cases for r in reports),
        free_conditions=tuple(free.values()),
        tracked_values=tuple(sorted({v for r in reports for v in r.tracked_values})),
        groups=tuple((tuple(sorted(sl.keep)), True if r.deadlocks else (
            False if r.deadlock_free else None)) for sl, r in parts),
        unconfirmed=tuple(lifted.failed) if verdict is Verdict.INCONCLUSIVE else (),
    )


def _open(failed: Sequence[Unconfirmed]) -> str:
    """Why the verdict is open: the violations found in slices that the whole net did not
    confirm, each named."""
    shown = [f"{u.what} found in the slice of {_names(u.group)} was not confirmed in the "
             "whole net" for u in failed[:2]]
    more = f" and {len(failed) - 2} more" if len(failed) > 2 else ""
    return "; ".join(dict.fromkeys(shown)) + more


def _verdicts(reports: list[VerifyReport], lifted: _Lifted, done: bool, check_progress: bool,
              ) -> tuple[bool | None, bool | None, bool | None, Verdict]:
    """Safeness, deadlock freedom, progress and the verdict of the whole net from its
    slices' reports and the violations lifted back (the module docstring)."""
    # a slice's violation counts only once replayed in the whole net
    safe = False if lifted.unsafe is not None else _all(
        [True if r.safe else None for r in reports], done)
    deadlock_free: bool | None
    if lifted.deadlocks:
        deadlock_free = False
    elif any(r.deadlock_free for r in reports):
        # one deadlock-free slice: the whole net is (a slice's deadlock, with or without a
        # firing sequence, proves nothing of the whole net until it is lifted)
        deadlock_free = True
    else:
        deadlock_free = None
    stuck_groups = any(r.deadlocks for r in reports)
    progress_ok: bool | None
    if lifted.progress:
        progress_ok = False
    elif check_progress and not stuck_groups and not lifted.failed:
        progress_ok = _all([r.progress_ok for r in reports], done)
    else:
        progress_ok = None
    violated = safe is False or deadlock_free is False or progress_ok is False
    if violated:
        verdict = Verdict.VIOLATED
    elif safe and deadlock_free and progress_ok:
        verdict = Verdict.VERIFIED
    elif safe and deadlock_free and not check_progress:
        verdict = Verdict.VERIFIED_WITHOUT_PROGRESS
    else:
        verdict = Verdict.INCONCLUSIVE
    return safe, deadlock_free, progress_ok, verdict


def _uncovered(parts: list[tuple[Slice, VerifyReport]]) -> tuple[str, ...]:
    """The places no slice's invariants prove safe (a slice's invariant bounds its places in
    the whole net too: the slice can do whatever its group does there)."""
    proved: set[str] = set()
    for sl, r in parts:
        open_ = set(r.uncovered_places)
        proved.update(p.label or p.name for p in sl.net.places
                      if (p.label or p.name) not in open_)
    return tuple(dict.fromkeys(p for _, r in parts for p in r.uncovered_places
                               if p not in proved))


def _all(values: list[bool | None], done: bool) -> bool | None:
    if any(v is False for v in values):
        return False
    if done and all(v is True for v in values):
        return True
    return None

