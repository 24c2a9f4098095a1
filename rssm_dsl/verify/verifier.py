"""``verify(net, options)``: place invariants, then the state space, then the verdict.

Pipeline:

1. Minimal P-semiflows (``invariants``). If the invariants carrying one token cover every
   place, the net is safe without exploring a state; either way the places they prove safe
   need no watching in the reduced search.
2. State space, by ``options.reduction``:
   - ``"off"``: full breadth-first exploration (``statespace``) with the reachability graph:
     safeness, deadlocks, dead transitions, unreachable behaviours, progress (``progress``).
   - ``"on"``: stubborn-set exploration only (``stubborn``): exact deadlock and safeness
     verdicts on far fewer states; with ``check_progress`` the search applies the cycle
     proviso and keeps its graph, on which progress is decided (see ``stubborn``); dead
     transitions and unreachable behaviours are not computed (the report says so).
   - ``"compositional"``: the compositional check only (``compose``): the net is rebuilt
     page by page, each piece reduced modulo divergence-preserving branching bisimilarity
     once what it hides is hidden. Exact safeness, deadlock and progress verdicts and the
     reachable behaviours, without counterexamples and without dead transitions.
   - ``"auto"`` (default): a first full exploration, ``slice_after_seconds`` and
     ``slice_after_states`` at most; a net that does not fit and has several blocking groups
     is verified group by group (``sliced``: each slice explored whole when small, else by
     stubborn sets; violations replayed in the whole net), with two thirds of the time left;
     when that leaves the verdict open, the whole net: full exploration up to
     ``auto_full_states`` markings (and ``auto_full_words`` of memory; it gives dead
     transitions and unreachable behaviours too; 0: none), then the compositional check;
     the stubborn-set search (as for ``"on"``) runs when that gives no verdict, or to find
     a counterexample for a violation it found.
3. Verdict: *violated* when any violation was found (a found deadlock or unsafe firing is real
   even if the search was cut short); *verified* when safeness, deadlock freedom and progress
   are all established; *verified without progress* when safeness and deadlock freedom are
   and progress was not asked for (``check_progress=False``); otherwise *inconclusive*, with
   the reason (``why_undecided``) and the notes.

Limits: one ``Budget`` (``budget.py``: deadline, memory limit, Ctrl-C) is shared by every phase;
the first limit reached ends the run (``report.stop``: which limit, in which phase), and what
was decided before it stands.

A marking is *final* when the net has final places and all of them are marked; a deadlock in
a final marking is the system having finished, not an error.
"""

from __future__ import annotations

import contextlib
import dataclasses
import time
from collections.abc import Collection, Sequence
from typing import TYPE_CHECKING

from rssm_core.records import dataclass
from rssm_dsl.hpn.flat import FlatNet, FlatTransition, Role
from rssm_dsl.verify.budget import Budget, LimitReached
from rssm_dsl.verify.compose.check import ComposeResult, compose_check
from rssm_dsl.verify.cover import one_token_semiflows
from rssm_dsl.verify.datanet import track_new
from rssm_dsl.verify.deadmarking import dead_markings
from rssm_dsl.verify.invariants import DEFAULT_MAX_ROWS, InvariantResult, place_invariants
from rssm_dsl.verify.netbits import NetBits, bits, to_mask
from rssm_dsl.verify.progress import check_progress, subsystems_of
from rssm_dsl.verify.report import (
    FAIRNESS,
    Counterexample,
    InvariantLine,
    Verdict,
    VerifyReport,
    marking_labels,
    marking_where,
)
from rssm_dsl.verify.sliced import verify_sliced
from rssm_dsl.verify.slicing import blocking_groups
from rssm_dsl.verify.stalls import StallTest
from rssm_dsl.verify.statespace import Graph, ProgressCallback, SearchResult, Trace, explore_full
from rssm_dsl.verify.stubborn import explore_reduced
from rssm_dsl.verify.valuenet import track_values

if TYPE_CHECKING:
    from rssm_dsl.verify.dataplan import ValuePlan

REDUCTIONS = ("auto", "on", "off", "compositional")
SMALL_NET = 400        # places: below, the minimal semiflows are always enumerated
SLICES_SHARE = 2 / 3   # of the time left, for the sliced verification (the rest: whole net)
ABSTRACT_SHARE = 1 / 3  # of the time left, for the pass with the conditions as free choices
PROPERTIES_SHARE = 0.4  # of the run's time, kept for the properties stated in the spec


