"""What the random runs found, put into the verifier's report.

A violation confirmed in the net (falsifier.py) is one: a property the exhaustive engines
left undecided becomes violated, with the run's counterexample (the verdict VIOLATED); one
they found violated keeps their counterexamples (the shortest), the simulation's is added
when it shows another subsystem's loss of progress. A property they *proved* that the
simulation violates is a contradiction, a bug of one of them: it is never settled by picking
one; the verdict becomes INCONCLUSIVE with an internal-consistency note, and the JSON says
``simulation.consistent: false`` (the soundness harness fails on it).
"""

from __future__ import annotations

import dataclasses

from rssm_dsl.falsify.confirm import Finding
from rssm_dsl.falsify.falsifier import Falsification
from rssm_dsl.hpn.flat import FlatNet
from rssm_dsl.verify.report import (
    Counterexample,
    SimulationSummary,
    Verdict,
    VerifyReport,
    marking_labels,
    marking_where,
)

PROVED_BY = "random simulation"


def counterexample(net: FlatNet, f: Finding) -> Counterexample:
    """The finding as the verifier writes its own counterexamples (report.py)."""
    nb_marking = frozenset(p for p in range(len(net.places)) if f.marking >> p & 1)
    steps = tuple(net.transitions[t] for t in f.steps)
    if f.kind == "progress":
        cycle_at = frozenset(p for p in range(len(net.places)) if f.cycle_marking >> p & 1)
        return Counterexample(
            "progress", steps, marking_labels(net, nb_marking), subsystem=f.subsystem,
            to_cycle=tuple(net.transitions[t] for t in f.to_cycle),
            cycle=tuple(net.transitions[t] for t in f.cycle),
            cycle_marking=marking_labels(net, cycle_at),
            where=marking_where(net, nb_marking))
    if f.kind == "unsafe":
        doubled = frozenset(p for p in range(len(net.places)) if f.doubled >> p & 1)
        return Counterexample("unsafe", steps, marking_labels(net, nb_marking),
                              doubled=marking_labels(net, doubled))
    return Counterexample("deadlock", steps, marking_labels(net, nb_marking))


def summary(found: Falsification, cx: Counterexample | None = None,
            consistent: bool = True, ran: bool = True) -> SimulationSummary:
    return SimulationSummary(
        ran=ran and found.skipped is None, text=found.text(), runs=found.runs,
        firings=found.firings, seconds=found.seconds, seed=found.seed,
        found=found.finding.kind if found.finding is not None else None, counterexample=cx,
        consistent=consistent, unconfirmed=found.unconfirmed)


def not_run(report: VerifyReport, why: str, seed: int = 0) -> VerifyReport:
    """The report saying the simulation did not run, and why."""
    return dataclasses.replace(report, simulation=SimulationSummary(
        ran=False, text=f"not run ({why})", seed=seed))


def apply(report: VerifyReport, net: FlatNet, found: Falsification) -> VerifyReport:
    """``report`` with what the random runs found (see the module docstring)."""
    f = found.finding
    if f is None:
        return dataclasses.replace(report, simulation=summary(found))
    cx = counterexample(net, f)
    proved = {"deadlock": report.deadlock_free, "unsafe": report.safe,
              "progress": report.progress_ok}[f.kind]
    if proved is True:
        what = {"deadlock": "deadlock freedom", "unsafe": "safeness",
                "progress": "progress"}[f.kind]
        note = (f"INTERNAL INCONSISTENCY: the exhaustive engines proved {what}, but a random "
                f"run of the interpreter, confirmed in the net, violates it ({found.text()}); "
                "one of them has a bug: please report it with this specification")
        return dataclasses.replace(
            report, verdict=Verdict.INCONCLUSIVE,
            why_undecided=f"internal inconsistency: {what} proved, violated by simulation",
            notes=(*report.notes, note), simulation=summary(found, cx, consistent=False))
    changes: dict[str, object] = {"verdict": Verdict.VIOLATED,
                                  "simulation": summary(found, cx),
                                  "notes": (*report.notes, *(f"simulation: {c}"
                                                             for c in found.caveats))}
    if f.kind == "deadlock":
        changes["deadlock_free"] = False
        changes["deadlock_count"] = max(1, report.deadlock_count)
        if not report.deadlocks:
            changes["deadlocks"] = (cx,)
    elif f.kind == "unsafe":
        changes["safe"] = False
        if report.unsafe is None:
            changes["unsafe"], changes["safe_by"] = cx, PROVED_BY
    else:
        changes["progress_ok"] = False
        if not any(c.subsystem == f.subsystem for c in report.progress):
            changes["progress"] = (*report.progress, cx)
            changes["progress_lost"] = tuple(s for s in report.progress_lost
                                             if s != f.subsystem)
    return dataclasses.replace(report, **changes)  # type: ignore[arg-type]

