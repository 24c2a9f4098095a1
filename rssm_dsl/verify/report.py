"""The verification report: the verdict and its evidence in the user's words, as text or JSON.

Every counterexample is a firing sequence of flat transitions, each printed as
``label (file:line)``, followed by the marking it ends in, named by place labels.

The report always says what was proved, what was not and why: per property (safeness,
deadlock freedom, progress) proved, violated, not decided (and why: the limit that stopped the
run, in which phase, or the search that stopped early) or not checked (``--no-progress-check``).

Exit codes (``exit_code``): 0 verified (safeness, deadlock freedom and progress), 1 violated,
3 inconclusive (a limit was reached or a property was not decided), 4 verified without the
progress check (safe and deadlock-free; progress not checked), 130 interrupted (Ctrl-C) with
no violation found. 2 is left to usage errors and bad input (``rssm_dsl.commands.common``).
"""

from __future__ import annotations

import json
import re
from dataclasses import field
from enum import Enum
from typing import Any

from rssm_core.records import dataclass
from rssm_core.values import short
from rssm_dsl.hpn.flat import FlatNet, FlatTransition
from rssm_dsl.source import Span
from rssm_dsl.verify.budget import INTERRUPT, Stop, format_seconds, format_size


class Verdict(str, Enum):
    VERIFIED = "verified"
    VIOLATED = "violated"
    INCONCLUSIVE = "inconclusive"
    VERIFIED_WITHOUT_PROGRESS = "verified_without_progress"   # progress not asked for


EXIT_VERIFIED, EXIT_VIOLATED, EXIT_INCONCLUSIVE, EXIT_WITHOUT_PROGRESS = 0, 1, 3, 4
EXIT_INTERRUPTED = 130
EXIT_CODES = {Verdict.VERIFIED: EXIT_VERIFIED, Verdict.VIOLATED: EXIT_VIOLATED,
              Verdict.INCONCLUSIVE: EXIT_INCONCLUSIVE,
              Verdict.VERIFIED_WITHOUT_PROGRESS: EXIT_WITHOUT_PROGRESS}


# what "loses progress" assumes of the schedule and of the free choices (printed with it)
FAIRNESS = ("strong", "weak")
# a value the verifier chose where the data does not decide it: (subsystem, variable, value);
# with the position of the firing that chose it in a counterexample's sequence
Chosen = tuple[str, str, Any]
StepValue = tuple[int, str, str, Any]
PROGRESS_ASSUMPTIONS = {
    "strong": (
        "strong fairness: a subsystem loses progress when some reachable state lets no "
        "continuation complete another iteration of it; a run that keeps a move or a free "
        "choice possible infinitely often and never takes it is not counted (starvation by "
        "such a schedule is not reported)"),
    "weak": (
        "weak fairness: a subsystem loses progress when some run never completes another "
        "iteration of it while every move that stays enabled for good is eventually taken; "
        "a move (or a free choice) enabled only now and then may be passed over forever "
        "(starvation by such a schedule is reported)"),
}
PROGRESS_FAIRNESS = "strong"          # the default
PROGRESS_ASSUMPTION = PROGRESS_ASSUMPTIONS[PROGRESS_FAIRNESS]


VALUES_ASSUMPTION = ("assuming no operation fails at run time (E802): terminal and error "
                     "conditions are evaluated on the values")


def exit_code(verdict: Verdict) -> int:
    """0 verified, 1 violated, 3 inconclusive, 4 verified without the progress check."""
    return EXIT_CODES[verdict]


_BUFFER = re.compile(r"(?:send of|receives|sends) (\w+)")


def step_text(t: FlatTransition) -> str:
    """One step of a counterexample: ``label (file:line)``."""
    return f"{t.label or t.name} ({t.span.location})"


def marking_labels(net: FlatNet, marking: frozenset[int]) -> tuple[str, ...]:
    return tuple(net.places[p].label or net.places[p].name for p in sorted(marking))