@dataclass(frozen=True)
class VerifyOptions:
    max_states: int = 5_000_000          # per exploration (per composition, compositionally)
    auto_full_states: int = 1_000_000    # "auto": the full search's share before the others
    #                                      (0: none, the compositional check first)
    auto_full_words: int = 16_000_000    # ... and its memory share, in 64-bit marking words
    time_limit: float | None = 300.0     # seconds for the whole verification
    reduction: str = "auto"              # "auto", "on" (stubborn sets), "off" (full only),
    #                                      "compositional"
    invariants: bool = True
    max_invariant_rows: int = DEFAULT_MAX_ROWS
    invariant_time: float = 5.0          # seconds at most for the place invariants
    check_progress: bool = True
    max_counterexamples: int = 3
    on_progress: ProgressCallback | None = None
    max_memory: int | None = None        # bytes resident at most (None: no limit)
    budget: Budget | None = None         # the run's limits; replaces time_limit and max_memory
    slicing: bool = True                 # "auto": blocking groups verified one by one (sliced)
    slice_after_states: int = 200_000    # ... when the whole net has more states than this
    slice_after_seconds: float = 0.75    # ... or takes longer to explore
    values: ValuePlan | None = None      # the finite values to track (dataplan.value_plan)
    guards: ValuePlan | None = None      # without values: the guards over parameters alone
    #                                      decided (the pass with the free choices)
    fairness: str = "strong"             # progress: "strong" or "weak" (report.FAIRNESS)
    values_first: bool = True            # ... only once the conditions as free choices
    #                                      gave a violation (verify_with_values)
    stall_shortcut: bool = True          # one blocking group of every subsystem that stalls
    #                                      together: progress from deadlock freedom
    dead_markings: bool = True           # "auto": deadlock freedom from the place invariants
    #                                      when they allow no dead marking (deadmarking.py)

    def __post_init__(self) -> None:
        if self.fairness not in FAIRNESS:
            raise ValueError(f"fairness must be one of {', '.join(FAIRNESS)}, "
                             f"not {self.fairness!r}")
        if self.reduction not in REDUCTIONS:
            raise ValueError(f"reduction must be one of {', '.join(REDUCTIONS)}, "
                             f"not {self.reduction!r}")


