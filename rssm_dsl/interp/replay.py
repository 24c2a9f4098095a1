"""Replay a counterexample of `rssmc verify` (or a trace of `rssmc simulate`) step by step.

Accepted files (told apart by their content):

* a verification report (``rssmc verify --format json``): its first counterexample is
  replayed, deadlocks first, then an unsafe firing, then a loss of progress;
* one counterexample object: ``{"kind": "deadlock" | "unsafe" | "progress", "steps": [...],
  "marking": [...], ...}`` as in the report (``rssm_dsl.verify.report.Counterexample``);
* a list of transitions;
* a trace of `rssmc simulate` (JSON lines): its ``fire`` events, read by the one trace
  reader (:mod:`rssm_core.trace`; a malformed line is an error naming the line).

Steps name transitions in the paper's notation, as strings or as objects with ``"name"`` or
``"transition"``. The replay forces exactly these firings, whatever the data says (the
verifier tracks new(x), so the data cases of its counterexamples hold, but its other
conditions on data are free choices; a forced firing whose condition does not hold in the
simulated data is marked ``"forced": true`` in the trace), with the operations
run so that the values can be seen. A loss of progress is replayed up to its cycle, then the
cycle twice. The replay then checks that the simulation ends where the verifier said, judged
by the firing rule of :mod:`rssm_core.firing` (a deadlock: no transition enabled in the
marking reached; an unsafe firing: the last step double-marks a place).
"""

from __future__ import annotations

import json
from dataclasses import field
from pathlib import Path
from typing import Any

from rssm_core.firing import Net, NotEnabled
from rssm_core.records import dataclass
from rssm_core.trace import TraceFormatError, parse_trace
from rssm_dsl.diagnostics import Diagnostic
from rssm_dsl.hpn.flat import FlatNet, Role
from rssm_dsl.interp.scheduler import RunResult, Simulator
from rssm_dsl.source import Span

CYCLES = 2
_LIST_KEYS = ("counterexample", "steps", "trace", "firings", "path")


class ReplayFileError(Exception):
    """The file holds no firing sequence that can be replayed."""


@dataclass(frozen=True)
class Counterexample:
    kind: str                              # deadlock | unsafe | progress | trace
    steps: tuple[str, ...]
    marking: tuple[str, ...] = ()          # labels of the places marked at the end of steps
    subsystem: str | None = None
    to_cycle: tuple[str, ...] = ()
    cycle: tuple[str, ...] = ()
    cycle_marking: tuple[str, ...] = ()

    def sequence(self, cycles: int = CYCLES) -> list[str]:
        return [*self.steps, *self.to_cycle, *(list(self.cycle) * cycles)]


def _names(items: Any, what: str) -> tuple[str, ...]:
    if not isinstance(items, list):
        raise ReplayFileError(f"{what} is not a list of transitions")
    out: list[str] = []
    for k, item in enumerate(items, start=1):
        if isinstance(item, str):
            out.append(item)
        elif isinstance(item, dict) and isinstance(item.get("name", item.get("transition")),
                                                   str):
            out.append(str(item.get("name", item.get("transition"))))
        else:
            raise ReplayFileError(f"{what}, step {k}: neither a transition name nor an object "
                                  "with \"name\"")
    return tuple(out)


def _strings(items: Any) -> tuple[str, ...]:
    return tuple(str(x) for x in items) if isinstance(items, list) else ()


def _from_object(d: dict[str, Any]) -> Counterexample:
    if any(k in d for k in ("deadlocks", "unsafe", "progress")) and "steps" not in d:
        for c in d.get("deadlocks") or []:
            return _from_object(c)
        if isinstance(d.get("unsafe"), dict):
            return _from_object(d["unsafe"])
        for c in d.get("progress") or []:
            return _from_object(c)
        verdict = d.get("verdict", "?")
        raise ReplayFileError(f"the report holds no counterexample (verdict: {verdict})")
    kind = str(d.get("kind", "trace"))
    for key in _LIST_KEYS:
        if key in d:
            value = d[key]
            if isinstance(value, dict):
                inner = _from_object(value)
                return inner
            return Counterexample(
                kind, _names(value, key), _strings(d.get("marking")),
                d.get("subsystem") if isinstance(d.get("subsystem"), str) else None,
                _names(d.get("to_cycle", []), "to_cycle"), _names(d.get("cycle", []), "cycle"),
                _strings(d.get("cycle_marking")))
    raise ReplayFileError("no firing sequence (\"steps\") in the file")


