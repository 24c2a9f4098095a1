"""The report of a run that a limit stopped before the verifier could return its own: the
phase did not return within the watchdog's grace (it does not check the budget: the
compilation, the flattening, a long step in C), or it raised the limit out of the verifier.

It says what the full report says of such a run: nothing decided (every property "not
decided" with the limit as the reason), the phases that completed before, the phase that was
stopped and when, the limits and the peak memory; INCONCLUSIVE, exit 3 (130 after Ctrl-C).
Its JSON has the full report's keys (``VerifyReport.to_json``) with the same meaning, and
``phases_completed`` and ``interrupted_phase`` (the phase the watchdog interrupted, or
null).
"""

from __future__ import annotations

import json
from typing import Any

from rssm_core.records import dataclass
from rssm_dsl.verify.budget import INTERRUPT, Budget, Stop, format_seconds, format_size
from rssm_dsl.verify.report import EXIT_INTERRUPTED, PropertyResult, Verdict, exit_code

SHOWN_PHASES = 12       # phases completed listed in the text report (JSON: all of them)
SHOWN_DEPTH = 2         # phases nested deeper are not listed (one per subsystem, ...)


@dataclass(frozen=True)
class PartialReport:
    system: str                          # the system's name, or the file's stem before it
    file: str
    stop: Stop
    completed: tuple[tuple[str, float], ...]   # phases that returned: name, seconds
    interrupted: str | None              # the phase the watchdog interrupted, if it did
    seconds: float                       # since the start of the command
    time_limit: float | None
    max_memory: int | None
    peak_memory: int
    progress_requested: bool = True
    properties: tuple[PropertyResult, ...] = ()   # the spec's, each not decided

    @classmethod
    def of(cls, budget: Budget, stop: Stop, system: str, file: str, interrupted: str | None,
           progress_requested: bool = True,
           properties: tuple[PropertyResult, ...] = ()) -> PartialReport:
        seen: dict[str, float] = {}
        for name, seconds, depth in list(budget.completed):
            if depth <= SHOWN_DEPTH and name not in seen:
                seen[name] = seconds
        return cls(system, file, stop, tuple(seen.items()), interrupted, budget.elapsed(),
                   budget.time_limit, budget.max_memory, budget.peak_resident(),
                   progress_requested, properties)

    @property
    def exit_code(self) -> int:
        return EXIT_INTERRUPTED if self.stop.kind == INTERRUPT else exit_code(
            Verdict.INCONCLUSIVE)

    def headline(self) -> str:
        return f"INCONCLUSIVE: {self.stop.message}"

    def phases_text(self) -> str:
        done = [f"{name} ({seconds:.1f} s)" for name, seconds in self.completed]
        more = len(done) - SHOWN_PHASES
        listed = ", ".join(done[:SHOWN_PHASES]) + (f" and {more} more" if more > 0 else "")
        text = f"completed: {listed or 'none'}; stopped in {self.stop.phase} after " \
               f"{self.stop.at:.1f} s"
        if self.interrupted is not None:
            text += (f"; {self.interrupted} did not return on its own and was interrupted "
                     f"after {self.seconds:.1f} s")
        return text

    def render_text(self) -> str:
        why = f"not decided ({self.stop.short})"
        progress = why if self.progress_requested else "not checked (--no-progress-check)"
        time_limit = ("no time limit" if self.time_limit is None
                      else f"time {format_seconds(self.time_limit)}")
        memory = ("no memory limit" if self.max_memory is None
                  else f"memory {format_size(self.max_memory)}")
        lines = [f"system {self.system}: {self.headline()}",
                 f"  safeness:   {why}",
                 f"  deadlocks:  {why}",
                 f"  progress:   {progress}",
                 f"  phases:     {self.phases_text()}",
                 f"  limits:     {time_limit}, {memory} (peak {format_size(self.peak_memory)} "
                 f"resident); stopped after {self.stop.at:.1f} s: {self.stop.message}"]
        if self.properties:
            lines += ["", f"properties stated in the spec ({len(self.properties)}):"]
            for prop in self.properties:
                lines += prop.lines()
        return "\n".join(lines) + "\n"

    def to_json(self) -> dict[str, Any]:
        undecided = {"status": "not decided", "by": None, "why": self.stop.message}
        return {
            "system": self.system, "file": self.file, "verdict": Verdict.INCONCLUSIVE.value,
            "exit_code": self.exit_code, "safe": None, "safe_by": None,
            "deadlock_free": None, "progress_ok": None,
            "invariants": {"complete": False, "message": "not computed", "list": [],
                           "uncovered_places": []},
            "state_space": {"method": "", "states": 0, "edges": 0, "depth": 0,
                            "complete": False},
            "deadlock_count": 0, "deadlocks": [], "unsafe": None, "progress": [],
            "progress_checked": [], "progress_lost_without_trace": [],
            "dead_transitions": None, "unreachable_behaviours": None,
            "seconds": round(self.seconds, 3), "notes": [f"phases: {self.phases_text()}"],
            "headline": self.headline(),
            "properties": {"safeness": undecided, "deadlock_freedom": undecided,
                           "progress": undecided if self.progress_requested else
                           {"status": "not checked", "by": None,
                            "why": "--no-progress-check"}},
            "progress_check": self.progress_requested,
            "progress_assumption": None,
            "stopped_by": self.stop.to_json(),
            "limits": {"time_seconds": self.time_limit, "memory_bytes": self.max_memory},
            "peak_memory_bytes": self.peak_memory,
            "phases_completed": [{"phase": name, "seconds": round(seconds, 3)}
                                 for name, seconds in self.completed],
            "interrupted_phase": self.interrupted,
            "groups": [], "user_properties": [p.to_json() for p in self.properties],
            "unconfirmed": [], "simulation": None,
            "conditions": {"new_tracked_cases": 0, "tracked_values": [], "free_choices": []},
        }

    def render(self, json_format: bool) -> str:
        """The whole report, as the command prints it (one JSON document, or the text)."""
        if json_format:
            return json.dumps(self.to_json(), indent=2, ensure_ascii=False) + "\n"
        return self.render_text()