def verify(net: FlatNet, options: VerifyOptions | None = None) -> VerifyReport:
    opts = options or VerifyOptions()
    groups, decided = _first_steps(net, opts)
    if decided is not None:
        return decided
    if opts.slicing and opts.reduction == "auto":
        groups = _groups(net, opts, groups)
        if len(groups) > 1:
            budget = (opts.budget if opts.budget is not None
                      else Budget(opts.time_limit, opts.max_memory))
            # a small net is explored whole (its dead transitions and unreachable behaviours
            # come with it); a larger one group by group
            with budget.capped(opts.slice_after_seconds) as first:
                whole = verify(net, dataclasses.replace(opts, slicing=False, budget=budget,
                                                         reduction="off",
                                                         max_states=opts.slice_after_states))
            # a violation found is one; a try the cap cut short (in its search, or after it
            # in the invariants or the progress check) decides nothing else
            if (whole.verdict is Verdict.VIOLATED or budget.stop is not None
                    or (whole.complete and not first.hit)):
                return dataclasses.replace(whole, stop=budget.stop)
            inner = dataclasses.replace(opts, slicing=False, budget=budget, reduction="on")
            left = budget.remaining()
            # the slices get two thirds of the time left: the whole net may need the rest
            with budget.capped(SLICES_SHARE * left if left is not None else float("inf")), \
                    budget.running("the sliced verification"):
                try:
                    sliced = verify_sliced(net, groups, inner, budget, verify)
                except LimitReached as e:   # a limit no phase of the slices caught (a
                    #                         lift's search): the slices decide nothing
                    sliced = dataclasses.replace(
                        whole, verdict=Verdict.INCONCLUSIVE, notes=(),
                        why_undecided=f"the sliced verification stopped: {e.stop.message}")
            if sliced.verdict is not Verdict.INCONCLUSIVE or budget.stop is not None:
                return dataclasses.replace(sliced, stop=budget.stop)
            # a group the stubborn sets do not decide (rings of many alike subsystems):
            # the whole net, compositionally
            whole = verify(net, dataclasses.replace(opts, slicing=False, budget=budget,
                                                     auto_full_states=0))
            # what the slices found and the whole net did not confirm stays in an open
            # report (the whole net's verdict, when it gives one, settles it)
            return dataclasses.replace(whole, notes=(
                f"sliced verification left the verdict open "
                f"({sliced.why_undecided or 'no slice decided it'}); "
                "the whole net was verified instead", *whole.notes),
                unconfirmed=sliced.unconfirmed
                if whole.verdict is Verdict.INCONCLUSIVE else ())
    # new(x) and the finite values in the net's places (datanet.py, valuenet.py), the report
    # told back in net's words
    with _named(opts.budget, "the data tracking"):
        tracked = (track_values(track_new(net), opts.values) if opts.values is not None
                   else track_values(track_new(net), opts.guards, values=False))
    if tracked.changed:
        return tracked.report(verify(tracked.net, dataclasses.replace(opts, values=None,
                                                                      guards=None)))
    opts = options or VerifyOptions()
    start = time.monotonic()
    budget = opts.budget if opts.budget is not None else Budget(opts.time_limit, opts.max_memory)
    nb = NetBits.of(net)
    notes: list[str] = []
    with budget.running("the place invariants"):
        inv = (_invariants(net, opts, budget, notes) if opts.invariants and not budget.stop
               else None)
    safe_mask = to_mask(inv.safe_places) if inv else 0
    safe_by_invariants = inv is not None and inv.proves_safe(nb.nplaces)
    no_dead = (_no_dead_marking(nb, inv, budget, notes)
               if opts.reduction == "auto" and opts.dead_markings and inv is not None
               and safe_by_invariants and budget.stop is None else False)
    # with deadlock freedom proved and no progress asked, only a quick full exploration
    # (the dead transitions and unreachable behaviours of a small net)
    full, comp, reduced = (_searches(net, nb, opts, safe_mask, budget, notes,
                                     inv.token_flows()[0] if inv is not None else [])
                           if opts.check_progress or not no_dead
                           else (_quick_full(nb, opts, budget), None, None))
    deciding = reduced if reduced is not None else full
    if deciding is None:          # compositional only (or nothing: no_dead)
        deciding = SearchResult("none", 0, 0, 0, False, None, 0.0, [], 0, 0, None)
    by_comp = comp is not None and comp.complete

    unsafe_trace = deciding.unsafe or (full.unsafe if full else None)
    safe, safe_by = _safeness(unsafe_trace, deciding, full, comp, safe_by_invariants)
    dead_traces = deciding.deadlocks or (full.deadlocks if full else [])
    dead_count = max(deciding.deadlock_count, full.deadlock_count if full else 0)
    deadlock_free: bool | None
    if dead_count:
        deadlock_free = False
    elif comp is not None and comp.deadlock_free is False:
        deadlock_free, dead_count = False, 1
        notes.append("the compositional check shows a reachable deadlock; no firing sequence "
                     "leading to it was found within the limits")
    elif deciding.complete or (comp is not None and comp.deadlock_free) or no_dead:
        deadlock_free = True
    else:
        deadlock_free = None

    dead_transitions, unreachable = _dead_parts(net, full, comp, reduced, notes)
    graph = _progress_graph(opts, full, reduced)
    progress = (_progress(net, nb, graph, comp, notes, budget, opts.fairness)
                if opts.check_progress else _Progress())

    violated = safe is False or deadlock_free is False or progress.ok is False
    if violated:
        verdict = Verdict.VIOLATED
    elif safe and deadlock_free and progress.ok:
        verdict = Verdict.VERIFIED
    elif safe and deadlock_free and not opts.check_progress:
        verdict = Verdict.VERIFIED_WITHOUT_PROGRESS
    else:
        verdict = Verdict.INCONCLUSIVE

    method = "+".join(name for name, used in (("full", full), ("compositional", comp),
                                              ("stubborn", reduced)) if used is not None) \
        or ("invariants" if no_dead else "")
    return VerifyReport(
        system=net.system,
        verdict=verdict,
        safe=safe,
        safe_by=safe_by,
        invariants=_invariant_lines(net, inv),
        invariants_complete=inv.complete if inv else False,
        invariants_message=inv.message if inv else "not computed",
        uncovered_places=tuple(net.places[p].label or net.places[p].name
                               for p in (inv.uncovered(nb.nplaces) if inv else
                                         range(nb.nplaces))),
        method=method,
        states=comp.states if by_comp and comp is not None else deciding.states,
        edges=deciding.edges,
        depth=deciding.depth,
        complete=deciding.complete or by_comp,
        deadlock_free=deadlock_free,
        deadlock_count=dead_count,
        deadlocks=tuple(_deadlock_cx(net, nb, t) for t in dead_traces),
        unsafe=_unsafe_cx(net, nb, unsafe_trace) if unsafe_trace else None,
        progress_ok=progress.ok,
        progress=progress.counterexamples,
        progress_checked=progress.checked,
        progress_lost=progress.lost,
        dead_transitions=dead_transitions,
        unreachable_behaviours=unreachable,
        seconds=time.monotonic() - start,
        notes=tuple(notes),
        stop=budget.stop,
        progress_requested=opts.check_progress,
        fairness=opts.fairness,
        why_undecided=_why_undecided(budget, (("the full exploration", full),
                                              ("the compositional check", comp),
                                              ("the stubborn-set exploration", reduced))),
        time_limit=budget.time_limit,
        max_memory=budget.max_memory,
        peak_memory=budget.peak_resident(),
    )


def _groups(net: FlatNet, opts: VerifyOptions,
            known: list[tuple[str, ...]] | None = None) -> list[tuple[str, ...]]:
    """The blocking groups (``known`` when already computed)."""
    if known is not None:
        return known
    with _named(opts.budget, "the slicing"):
        return blocking_groups(net)