def marking_where(net: FlatNet, marking: frozenset[int]) -> tuple[tuple[str, str], ...]:
    """Each marked place's label with the file:line of the user's text it comes from."""
    return tuple((net.places[p].label or net.places[p].name, net.places[p].span.location)
                 for p in sorted(marking))


@dataclass(frozen=True)
class Counterexample:
    """A firing sequence from the initial marking that exhibits a violation.

    kind: "deadlock" (ends in a non-final marking with nothing enabled), "unsafe" (the last
    step would put a second token into ``doubled``), "progress" (after ``steps`` the
    ``subsystem`` never completes an iteration again; ``to_cycle`` then ``cycle``, repeated
    forever, is what the rest of the system keeps doing).
    """

    kind: str
    steps: tuple[FlatTransition, ...]
    marking: tuple[str, ...]                  # place labels of the marking reached by steps
    subsystem: str | None = None
    doubled: tuple[str, ...] = ()
    to_cycle: tuple[FlatTransition, ...] = ()
    cycle: tuple[FlatTransition, ...] = ()
    cycle_marking: tuple[str, ...] = ()
    where: tuple[tuple[str, str], ...] = ()   # (label, file:line) of the marking's places
    # values the data does not decide (a device's reading...), as the verifier chose them
    # on this path: (position in steps + to_cycle + cycle, subsystem, variable, value)
    values: tuple[StepValue, ...] = ()

    def stuck_at(self) -> tuple[str, ...]:
        """For a loss of progress: where the subsystem stands in the marking reached (its
        places) and the state of the channels it is sending or receiving on there."""
        if self.kind != "progress" or self.subsystem is None:
            return ()
        own = [m for m in self.marking if m.startswith(f"{self.subsystem} ")]
        buffers = {b for m in own for b in _BUFFER.findall(m)}
        channels = [m for m in self.marking if m.startswith("channel ") and any(
            f"{self.subsystem}.{b} " in m for b in buffers)]
        return (*own, *channels)

    def stuck_where(self) -> tuple[str, ...]:
        """The file:line of each line of :meth:`stuck_at` ("" when not known)."""
        where = dict(self.where)
        return tuple(where.get(x, "") for x in self.stuck_at())

    def lines(self) -> list[str]:
        out = [f"    stands at: {x}" + (f" ({loc})" if loc else "")
               for x, loc in zip(self.stuck_at(), self.stuck_where(), strict=True)]
        out += [f"  {i + 1:>3}. {step_text(t)}" for i, t in enumerate(self.steps)]
        if not self.steps:
            out.append("    (in the initial marking)")
        if self.kind == "unsafe":
            out.append("    would put a second token into: " + ", ".join(self.doubled))
            out.append("    marking before the last step: " + ", ".join(self.marking))
        else:
            out.append("    marking reached: " + (", ".join(self.marking) or "(empty)"))
        if self.kind == "progress":
            if self.to_cycle:
                out.append(f"    then, without {self.subsystem} ever iterating again:")
                out += [f"        {step_text(t)}" for t in self.to_cycle]
            out.append("    and then forever:")
            out += [f"        {step_text(t)}" for t in self.cycle]
        elif self.kind == "property" and (self.to_cycle or self.cycle):
            out.append("    then, the goal never reached:")
            out += [f"        {step_text(t)}" for t in self.to_cycle]
            if self.cycle:
                out.append("    and then forever:")
                out += [f"        {step_text(t)}" for t in self.cycle]
        if self.values:
            out.append("    values the data does not decide (read from a device or computed "
                       "from untracked data), as chosen on this path:")
            out += [f"        step {i + 1}: {sub}.{var} = {short(v)}"
                    for i, sub, var, v in self.values]
        return out

    def to_json(self) -> dict[str, Any]:
        data: dict[str, Any] = {
            "kind": self.kind,
            "steps": [_transition_json(t) for t in self.steps],
            "marking": list(self.marking),
        }
        if self.subsystem is not None:
            data["subsystem"] = self.subsystem
        if self.doubled:
            data["doubled"] = list(self.doubled)
        if self.kind == "progress":
            data["stuck_at"] = list(self.stuck_at())
            data["stuck_at_locations"] = list(self.stuck_where())
            data["to_cycle"] = [_transition_json(t) for t in self.to_cycle]
            data["cycle"] = [_transition_json(t) for t in self.cycle]
            data["cycle_marking"] = list(self.cycle_marking)
        elif self.kind == "property" and (self.to_cycle or self.cycle):
            data["to_cycle"] = [_transition_json(t) for t in self.to_cycle]
            data["cycle"] = [_transition_json(t) for t in self.cycle]
            data["cycle_marking"] = list(self.cycle_marking)
        if self.values:
            data["values"] = [{"step": i + 1, "subsystem": sub, "variable": var, "value": v}
                              for i, sub, var, v in self.values]
        return data


