"""The verification report: the verdict and its evidence in the user's words, as text or JSON.

Every counterexample is a firing sequence of flat transitions, each printed as
``label (file:line)``, followed by the marking it ends in, named by place labels.
Exit codes (``exit_code``): 0 verified, 1 violated, 2 inconclusive.
"""

from __future__ import annotations

import json
from dataclasses import dataclass, field
from enum import Enum
from typing import Any

from rssm_dsl.hpn.flat import FlatNet, FlatTransition


class Verdict(str, Enum):
    VERIFIED = "verified"
    VIOLATED = "violated"
    INCONCLUSIVE = "inconclusive"


EXIT_CODES = {Verdict.VERIFIED: 0, Verdict.VIOLATED: 1, Verdict.INCONCLUSIVE: 2}


def exit_code(verdict: Verdict) -> int:
    """0 verified, 1 violated, 2 inconclusive."""
    return EXIT_CODES[verdict]


def step_text(t: FlatTransition) -> str:
    """One step of a counterexample: ``label (file:line)``."""
    return f"{t.label or t.name} ({t.span.location})"


def marking_labels(net: FlatNet, marking: frozenset[int]) -> tuple[str, ...]:
    return tuple(net.places[p].label or net.places[p].name for p in sorted(marking))


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

    def lines(self) -> list[str]:
        out = [f"  {i + 1:>3}. {step_text(t)}" for i, t in enumerate(self.steps)]
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
            data["to_cycle"] = [_transition_json(t) for t in self.to_cycle]
            data["cycle"] = [_transition_json(t) for t in self.cycle]
            data["cycle_marking"] = list(self.cycle_marking)
        return data


def _transition_json(t: FlatTransition) -> dict[str, Any]:
    return {"name": t.name, "label": t.label, "file": t.span.file, "line": t.span.line,
            "column": t.span.column, "role": t.role.value}


@dataclass(frozen=True)
class InvariantLine:
    text: str                      # "p + q + 2*r = 1" in place labels
    tokens: int
    proves_safe: tuple[str, ...]   # places whose safeness this invariant proves


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

    @property
    def exit_code(self) -> int:
        return exit_code(self.verdict)

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
        }


def render_json(report: VerifyReport, indent: int | None = 2) -> str:
    return json.dumps(report.to_json(), indent=indent, ensure_ascii=False)


def _yes_no(value: bool | None, yes: str, no: str, unknown: str = "not decided") -> str:
    return unknown if value is None else (yes if value else no)


def render_text(report: VerifyReport, max_invariants: int = 20) -> str:
    r = report
    out = [f"system {r.system}: {r.verdict.value.upper()}"]
    safe = _yes_no(r.safe, "safe", "NOT SAFE")
    if r.safe_by:
        safe += f" (proved by {r.safe_by})" if r.safe else f" (found by {r.safe_by})"
    out.append(f"  safeness:   {safe}")
    out.append("  deadlocks:  " + _yes_no(
        r.deadlock_free, "none", f"{r.deadlock_count} reachable deadlock marking(s)"))
    out.append("  progress:   " + _yes_no(
        r.progress_ok, "no subsystem with ITERATION transitions to check"
        if not r.progress_checked else "no subsystem can get stuck while the rest keeps "
        f"running ({len(r.progress_checked)} checked)",
        f"{len(r.progress) + len(r.progress_lost)} subsystem(s) can get stuck while the rest "
        "keeps running",
        "not decided (see the notes; --no-progress-check skips it)"
        if any(n.startswith(("progress not decided", "compositional check: time limit",
                             "compositional check: progress")) for n in r.notes)
        else "not checked" if not r.progress_checked else "not decided"))
    out.append(f"  states:     {r.states} explored ({r.method}"
               f"{'' if r.complete else ', incomplete'}), {r.edges} firings, depth {r.depth},"
               f" {r.seconds:.2f} s")
    for note in r.notes:
        out.append(f"  note: {note}")
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
    out.append("")
    n = len(r.invariants)
    head = f"place invariants: {n}" + ("" if r.invariants_complete else " (incomplete)")
    out.append(head)
    if r.invariants_message:
        out.append(f"  {r.invariants_message}")
    for inv in r.invariants[:max_invariants]:
        out.append(f"  {inv.text}")
    if n > max_invariants:
        out.append(f"  ... {n - max_invariants} more (--show-invariants lists them)")
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
    return "\n".join(out) + "\n"