def _first_steps(net: FlatNet, opts: VerifyOptions,
                 ) -> tuple[list[tuple[str, ...]] | None, VerifyReport | None]:
    """The blocking groups (when computed), and the report when it is decided here: the
    finite values tracked only where they matter (``_abstraction_first``), or every
    subsystem stalling together or in the stall order (``_stall_argument``: the
    deadlock-only check decides progress)."""
    if opts.values is not None and opts.values_first:
        if opts.budget is None:
            opts = dataclasses.replace(opts, budget=Budget(opts.time_limit, opts.max_memory))
        budget = opts.budget
        assert budget is not None
        left = budget.remaining()
        system = opts.values.system if opts.values is not None else None
        if left is None or system is None or not system.properties or budget.inside_cap:
            return None, _with_properties(net, opts, _abstraction_first(net, opts))
        # the properties keep a share of the time whatever safeness, deadlocks and progress
        # take (a fleet's progress check took a whole run, its properties "not checked");
        # a capped try has its caller's schedule (falsify/orchestrate.py gives the
        # properties a try of their own after it)
        with budget.capped((1 - PROPERTIES_SHARE) * left):
            first = _abstraction_first(net, opts)
        return None, _with_properties(net, opts, first)
    # (a slice, verified with slicing off, has its environment: stalls.py's argument for
    # it is the sliced verification's own)
    if not (opts.check_progress and opts.fairness == "strong" and opts.stall_shortcut
            and opts.slicing):
        return None, None
    groups = _groups(net, opts)
    why = _stall_argument(net, groups, opts)
    if why is None:
        return groups, None
    # the deadlock-only check: the full exploration gets the share a sliced net gives its
    # first try (beyond it, the compositional check, cheap without the per-subsystem
    # compositions, decides sooner)
    quick = verify(net, dataclasses.replace(
        opts, check_progress=False, stall_shortcut=False,
        auto_full_states=min(opts.auto_full_states, opts.slice_after_states)))
    if (quick.verdict is Verdict.VIOLATED and quick.complete
            and quick.method in ("full", "compositional")
            and (opts.budget is None or opts.budget.stop is None)):
        # a deadlock in a net explored whole (or composed whole): its progress check costs
        # little more and says who else loses progress and which behaviours are
        # unreachable (the deadlock stands whatever it finds)
        again = verify(net, dataclasses.replace(opts, stall_shortcut=False))
        if again.verdict is Verdict.VIOLATED:
            return groups, again
    return groups, _progress_from_deadlocks(net, quick, why)


TOGETHER = ("progress follows from deadlock freedom: every subsystem is in one blocking "
            "group, and none can run on once another stops iterating, so a loss of "
            "progress would be a deadlock")


def _stall_argument(net: FlatNet, groups: list[tuple[str, ...]],
                    opts: VerifyOptions) -> str | None:
    """Why progress follows from deadlock freedom, when it does: every subsystem of the
    net in one blocking group that stalls together (stalls.py: no subsystem can run on once
    another stops iterating), or, with the conditions as free choices (the net stalls.py's
    structural test reads), one whose subsystems the stall order proves (a coordinator that
    never waits and robots that wait on it)."""
    if len(groups) != 1 or set(groups[0]) != set(subsystems_of(net)):
        return None
    test = StallTest(net)
    if test.together(groups[0]):
        return TOGETHER
    if opts.values is None and test.ordered(groups[0]) is not None:
        from rssm_dsl.verify.sliced import ORDERED

        return ORDERED
    return None


def _progress_from_deadlocks(net: FlatNet, quick: VerifyReport,
                             why: str = TOGETHER) -> VerifyReport:
    """The report of the deadlock-only check of a net whose subsystems all stall together
    (``_stall_argument``, whose reason is ``why``), with progress decided by it. The argument of stalls.py with the
    group the whole net: a subsystem that loses progress at X leaves, once the group has
    fired what it can (finitely often: nobody iterates for ever without it), a marking where
    none of the group is enabled and it is unfinished; only the plumbing of the agents and
    the system remains, which fires finitely often: a deadlock, which is not final."""
    if quick.verdict is Verdict.VERIFIED_WITHOUT_PROGRESS:
        checked = tuple(s for s in subsystems_of(net) if any(
            t.subsystem == s and t.role is Role.ITERATION for t in net.transitions))
        return dataclasses.replace(
            quick, verdict=Verdict.VERIFIED, progress_ok=True, progress_requested=True,
            progress_checked=checked, notes=(
                *(n for n in quick.notes if "--no-progress-check" not in n), why))
    if quick.verdict is Verdict.INCONCLUSIVE and quick.why_undecided is None:
        return dataclasses.replace(quick, progress_requested=True,
                                   why_undecided="deadlock freedom not decided")
    return dataclasses.replace(quick, progress_requested=True)


def _named(budget: Budget | None, phase: str) -> contextlib.AbstractContextManager[object]:
    """``budget.running(phase)``, or nothing without a budget."""
    return budget.running(phase) if budget is not None else contextlib.nullcontext()


