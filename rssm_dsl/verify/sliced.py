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

A violation whose replay fails is not reported as a violation; the report says so and the
verdict stays open.
"""

from __future__ import annotations

import dataclasses
import time
from collections.abc import Callable, Collection, Sequence
from typing import TYPE_CHECKING

from rssm_dsl.hpn.flat import FlatNet, FlatTransition, Role
from rssm_dsl.verify.budget import Budget
from rssm_dsl.verify.progress import live_places
from rssm_dsl.verify.report import (
    Counterexample,
    Verdict,
    VerifyReport,
    marking_labels,
    marking_where,
)
from rssm_dsl.verify.slicing import ReplayError, Slice, replay_group, run_outside, slice_net
from rssm_dsl.verify.stalls import StallTest

if TYPE_CHECKING:
    from rssm_dsl.verify.verifier import VerifyOptions

Verifier = Callable[[FlatNet, "VerifyOptions"], VerifyReport]
CYCLE_PASSES = 6            # replays of a slice's cycle to find the whole net's cycle
STUBBORN_STATES = 100_000   # a slice's stubborn-set search at most
SMALL_SLICE = 10_000        # a slice explored whole when it has no more states
COMPOSE_SHARE = 1 / 2       # of the time left, for each later try on a slice
MANY = 4                    # subsystems: a group of this many is composed first


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
        r = _decide(sl, opts if check_progress else quick, verify)
        if r.verdict is Verdict.INCONCLUSIVE and check_progress and budget.stop is None:
            # progress not decided: at least safeness and deadlocks
            first = _decide(sl, quick, verify)
            r = dataclasses.replace(first, progress_requested=True, verdict=(
                first.verdict if first.verdict is Verdict.VIOLATED else Verdict.INCONCLUSIVE),
                notes=(*r.notes, *first.notes), why_undecided=r.why_undecided)
        found[i] = r
    parts = [(slices[i], found[i]) for i in range(len(slices)) if i in found]
    return _combine(net, groups, parts, budget, start, check_progress)


def _decide(sl: Slice, opts: VerifyOptions, verify: Verifier) -> VerifyReport:
    """A slice's report: explored whole when it is small (``SMALL_SLICE`` states: dead
    transitions and unreachable behaviours come with it), else by stubborn sets (with
    counterexamples) up to ``STUBBORN_STATES`` states; a slice they do not decide within
    that leaves the sliced verdict open, and ``verify`` goes on with the whole net."""
    small = verify(sl.net, dataclasses.replace(opts, reduction="off", max_states=SMALL_SLICE))
    if small.complete or small.verdict is Verdict.VIOLATED:
        return small
    cap = min(opts.max_states, STUBBORN_STATES)
    return verify(sl.net, dataclasses.replace(opts, max_states=cap))


def _by_deadlocks(sl: Slice, quick: VerifyOptions, budget: Budget,
                  verify: Verifier) -> VerifyReport:
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
            progress_checked=checked, notes=(*r.notes, (
                "progress follows from deadlock freedom: no subsystem of the group can run "
                "on once another stops iterating, so a loss of progress would be a deadlock "
                "of the slice")))
    return dataclasses.replace(r, progress_requested=True)


class _Lifted:
    """The violations of the slices as the whole net's firing sequences."""

    def __init__(self, net: FlatNet) -> None:
        self.net = net
        self.deadlocks: list[Counterexample] = []
        self.progress: list[Counterexample] = []
        self.unsafe: Counterexample | None = None
        self.failed: list[str] = []

    def _steps(self, steps: Sequence[int]) -> tuple[FlatTransition, ...]:
        return tuple(self.net.transitions[t] for t in steps)

    def _labels(self, m: frozenset[int]) -> tuple[str, ...]:
        return marking_labels(self.net, m)

    def slice_deadlock(self, sl: Slice, cx: Counterexample) -> None:
        net = self.net
        steps, m = replay_group(sl, sl.whole_steps(cx.steps))
        stuck = [s for s in sl.net.subsystems if live_places(net, s) & _mask(m)]
        if not stuck:
            return                  # the group has finished; the rest decides
        to_cycle, cycle, stopped = run_outside(net, m, sl.keep)
        if stopped:
            end = _fire(net, m, to_cycle)
            self.deadlocks.append(Counterexample("deadlock", self._steps(steps + to_cycle),
                                                 self._labels(end)))
            return
        at_cycle = _fire(net, m, to_cycle)
        for s in stuck:
            self.progress.append(Counterexample(
                "progress", self._steps(steps), self._labels(m), subsystem=s,
                where=marking_where(self.net, m),
                to_cycle=self._steps(to_cycle), cycle=self._steps(cycle),
                cycle_marking=self._labels(at_cycle)))

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
                self.progress.append(Counterexample(
                    "progress", self._steps(steps), self._labels(m), subsystem=cx.subsystem,
                    where=marking_where(self.net, m),
                    to_cycle=self._steps(passes[:k]), cycle=self._steps(passes[k:]),
                    cycle_marking=self._labels(at)))
                return
            seen[at] = len(passes)
        raise ReplayError(f"the cycle of {cx.subsystem} does not repeat in the whole net "
                          f"within {CYCLE_PASSES} passes")

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
        self.unsafe = Counterexample("unsafe", self._steps([*steps, last]), self._labels(m),
                                     doubled=self._labels(doubled))

    def lift(self, what: str, fn: Callable[[Slice, Counterexample], None], sl: Slice,
             cx: Counterexample) -> None:
        try:
            fn(sl, cx)
        except ReplayError as e:
            self.failed.append(f"{what} found in the slice of {_names(sl.keep)} "
                               f"was not reproduced in the whole net: {e}")


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