def _transition_json(t: FlatTransition) -> dict[str, Any]:
    return {"name": t.name, "label": t.label, "file": t.span.file, "line": t.span.line,
            "column": t.span.column, "role": t.role.value}


@dataclass(frozen=True)
class PropertyResult:
    """A property stated in the spec (verify/userprops.py): whether it holds (None: not
    decided), why, and for a violation the firing sequence to a state that violates it."""

    name: str
    kind: str                      # "always" | "response"
    text: str                      # the property in the spec's words
    holds: bool | None
    counterexample: Counterexample | None
    why: str
    span: Span
    states: int = 0                # the states explored to decide it (0: none decided it)

    def lines(self) -> list[str]:
        word = {True: "holds", False: "VIOLATED", None: "not decided"}[self.holds]
        out = [f"  {self.name} ({self.span.location}): {word}: {self.text}",
               f"    {self.why}"]
        if self.counterexample is not None:
            out += self.counterexample.lines()
        return out

    def to_json(self) -> dict[str, Any]:
        return {"name": self.name, "kind": self.kind, "text": self.text, "holds": self.holds,
                "why": self.why, "file": self.span.file, "line": self.span.line,
                "states": self.states,
                "counterexample": self.counterexample.to_json()
                if self.counterexample is not None else None}


@dataclass(frozen=True)
class InvariantLine:
    text: str                      # "p + q + 2*r = 1" in place labels
    tokens: int
    proves_safe: tuple[str, ...]   # places whose safeness this invariant proves


@dataclass(frozen=True)
class FreeCondition:
    """A condition on data the state space leaves a free choice: every outcome is explored
    (an over-approximation, sound for deadlock freedom; docs/verify.md, "How values are
    tracked")."""

    kind: str              # "terminal/error" (a behaviour's t_4 / t_out) or "switch"
    where: str             # the subsystem (behaviour), or the switch in words
    condition: str         # the condition's text
    span: Span

    def text(self) -> str:
        what = (f"{self.where} [{self.condition}]" if self.kind == "switch" else
                f"{self.where}: {self.kind} [{self.condition}]")
        return f"{what} ({self.span.location})"

    def to_json(self) -> dict[str, Any]:
        return {"kind": self.kind, "where": self.where, "condition": self.condition,
                "file": self.span.file, "line": self.span.line, "column": self.span.column}