def _with_properties(net: FlatNet, opts: VerifyOptions, report: VerifyReport) -> VerifyReport:
    """The report with the properties stated in the spec checked (userprops.py): a violated
    one makes the verdict VIOLATED, one not decided leaves a verification open."""
    from rssm_dsl.verify.userprops import check_properties

    system = opts.values.system if opts.values is not None else None
    if system is None or not system.properties:
        return report
    assert opts.budget is not None
    start = time.monotonic()
    results = check_properties(net, system, opts.values, opts.budget, opts.max_states,
                               opts.reduction)
    spent = time.monotonic() - start        # the report's seconds count the properties too
    verdict, why = report.verdict, report.why_undecided
    if any(r.holds is False for r in results):
        verdict = Verdict.VIOLATED
    elif any(r.holds is None for r in results) and verdict in (
            Verdict.VERIFIED, Verdict.VERIFIED_WITHOUT_PROGRESS):
        verdict = Verdict.INCONCLUSIVE
        why = next(f"property {r.name}: {r.why}" for r in results if r.holds is None)
    return dataclasses.replace(report, verdict=verdict, why_undecided=why,
                               user_properties=results, stop=opts.budget.stop,
                               seconds=report.seconds + spent)


def properties_again(net: FlatNet, opts: VerifyOptions, report: VerifyReport) -> VerifyReport:
    """``report`` with the properties a shorter try left not decided checked again with
    ``opts.budget``'s time; the rest of the report stands (the caller knows the system is
    violated: the random runs found it)."""
    from rssm_dsl.verify.userprops import check_properties

    system = opts.values.system if opts.values is not None else None
    open_ = {r.name for r in report.user_properties if r.holds is None}
    if system is None or not open_:
        return report
    assert opts.budget is not None
    start = time.monotonic()
    some = dataclasses.replace(system, properties=tuple(p for p in system.properties
                                                        if p.name in open_))
    got = {r.name: r for r in check_properties(net, some, opts.values, opts.budget,
                                               opts.max_states, opts.reduction)}
    return dataclasses.replace(
        report, user_properties=tuple(got.get(r.name, r) for r in report.user_properties),
        seconds=report.seconds + time.monotonic() - start)


def _abstraction_first(net: FlatNet, opts: VerifyOptions) -> VerifyReport:
    """The finite values tracked only where they matter: the conditions as free choices
    first (an over-approximation: what it proves holds), and when that finds a violation,
    which the data may rule out, again with the values tracked (datanet.py, valuenet.py).

    The free choices can also make the state space far larger than the system's (robots
    whose behaviour switches are free are a product of their choices; with the values
    tracked each one follows its data): the first pass gets ``ABSTRACT_SHARE`` of the time
    left, and when that cuts it short, the values are tracked with the rest of the budget
    (sound as well: the tracked net over-approximates the runs on every value it does not
    track)."""
    assert opts.values is not None
    budget = opts.budget if opts.budget is not None else Budget(opts.time_limit,
                                                                opts.max_memory)
    with budget.running("the data tracking"):
        has_values = bool(track_values(track_new(net), opts.values).values)
    # a share of the run's own time left, not of a shorter first try's (the falsifier gives
    # the engines their first second under a cap: the first pass keeps all of it)
    left = (None if budget.time_limit is None
            else max(0.0, budget.time_limit - budget.elapsed()))
    share = (ABSTRACT_SHARE * left if has_values and left is not None else float("inf"))
    with budget.capped(share) as first:
        abstract = verify(net, dataclasses.replace(opts, values=None, guards=opts.values,
                                                   budget=budget))
    if not has_values:
        return dataclasses.replace(abstract, stop=budget.stop)
    cut_short = first.hit and abstract.verdict is not Verdict.VIOLATED
    if abstract.verdict is Verdict.VIOLATED and budget.stop is not None:
        # a limit stopped the run before the values were tracked: what the free choices
        # found may be ruled out by the data, so it is not reported as a violation
        return _unconfirmed_abstract(abstract)
    if not cut_short and (abstract.verdict is not Verdict.VIOLATED
                          or budget.stop is not None):
        return abstract
    if cut_short:
        concrete = _concrete_after_cut(net, opts, budget)
        return dataclasses.replace(concrete, notes=(
            f"with the conditions as free choices the verdict was open after "
            f"{ABSTRACT_SHARE:.0%} of the time ({abstract.why_undecided}); verified again "
            "with the values tracked", *concrete.notes))
    concrete = _concrete_after_cut(net, opts, budget)
    if concrete.verdict is Verdict.VIOLATED:
        why = "confirmed with the values tracked"
    elif concrete.verdict is Verdict.INCONCLUSIVE:
        why = "it may be ruled out by the data: with the values tracked the verdict is open"
    else:
        why = "the data rules it out (it is not possible with the values tracked)"
    return dataclasses.replace(concrete, notes=(
        f"with the conditions as free choices a violation was found; {why}",
        *concrete.notes))