def load_counterexample(path: Path) -> Counterexample:
    try:
        text = path.read_text(encoding="utf-8")
    except OSError as e:
        raise ReplayFileError(f"cannot read {path}: {e.strerror or e}") from e
    try:
        data = json.loads(text)
    except json.JSONDecodeError:
        data = None
    if data is None or (isinstance(data, dict) and "event" in data):   # JSON lines
        try:
            trace = parse_trace(text.split("\n"), str(path))
        except TraceFormatError as e:
            raise ReplayFileError(str(e)) from None
        steps = tuple(f.transition for f in trace.fires())
        if not steps:
            raise ReplayFileError(f"{path} holds no firing sequence")
        return Counterexample("trace", steps)
    if isinstance(data, list):
        return Counterexample("trace", _names(data, "the list"))
    if isinstance(data, dict):
        return _from_object(data)
    raise ReplayFileError(f"{path} holds no firing sequence")


def resolve_steps(net: FlatNet, names: list[str],
                  source: str) -> tuple[list[int], list[Diagnostic]]:
    """Transition indices of the steps; unknown names are E806 diagnostics."""
    index = {t.name: t.index for t in net.transitions}
    out: list[int] = []
    diags: list[Diagnostic] = []
    for k, name in enumerate(names, start=1):
        if name in index:
            out.append(index[name])
            continue
        diags.append(Diagnostic("E806", f"step {k} of {source} fires '{name}', which is not a "
                                f"transition of system {net.system}", Span(source, 1, 1, 1, 1),
                                "replay a counterexample of this specification"))
        if len(diags) >= 5:
            break
    return out, diags


@dataclass
class ReplayVerdict:
    reproduced: bool
    message: str
    diagnostics: list[Diagnostic] = field(default_factory=list)


def iterations_in(net: FlatNet, subsystem: str | None, steps: list[int]) -> int:
    return sum(1 for t in steps if net.transitions[t].role is Role.ITERATION
               and net.transitions[t].subsystem == subsystem)


def labels(net: FlatNet, marking: frozenset[int]) -> tuple[str, ...]:
    return tuple(net.places[p].label or net.places[p].name for p in sorted(marking))


def _last_step_unsafe(rule: Net, initial: frozenset[int], steps: list[int]) -> bool:
    """By the firing rule: the steps fire from ``initial``, safely but for the last one."""
    try:
        firings = rule.run(initial, steps)
    except NotEnabled:
        return False
    return bool(firings) and all(f.safe for f in firings[:-1]) and not firings[-1].safe


def judge(cx: Counterexample, forced: list[int], result: RunResult,
          sim: Simulator) -> ReplayVerdict:
    """Does the replayed run end where the verifier said?"""
    net = sim.rt.net
    rule = sim.game.rule
    codes = {d.code for d in result.diagnostics}
    if result.reason == "error":
        if (cx.kind == "unsafe" and "E807" in codes and result.steps == len(forced)
                and _last_step_unsafe(rule, net.initial, forced)):
            return ReplayVerdict(True, "unsafe firing reproduced: " + result.message,
                                 result.diagnostics)
        return ReplayVerdict(False, f"the replay stopped at step {result.steps}: "
                             f"{result.message}", result.diagnostics)
    if result.reason != "replayed":
        return ReplayVerdict(False, f"the replay stopped early ({result.reason}): "
                             f"{result.message}", result.diagnostics)
    n = len(forced)
    if cx.kind == "deadlock":
        marking = sim.game.marking()
        enabled = rule.enabled_set(marking)
        if enabled or sim.final in marking:
            return ReplayVerdict(False, f"after the {n} firings of the counterexample "
                                 f"{len(enabled)} transition(s) are still enabled: "
                                 "no deadlock here")
        diag = sim.deadlock_diagnostic()
        reached = labels(net, marking)
        note = ""
        if cx.marking and tuple(sorted(cx.marking)) != tuple(sorted(reached)):
            note = " (the marking differs from the verifier's: " + ", ".join(reached) + ")"
        return ReplayVerdict(True, f"deadlock reproduced after {n} firings{note}", [diag])
    if cx.kind == "unsafe":
        return ReplayVerdict(False, "the last firing did not double-mark a place: the unsafe "
                             "firing is not reproduced")
    if cx.kind == "progress":
        start = len(cx.steps) + len(cx.to_cycle)
        size = len(cx.cycle)
        marks = result.markings
        if size == 0 or len(marks) <= start + CYCLES * size:
            return ReplayVerdict(False, "the counterexample has no cycle to repeat")
        ends = [marks[start + k * size] for k in range(CYCLES + 1)]
        if any(m != ends[0] for m in ends):
            return ReplayVerdict(False, "the cycle does not come back to the marking it "
                                 "started from")
        if iterations_in(net, cx.subsystem, forced[start:]):
            return ReplayVerdict(False, f"{cx.subsystem} completes an iteration in the cycle")
        return ReplayVerdict(True, f"loss of progress reproduced: after {start} firings "
                             f"{cx.subsystem} never completes an iteration again while the "
                             f"rest of the system repeats a cycle of {size} firings "
                             f"(replayed {CYCLES} times)")
    return ReplayVerdict(True, f"replayed {n} firings")