@dataclass(frozen=True)
class SimulationSummary:
    """What the random runs of the interpreter did (``rssm_dsl.falsify``): ``text`` in one
    line ("12 random run(s) (seed 0), 40,000 firings in 2.0 s: found nothing"), the violation
    they found and confirmed in the net (its kind and counterexample), and whether it agrees
    with what the exhaustive engines proved (``consistent``: False is a bug of one of them)."""

    ran: bool
    text: str
    runs: int = 0
    firings: int = 0
    seconds: float = 0.0
    seed: int = 0
    found: str | None = None                   # deadlock | unsafe | progress
    counterexample: Counterexample | None = None
    consistent: bool = True
    unconfirmed: tuple[str, ...] = ()          # stops of runs the net does not confirm

    def to_json(self) -> dict[str, Any]:
        return {"ran": self.ran, "text": self.text, "runs": self.runs,
                "firings": self.firings, "seconds": round(self.seconds, 3), "seed": self.seed,
                "found": self.found, "consistent": self.consistent,
                "counterexample": self.counterexample.to_json()
                if self.counterexample is not None else None,
                "unconfirmed": list(self.unconfirmed)}


@dataclass(frozen=True)
class Unconfirmed:
    """A violation found in a slice (verify/sliced.py) that was not lifted to a firing
    sequence of the whole net. A slice over-approximates its group (its environment may
    write at any time or never, with any value), so it is reported as what it is: found in
    the slice of ``group``, not confirmed in the whole net, ``why``, and ``tried`` what
    was tried; never as a violation. ``counterexample`` is the slice's firing sequence (the
    environment's moves named as such)."""

    kind: str                      # deadlock (the group stuck) | progress | unsafe
    what: str                      # "a loss of progress of arm.c", "a stuck group", ...
    group: tuple[str, ...]
    why: str
    tried: str
    counterexample: Counterexample | None    # None: found without one (compositionally)

    def headline(self) -> str:
        return (f"{self.what} found in the slice of {', '.join(self.group)}, not confirmed "
                f"in the whole net ({self.why})")

    def lines(self) -> list[str]:
        out = [self.headline(), f"    tried: {self.tried}"]
        if self.counterexample is not None:
            out += ["    the slice's firing sequence:", *self.counterexample.lines()]
        return out

    def to_json(self) -> dict[str, Any]:
        return {"kind": self.kind, "what": self.what, "group": list(self.group),
                "why": self.why, "tried": self.tried,
                "counterexample": self.counterexample.to_json()
                if self.counterexample is not None else None}