def _concrete_after_cut(net: FlatNet, opts: VerifyOptions, budget: Budget) -> VerifyReport:
    """The values tracked, after a free-choice pass the time cut short or that found a
    violation. With ``auto`` on a net that does not slice (one blocking group), the
    stubborn sets first (half the time left): the free choices' full exploration already
    overflowed, they find a deadlock without the whole state space, and a net whose
    subsystems follow their data is where they cut most; then ``auto`` with the rest when
    they do not decide. A net that slices is verified group by group, as ``auto`` does."""
    concrete = dataclasses.replace(opts, values_first=False, budget=budget)
    if opts.reduction != "auto" or (opts.slicing and len(_groups(net, opts)) > 1):
        return verify(net, concrete)
    # a small net explored whole first (its dead transitions and unreachable behaviours
    # come with it), as a sliced net's first try
    with budget.capped(opts.slice_after_seconds) as cap:
        whole = verify(net, dataclasses.replace(concrete, reduction="off",
                                                max_states=opts.slice_after_states))
    if (whole.verdict is Verdict.VIOLATED or budget.stop is not None
            or (whole.complete and not cap.hit)):
        return dataclasses.replace(whole, stop=budget.stop)
    left = budget.remaining()
    with budget.capped(left / 2 if left is not None else float("inf")):
        reduced = verify(net, dataclasses.replace(concrete, reduction="on"))
    if reduced.verdict is not Verdict.INCONCLUSIVE or budget.stop is not None:
        return dataclasses.replace(reduced, stop=budget.stop)
    whole = verify(net, concrete)
    return dataclasses.replace(whole, notes=(
        f"with the values tracked, the stubborn sets did not decide within half the time "
        f"left ({reduced.why_undecided})", *whole.notes))


def _unconfirmed_abstract(abstract: VerifyReport) -> VerifyReport:
    """The free-choice pass's violations, left open: the run stopped before the values
    were tracked, and the data may rule them out."""
    return dataclasses.replace(
        abstract, verdict=Verdict.INCONCLUSIVE,
        safe=None if abstract.safe is False else abstract.safe,
        deadlock_free=None if abstract.deadlock_free is False else abstract.deadlock_free,
        progress_ok=None if abstract.progress_ok is False else abstract.progress_ok,
        deadlocks=(), deadlock_count=0, unsafe=None, progress=(), progress_lost=(),
        notes=("with the conditions as free choices a violation was found; the run stopped "
               "before it could be checked with the values tracked (the data may rule it "
               "out)", *abstract.notes))


def _why_undecided(budget: Budget,
                   searches: tuple[tuple[str, SearchResult | ComposeResult | None], ...],
                   ) -> str | None:
    """Why what is not decided is not: the limit that stopped the run, else the last search
    that stopped early."""
    if budget.stop is not None:
        return budget.stop.message
    why = None
    for name, search in searches:
        if search is not None and search.stopped:
            why = f"{name}: {search.stopped}"
    return why


def _invariants(net: FlatNet, opts: VerifyOptions, budget: Budget,
                notes: list[str]) -> InvariantResult:
    """Step 1: one-token semiflows found by search (``cover``: fast, one per place), then the
    minimal P-semiflows within a third of the time left at most. On a large net that the
    search proves safe the enumeration is skipped (it can take its whole share and more)."""
    start = time.monotonic()
    found = one_token_semiflows(net, range(len(net.places)), lambda: budget.poll() is not None)
    covered = {p for f in found for p in f.support}
    if len(covered) == len(net.places) and len(net.places) > SMALL_NET:
        proof = {p: k for k, f in enumerate(found) for p in f.support}
        return InvariantResult(tuple(found), False,
                               "minimal semiflows not enumerated: one-token semiflows found "
                               "by search prove every place safe", time.monotonic() - start,
                               proof=dict(sorted(proof.items())))
    left = budget.remaining()
    inv = place_invariants(net, opts.max_invariant_rows,
                           opts.invariant_time if left is None
                           else min(left / 3, opts.invariant_time), budget)
    if inv.message:
        notes.append(f"place invariants: {inv.message}")
    extra = [f for f in found if not f.support <= inv.safe_places]
    if not extra:
        return inv
    proof = dict(inv.proof)
    for k, f in enumerate(extra, start=len(inv.invariants)):
        for p in f.support:
            proof.setdefault(p, k)
    notes.append(f"place invariants: {len(extra)} one-token semiflow(s) found by search "
                 f"prove {len(proof) - len(inv.proof)} more place(s) safe")
    return InvariantResult((*inv.invariants, *extra), inv.complete, inv.message,
                           time.monotonic() - start, proof=proof)


def _quick_full(nb: NetBits, opts: VerifyOptions, budget: Budget) -> SearchResult | None:
    """The full exploration within the share of a first try (``slice_after_seconds``,
    ``slice_after_states``); None when it does not finish there."""
    with budget.capped(opts.slice_after_seconds) as cap:
        full = explore_full(nb, min(opts.max_states, opts.slice_after_states),
                            keep_graph=False, max_counterexamples=opts.max_counterexamples,
                            progress=opts.on_progress, budget=budget)
    return full if full.complete and not cap.hit else None


def _no_dead_marking(nb: NetBits, inv: InvariantResult, budget: Budget,
                     notes: list[str]) -> bool:
    """Deadlock freedom from the place invariants (deadmarking.py): no marking that marks
    one place of each one-token semiflow, and none of the semiflows without a token, is
    dead and not final."""
    flows, empty = inv.token_flows()
    with budget.running("the dead markings the invariants allow"):
        try:
            found = dead_markings(nb, flows, empty, budget)
        except LimitReached:
            return False
    if found.proved:
        notes.append(f"deadlock freedom proved from the place invariants: no marking they "
                     f"allow is dead ({found.nodes:,} branchings)")
    return found.proved