def _fire(net: FlatNet, m: frozenset[int], steps: Sequence[int]) -> frozenset[int]:
    rule = net.rule
    out = set(m)
    for t in steps:
        out.difference_update(rule.consume[t])
        out.update(rule.produce[t])
    return frozenset(out)


def _combine(net: FlatNet, groups: Sequence[tuple[str, ...]],
             parts: list[tuple[Slice, VerifyReport]], budget: Budget, start: float,
             check_progress: bool) -> VerifyReport:
    lifted = _Lifted(net)
    for sl, r in parts:
        for cx in r.deadlocks:
            lifted.lift("a stuck group", lifted.slice_deadlock, sl, cx)
        for cx in r.progress:
            lifted.lift(f"a loss of progress of {cx.subsystem}", lifted.slice_progress, sl, cx)
        if r.unsafe is not None:
            lifted.lift("an unsafe firing", lifted.slice_unsafe, sl, r.unsafe)
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
    notes += lifted.failed
    for (sl, r) in parts:
        if len(sl.keep) == 1 and r.verdict is not Verdict.INCONCLUSIVE:
            continue            # the free-running ones: their notes say nothing new
        label = _names(sl.keep)
        notes += [f"[{label}] {n}" for n in r.notes]
    why = next((r.why_undecided for r in reports if r.why_undecided), None)
    if why is None and lifted.failed:
        why = "a violation found in a slice was not reproduced in the whole net"
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
        progress_lost=tuple(s for r in reports for s in r.progress_lost),
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
        peak_memory=max(budget.peak, budget.resident()),
        new_tracked_cases=sum(r.new_tracked_cases for r in reports),
        free_conditions=tuple(free.values()),
        tracked_values=tuple(sorted({v for r in reports for v in r.tracked_values})),
        groups=tuple((tuple(sorted(sl.keep)), True if r.deadlocks else (
            False if r.deadlock_free else None)) for sl, r in parts),
    )


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
    elif any(r.deadlock_free for r in reports) or (
            done and all(r.deadlock_free is not None for r in reports)
            and not any(r.deadlocks for r in reports)):
        deadlock_free = True
    else:
        deadlock_free = None
    stuck_groups = any(r.deadlocks for r in reports)
    progress_ok: bool | None
    if lifted.progress or any(r.progress_lost for r in reports):
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