@dataclass(frozen=True)
class VerifyReport:
    system: str
    verdict: Verdict
    # safeness
    safe: bool | None                          # None: not decided
    safe_by: str | None                        # "place invariants" / "full exploration" / ...
    # invariants
    invariants: tuple[InvariantLine, ...]
    invariants_complete: bool
    invariants_message: str | None
    uncovered_places: tuple[str, ...]          # places the invariants do not prove safe
    # state space
    method: str                                # "full", "stubborn", "compositional", "a+b"
    states: int
    edges: int
    depth: int
    complete: bool                             # the exploration covered the state space
    deadlock_free: bool | None
    deadlock_count: int
    deadlocks: tuple[Counterexample, ...]
    unsafe: Counterexample | None
    progress_ok: bool | None                   # None: not checked or inconclusive
    progress: tuple[Counterexample, ...]
    progress_checked: tuple[str, ...]
    dead_transitions: tuple[FlatTransition, ...] | None    # None: not computed
    unreachable_behaviours: tuple[str, ...] | None
    seconds: float
    notes: tuple[str, ...] = field(default=())
    # subsystems shown to lose progress without a firing sequence (compositional check)
    progress_lost: tuple[str, ...] = field(default=())
    # the limits of the run and what stopped it
    stop: Stop | None = None                   # the limit that ended the run early
    progress_requested: bool = True            # False: --no-progress-check
    why_undecided: str | None = None           # why what is not decided is not
    time_limit: float | None = None
    max_memory: int | None = None              # bytes
    peak_memory: int = 0                       # bytes resident at most, as measured
    # conditions on data: the data cases decided by new(x) tracked in the state (datanet.py),
    # and the conditions left free choices
    new_tracked_cases: int = 0
    free_conditions: tuple[FreeCondition, ...] = field(default=())
    # the finite values tracked in the state (valuenet.py), in the user's words
    tracked_values: tuple[str, ...] = field(default=())
    # the properties stated in the spec (userprops.py)
    user_properties: tuple[PropertyResult, ...] = field(default=())
    fairness: str = PROGRESS_FAIRNESS          # what progress assumed (FAIRNESS)
    # sliced verification (verify/sliced.py): per blocking group its subsystems and whether
    # its slice can get stuck for good (a deadlock of the slice; None: not decided)
    groups: tuple[tuple[tuple[str, ...], bool | None], ...] = field(default=())
    # the random runs of the interpreter (rssm_dsl.falsify); None: not asked for
    simulation: SimulationSummary | None = None
    # violations found in slices and not confirmed in the whole net (verify/sliced.py)
    unconfirmed: tuple[Unconfirmed, ...] = field(default=())

    @property
    def exit_code(self) -> int:
        """The verdict's code; 130 for a run interrupted (Ctrl-C) before any violation."""
        if (self.stop is not None and self.stop.kind == INTERRUPT
                and self.verdict is not Verdict.VIOLATED):
            return EXIT_INTERRUPTED
        return exit_code(self.verdict)

    def properties(self) -> dict[str, dict[str, str | None]]:
        """Per property: ``status`` (proved, violated, not decided, not checked), ``by``
        (what proved or found it) and ``why`` (why it is not decided or not checked)."""
        why = self.why_undecided or "the state space was not explored completely"

        def status(value: bool | None, by: str | None = None) -> dict[str, str | None]:
            if value is None:
                return {"status": "not decided", "by": None, "why": why}
            return {"status": "proved" if value else "violated", "by": by, "why": None}

        progress = status(self.progress_ok, self.method)
        if not self.progress_requested:
            progress = {"status": "not checked", "by": None, "why": "--no-progress-check"}
        return {"safeness": status(self.safe, self.safe_by),
                "deadlock_freedom": status(self.deadlock_free, self.method),
                "progress": progress}

    def headline(self) -> str:
        """The verdict in one line, with why when it is not plain."""
        if self.verdict is Verdict.VERIFIED_WITHOUT_PROGRESS:
            return ("VERIFIED (progress not checked): safe and deadlock-free; loss of progress "
                    "was not checked (--no-progress-check)")
        if self.verdict is Verdict.INCONCLUSIVE:
            return "INCONCLUSIVE: " + (self.why_undecided or "not every property was decided")
        return str(self.verdict.value).upper()

    def to_json(self) -> dict[str, Any]:
        return {
            "system": self.system,
            "verdict": self.verdict.value,
            "exit_code": self.exit_code,
            "safe": self.safe,
            "safe_by": self.safe_by,
            "deadlock_free": self.deadlock_free,
            "progress_ok": self.progress_ok,
            "invariants": {
                "complete": self.invariants_complete,
                "message": self.invariants_message,
                "list": [{"invariant": i.text, "tokens": i.tokens,
                          "proves_safe": list(i.proves_safe)} for i in self.invariants],
                "uncovered_places": list(self.uncovered_places),
            },
            "state_space": {
                "method": self.method, "states": self.states, "edges": self.edges,
                "depth": self.depth, "complete": self.complete,
            },
            "deadlock_count": self.deadlock_count,
            "deadlocks": [c.to_json() for c in self.deadlocks],
            "unsafe": self.unsafe.to_json() if self.unsafe else None,
            "progress": [c.to_json() for c in self.progress],
            "progress_checked": list(self.progress_checked),
            "progress_lost_without_trace": list(self.progress_lost),
            "dead_transitions": None if self.dead_transitions is None else
            [_transition_json(t) for t in self.dead_transitions],
            "unreachable_behaviours": None if self.unreachable_behaviours is None else
            list(self.unreachable_behaviours),
            "seconds": round(self.seconds, 3),
            "notes": list(self.notes),
            # added with the limits (--timeout, --max-memory); the fields above are unchanged
            "headline": self.headline(),
            "properties": self.properties(),
            "progress_check": self.progress_requested,
            "progress_assumption": {"fairness": self.fairness,
                                    "text": PROGRESS_ASSUMPTIONS[self.fairness]}
            if self.progress_requested else None,
            "stopped_by": self.stop.to_json() if self.stop is not None else None,
            "limits": {"time_seconds": self.time_limit, "memory_bytes": self.max_memory},
            "peak_memory_bytes": self.peak_memory,
            "groups": [{"subsystems": list(g), "stuck": stuck} for g, stuck in self.groups],
            "unconfirmed": [u.to_json() for u in self.unconfirmed],
            "user_properties": [p.to_json() for p in self.user_properties],
            "simulation": self.simulation.to_json() if self.simulation is not None
            else None,
            "conditions": {"new_tracked_cases": self.new_tracked_cases,
                           "tracked_values": list(self.tracked_values),
                           "free_choices": [c.to_json() for c in self.free_conditions]},
        }