def _searches(net: FlatNet, nb: NetBits, opts: VerifyOptions, safe_mask: int,
              budget: Budget, notes: list[str], flows: Sequence[int] = (),
              ) -> tuple[SearchResult | None, ComposeResult | None, SearchResult | None]:
    """Step 2: the explorations ``options.reduction`` asks for (full, compositional,
    stubborn sets), each started only when the ones before left the question open. ``flows``:
    the one-token semiflows (the stubborn sets' necessary enabling sets)."""
    full: SearchResult | None = None
    reduced: SearchResult | None = None
    comp: ComposeResult | None = None
    skip_full = opts.reduction == "auto" and opts.auto_full_states == 0
    if opts.reduction in ("auto", "off") and budget.stop is None and not skip_full:
        limit = opts.max_states
        if opts.reduction == "auto":
            limit = min(limit, opts.auto_full_states, max(10_000, opts.auto_full_words // nb.nwords))
        full = explore_full(nb, limit, keep_graph=opts.check_progress,
                            max_counterexamples=opts.max_counterexamples,
                            progress=opts.on_progress, budget=budget)
        if full.stopped and full.unsafe is None:
            notes += _stopped_note("full exploration", full.stopped, budget)
    # "auto": the full search ran out of states without finding a violation
    open_after_full = skip_full or (opts.reduction == "auto" and full is not None
                                    and not full.complete and full.unsafe is None
                                    and not full.deadlocks)
    if budget.stop is None and (opts.reduction == "compositional" or skip_full or (
            open_after_full and full is not None and "state limit" in (full.stopped or ""))):
        comp, comp_notes = _compositional(net, nb, opts, budget)
        notes += comp_notes
    if budget.stop is None and (opts.reduction == "on" or (open_after_full and (
            comp is None or not comp.complete or comp.safe is False
            or comp.deadlock_free is False))):
        # stubborn sets: the verdict when nothing else gave one, else a counterexample
        reduced = explore_reduced(nb, safe_mask, opts.max_states, None,
                                  opts.max_counterexamples, opts.on_progress,
                                  for_progress=opts.check_progress and comp is None,
                                  budget=budget, semiflows=flows)
        notes.append(f"stubborn-set exploration: {reduced.states} states")
        if reduced.stopped and reduced.unsafe is None:
            notes += _stopped_note("stubborn-set exploration", reduced.stopped, budget)
    return full, comp, reduced


def _stopped_note(name: str, stopped: str, budget: Budget) -> list[str]:
    """The note for a search that stopped early; none for the limit that stopped the run
    (the report says it)."""
    limit = budget.stop is not None and stopped.startswith(budget.stop.message)
    return [] if limit else [f"{name}: {stopped}"]


def _safeness(unsafe_trace: Trace | None, deciding: SearchResult, full: SearchResult | None,
              comp: ComposeResult | None, by_invariants: bool) -> tuple[bool | None, str | None]:
    """Step 3: safe or not, and what shows it."""
    search = "full exploration" if deciding is full else "stubborn-set exploration"
    if unsafe_trace is not None:
        return False, search
    if comp is not None and comp.safe is False:
        return False, "the compositional check"
    if by_invariants:
        return True, "place invariants"
    if deciding.complete:
        return True, search
    if comp is not None and comp.safe:
        return True, "the compositional check"
    return None, None


def _dead_parts(net: FlatNet, full: SearchResult | None, comp: ComposeResult | None,
                reduced: SearchResult | None, notes: list[str],
                ) -> tuple[tuple[FlatTransition, ...] | None, tuple[str, ...] | None]:
    """The dead transitions and unreachable behaviours, when the search allows them."""
    if full is not None and full.complete:
        assert full.fired is not None and full.ever_marked is not None
        dead = tuple(t for t in net.transitions if t.index not in full.fired)
        return dead, _unreachable_behaviours(net, _reached(net, full.fired, full.ever_marked))
    if comp is not None and comp.detail_complete:
        notes.append("dead transitions need the full state space (the compositional check "
                     "decides reachable behaviours only)")
        return None, _unreachable_behaviours(net, comp.reached)
    if (reduced is not None and reduced.complete) or (comp is not None and comp.complete):
        notes.append("dead transitions and unreachable behaviours need the full state space")
    return None, None


@dataclass(frozen=True)
class _Progress:
    ok: bool | None = None
    counterexamples: tuple[Counterexample, ...] = ()
    checked: tuple[str, ...] = ()
    lost: tuple[str, ...] = ()


def _progress_graph(opts: VerifyOptions, full: SearchResult | None,
                    reduced: SearchResult | None) -> Graph | None:
    """The graph progress is judged on: a complete search's (weak fairness needs every
    enabled move, so only the full search's)."""
    if full is not None and full.complete:
        return full.graph
    if reduced is not None and reduced.complete and opts.fairness == "strong":
        return reduced.graph
    return None


def _progress(net: FlatNet, nb: NetBits, graph: Graph | None, comp: ComposeResult | None,
              notes: list[str], budget: Budget, fairness: str = "strong") -> _Progress:
    """Step 3, progress: on the reachability graph of a complete search, else from the
    compositional check."""
    if graph is not None and budget.stop is None:
        result = check_progress(nb, graph, subsystems_of(net), budget, fairness)
        if result.stopped:
            notes.append(f"progress not decided: {result.stopped}; checked before: "
                         + (", ".join(result.checked) or "none"))
        if result.skipped:
            notes.append("no ITERATION transition, progress not checked: "
                         + ", ".join(result.skipped))
        cxs = tuple(Counterexample(
            kind="progress", steps=_steps(net, v.prefix),
            marking=marking_labels(net, nb.marking_of(graph.marking(v.point))),
            where=marking_where(net, nb.marking_of(graph.marking(v.point))),
            subsystem=v.subsystem, to_cycle=_steps(net, v.to_cycle),
            cycle=_steps(net, v.cycle),
            cycle_marking=marking_labels(net, nb.marking_of(v.cycle_marking)))
            for v in result.violations)
        ok = False if result.violations else None if result.stopped else True
        return _Progress(ok, cxs, result.checked)
    if comp is not None and comp.detail_complete and fairness == "strong":
        return _Progress(not comp.progress_lost, (), tuple(comp.progress_checked),
                         tuple(comp.progress_lost))
    if budget.stop is None:         # else the report says which limit stopped the run
        notes.append("progress not decided: the state space was not explored completely"
                     + (" (weak fairness needs the full state space: --reduction off)"
                        if fairness == "weak" else ""))
    return _Progress()


def _steps(net: FlatNet, steps: tuple[int, ...]) -> tuple:  # type: ignore[type-arg]
    return tuple(net.transitions[t] for t in steps)


def _deadlock_cx(net: FlatNet, nb: NetBits, trace: Trace) -> Counterexample:
    return Counterexample("deadlock", _steps(net, trace.steps),
                          marking_labels(net, nb.marking_of(trace.marking)))


def _unsafe_cx(net: FlatNet, nb: NetBits, trace: Trace) -> Counterexample:
    return Counterexample("unsafe", _steps(net, trace.steps),
                          marking_labels(net, nb.marking_of(trace.marking)),
                          doubled=marking_labels(net, frozenset(bits(trace.places))))


def _invariant_lines(net: FlatNet, inv: InvariantResult | None) -> tuple[InvariantLine, ...]:
    if inv is None:
        return ()
    proves: dict[int, list[str]] = {}
    for p, k in sorted(inv.proof.items()):
        proves.setdefault(k, []).append(net.places[p].label or net.places[p].name)
    return tuple(InvariantLine(i.render(net), i.tokens, tuple(proves.get(k, ())))
                 for k, i in enumerate(inv.invariants))


def _reached(net: FlatNet, fired: frozenset[int], ever: int) -> set[tuple[str | None, str]]:
    """The behaviours (subsystem, behaviour) with a transition fired or a place marked."""
    out: set[tuple[str | None, str]] = set()
    for p in net.places:
        if p.behaviour is not None and ever >> p.index & 1:
            out.add((p.subsystem, p.behaviour))
    for t in net.transitions:
        if t.behaviour is not None and t.index in fired:
            out.add((t.subsystem, t.behaviour))
    return out


def _unreachable_behaviours(net: FlatNet, reached: Collection[tuple[str | None, str]],
                            ) -> tuple[str, ...]:
    where: dict[tuple[str | None, str], str] = {}
    for p in net.places:
        if p.behaviour is not None:
            where.setdefault((p.subsystem, p.behaviour), p.span.location)
    for t in net.transitions:
        if t.behaviour is not None:
            where.setdefault((t.subsystem, t.behaviour), t.span.location)
    out = []
    for key, location in where.items():
        if key not in reached:
            sub, beh = key
            name = beh if sub is None or beh.startswith(f"{sub}.") else f"{sub}: {beh}"
            out.append(f"{name} ({location})")
    return tuple(out)


def _compositional(net: FlatNet, nb: NetBits, opts: VerifyOptions, budget: Budget,
                   ) -> tuple[ComposeResult, list[str]]:
    """The compositional check (``compose``) within the run's budget."""
    res = compose_check(net, nb, opts.max_states, None, detail=opts.check_progress,
                        budget=budget)
    notes = [f"compositional check: {res.components} page components, {res.states:,} states "
             f"built in all, the largest composition {res.largest:,} states"]
    if res.stopped:
        notes += _stopped_note("compositional check", res.stopped, budget)
    elif not res.detail_complete:
        notes.append("compositional check: progress and reachable behaviours not decided"
                     + ("" if opts.check_progress else " (--no-progress-check)"))
    return res, notes