def _limits_text(r: VerifyReport) -> str:
    """The run's limits and its peak memory; the limit that stopped it, and when."""
    time_limit = "no time limit" if r.time_limit is None else f"time {format_seconds(r.time_limit)}"
    memory = "no memory limit" if r.max_memory is None else f"memory {format_size(r.max_memory)}"
    text = f"{time_limit}, {memory} (peak {format_size(r.peak_memory)} resident)"
    if r.stop is not None:
        text += f"; stopped after {r.stop.at:.1f} s: {r.stop.message}"
    return text


def render_json(report: VerifyReport, indent: int | None = 2) -> str:
    return json.dumps(report.to_json(), indent=indent, ensure_ascii=False)


def _yes_no(value: bool | None, yes: str, no: str, unknown: str = "not decided") -> str:
    return unknown if value is None else (yes if value else no)


def _summary_lines(r: VerifyReport) -> list[str]:
    """Per property what was found, the assumption, the state space and the limits."""
    out: list[str] = []
    why = r.stop.short if r.stop is not None else r.why_undecided
    undecided = f"not decided ({why})" if why else "not decided"
    safe = _yes_no(r.safe, "safe", "NOT SAFE", undecided)
    if r.safe_by:
        safe += f" (proved by {r.safe_by})" if r.safe else f" (found by {r.safe_by})"
    out.append(f"  safeness:   {safe}")
    out.append("  deadlocks:  " + _yes_no(
        r.deadlock_free, "none", f"{r.deadlock_count} reachable deadlock marking(s)",
        undecided))
    out.append("  progress:   " + _yes_no(
        r.progress_ok, "no subsystem with ITERATION transitions to check"
        if not r.progress_checked else "no subsystem can get stuck while the rest keeps "
        f"running ({len(r.progress_checked)} checked)",
        f"{len(r.progress) + len(r.progress_lost)} subsystem(s) can get stuck while the rest "
        "keeps running",
        "not checked (--no-progress-check)" if not r.progress_requested else undecided))
    if r.progress_requested:
        out.append(f"  assuming:   {PROGRESS_ASSUMPTIONS[r.fairness]}")
    # the properties' own explorations (on their slices): the largest one
    props = max((p.states for p in r.user_properties), default=0)
    also = f"; the properties: {props:,} states at most" if props else ""
    if r.method == "invariants":
        out.append(f"  states:     none explored (decided from the place invariants){also}, "
                   f"{r.seconds:.2f} s")
    elif r.method:
        out.append(f"  states:     {r.states} explored ({r.method}"
                   f"{'' if r.complete else ', incomplete'}), {r.edges} firings, depth "
                   f"{r.depth}{also}, {r.seconds:.2f} s")
    else:
        out.append(f"  states:     none explored (no search ran){also}, {r.seconds:.2f} s")
    out.append("  limits:     " + _limits_text(r))
    if r.simulation is not None:
        out.append(f"  simulation: {r.simulation.text}")
    return out


def _violation_lines(r: VerifyReport) -> list[str]:
    """The counterexamples, and the violations found in slices and not confirmed."""
    out: list[str] = []
    if r.unsafe is not None:
        out.append("")
        out.append("unsafe firing:")
        out += r.unsafe.lines()
    for k, c in enumerate(r.deadlocks):
        out.append("")
        out.append(f"deadlock {k + 1} of {r.deadlock_count}:")
        out += c.lines()
    for c in r.progress:
        out.append("")
        out.append(f"loss of progress: {c.subsystem} never completes an iteration again")
        out += c.lines()
    for name in r.progress_lost:
        out.append("")
        out.append(f"loss of progress: {name} can reach a state from which it never completes "
                   "an iteration again (shown by the compositional check; no firing sequence "
                   "was extracted within the limits)")
    for u in r.unconfirmed:
        out.append("")
        out += u.lines()
    return out


def render_text(report: VerifyReport, max_invariants: int = 20) -> str:
    r = report
    out = [f"system {r.system}: {r.headline()}", *_summary_lines(r)]
    for note in r.notes:
        out.append(f"  note: {note}")
    out += _violation_lines(r)
    out.append("")
    n = len(r.invariants)
    head = f"place invariants: {n}" + ("" if r.invariants_complete else " (incomplete)")
    out.append(head)
    if r.invariants_message:
        out.append(f"  {r.invariants_message}")
    for inv in r.invariants[:max_invariants]:
        out.append(f"  {inv.text}")
    if n > max_invariants:
        out.append(f"  ... {n - max_invariants} more (--show-invariants lists them)"
                   if max_invariants else "  (--show-invariants lists them)")
    if r.uncovered_places:
        shown = ", ".join(r.uncovered_places[:10])
        more = f" and {len(r.uncovered_places) - 10} more" if len(r.uncovered_places) > 10 else ""
        out.append(f"  not proved safe by invariants: {shown}{more}")
    elif r.invariants:
        out.append("  every place is covered by an invariant carrying one token: the net is safe")
    if r.dead_transitions:
        out.append("")
        out.append(f"dead transitions (never enabled): {len(r.dead_transitions)}")
        out += [f"  {step_text(t)}" for t in r.dead_transitions]
    if r.unreachable_behaviours:
        out.append("")
        out.append("unreachable behaviours:")
        out += [f"  {b}" for b in r.unreachable_behaviours]
    if r.user_properties:
        out.append("")
        out.append(f"properties stated in the spec ({len(r.user_properties)}):")
        for prop in r.user_properties:
            out += prop.lines()
    out += _conditions_text(r)
    return "\n".join(out) + "\n"


def _conditions_text(r: VerifyReport) -> list[str]:
    """How the conditions on data were explored: new(x) of the data cases tracked in the
    state; every other condition a free choice, listed."""
    if not (r.new_tracked_cases or r.free_conditions or r.tracked_values
            or r.user_properties):
        return []
    out = ["", "conditions on data:"]
    if r.new_tracked_cases:
        out.append(f"  new(x): tracked in the state; {r.new_tracked_cases} data case(s) fire "
                   "only when the receives allow them")
    if r.tracked_values:
        out.append(f"  values tracked in the state ({len(r.tracked_values)}): "
                   f"{', '.join(r.tracked_values)}")
    if r.tracked_values or r.user_properties:      # the properties track their values too
        out.append(f"  {VALUES_ASSUMPTION}")
    if r.free_conditions:
        out.append(f"  abstracted as free choices (every outcome explored): "
                   f"{len(r.free_conditions)}")
        if r.user_properties:
            out.append("  (for safeness, deadlocks and progress; the properties are checked "
                       "with the values their slices' conditions read tracked where they "
                       "can be)")
        out += [f"    {c.text()}" for c in r.free_conditions]
    return out
