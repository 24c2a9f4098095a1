"""Token-game playback: read a firing sequence and fire it on the flat net, so the explorer
only has to display the markings.

Two inputs are accepted (told apart by their content):

* a trace of `rssmc simulate`: JSON lines, read and validated by the one trace reader
  (:mod:`rssm_core.trace`); its `fire` events name the fired transition in `"transition"`
  (its id in the paper's notation, e.g. `"t[1,lwr,move,4]"`); every other event (behaviour
  switches, buffer values, ...) is skipped;
* a verifier counterexample: the JSON report of `rssmc verify --format json` (its first
  counterexample is played: deadlocks first, then an unsafe firing, then a loss of progress,
  whose way to the cycle and then the cycle, twice, follow its steps), one counterexample
  object (`{"kind": ..., "steps": [...]}`), or a plain list. Steps are transition ids, or
  objects naming one in `"name"` or `"transition"`.

Firing follows the rule of :mod:`rssm_core.firing`: a transition is enabled when all its
input places are marked; firing removes their tokens and marks its output places. A firing that
would put a second token into a place is played (that is what a safeness counterexample shows)
and the step records those places as unsafe. Problems are diagnostics E852-E854 at the line of
the file, never exceptions; a trace longer than `max_steps` is cut there (W855).
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from rssm_core.trace import TraceFormatError, parse_trace
from rssm_dsl.diagnostics import DiagnosticBag
from rssm_dsl.hpn.flat import FlatNet
from rssm_dsl.render import MAX_STEPS
from rssm_dsl.source import Span

MAX_TRACE_BYTES = 256 * 1024 * 1024
_LIST_KEYS = ("counterexample", "steps", "trace", "firings", "path")
_REPORT_KEYS = ("deadlocks", "unsafe", "progress")
PROGRESS_CYCLES = 2


@dataclass(frozen=True, slots=True)
class Firing:
    transition: str
    line: int                      # 1-based line of the file it came from


@dataclass(frozen=True, slots=True)
class Step:
    transition: str
    marking: tuple[int, ...]       # flat place indices marked after the firing
    unsafe: tuple[int, ...]        # places that would hold a second token
    line: int


@dataclass(frozen=True, slots=True)
class Playback:
    source: str                    # the file as given on the command line
    kind: str                      # "trace" or "counterexample"
    initial: tuple[int, ...]
    steps: tuple[Step, ...]


def _at(source: str, line: int = 1) -> Span:
    return Span(source, line, 1, line, 1)


def _as_names(seq: Any) -> list[str] | None:
    """A list of transition ids, or of objects naming one in "name" or "transition"."""
    if not isinstance(seq, list):
        return None
    names: list[str] = []
    for item in seq:
        name = item.get("name", item.get("transition")) if isinstance(item, dict) else item
        if not isinstance(name, str):
            return None
        names.append(name)
    return names


def _counterexample(doc: Any) -> tuple[str, list[str]] | None:
    """(kind, firing sequence) of a verification report, of one counterexample, or of a
    plain list; None if the document holds none."""
    if isinstance(doc, list):
        names = _as_names(doc)
        return None if names is None else ("counterexample", names)
    if not isinstance(doc, dict):
        return None
    if "steps" not in doc and any(k in doc for k in _REPORT_KEYS):
        # a report of `rssmc verify --format json`: deadlocks first, then unsafe, then progress
        found = [*(doc.get("deadlocks") or []), doc.get("unsafe"), *(doc.get("progress") or [])]
        for cex in found:
            if isinstance(cex, dict):
                return _counterexample(cex)
        return None
    for key in _LIST_KEYS:
        if key not in doc:
            continue
        value = doc[key]
        if isinstance(value, dict):
            return _counterexample(value)
        names = _as_names(value)
        if names is None:
            return None
        kind = doc.get("kind")
        kind = kind if isinstance(kind, str) else "counterexample"
        if kind == "progress":
            # the steps, the way to the cycle, then the cycle the rest of the system repeats
            cycle = _as_names(doc.get("cycle", [])) or []
            names += (_as_names(doc.get("to_cycle", [])) or []) + cycle * PROGRESS_CYCLES
        return kind, names
    return None


def _jsonl(text: str, source: str, bag: DiagnosticBag) -> list[Firing] | None:
    try:
        trace = parse_trace(text.split("\n"), source)
    except TraceFormatError as e:
        bag.error("E852", f"line {e.line} of the trace: {e.message}", _at(source, e.line),
                  "a trace has one JSON object per line, each with \"event\"; a fire event "
                  "names its transition in \"transition\"")
        return None
    return [Firing(f.transition, f.line) for f in trace.fires()]


def read_firings(path: Path, bag: DiagnosticBag) -> tuple[str, list[Firing]] | None:
    """The kind of the file and its firing sequence; None (with a diagnostic) if unreadable."""
    source = str(path)
    try:
        if path.stat().st_size > MAX_TRACE_BYTES:
            bag.error("E852", f"'{path}' is larger than {MAX_TRACE_BYTES >> 20} MB", _at(source))
            return None
        text = path.read_text(encoding="utf-8")
    except FileNotFoundError:
        bag.error("E852", f"cannot read '{path}': no such file", _at(source))
        return None
    except (OSError, UnicodeDecodeError) as e:
        bag.error("E852", f"cannot read '{path}': {e}", _at(source))
        return None
    try:
        doc = json.loads(text)
    except json.JSONDecodeError:
        doc = None
    if doc is None or (isinstance(doc, dict) and "event" in doc):
        firings = _jsonl(text, source, bag)
        return None if firings is None else ("trace", firings)
    found = _counterexample(doc)
    if found is None:
        verdict = doc.get("verdict") if isinstance(doc, dict) else None
        bag.error("E852", f"'{path}' holds no firing sequence"
                  + (f" (verdict: {verdict})" if isinstance(verdict, str) else ""),
                  _at(source), "give a trace of `rssmc simulate` (JSON lines) or a verifier "
                  "counterexample (a list of transition ids)")
        return None
    kind, names = found
    return kind, [Firing(name, 0) for name in names]


def play(net: FlatNet, firings: list[Firing], source: str, kind: str,
         bag: DiagnosticBag, max_steps: int = MAX_STEPS) -> Playback | None:
    """Fire the sequence from the initial marking; None (with a diagnostic) if it cannot.
    Only the first `max_steps` firings are played (warning W855), so the page stays small."""
    if len(firings) > max_steps:
        bag.warn("W855", f"the {kind} has {len(firings)} firings; the explorer plays the first "
                 f"{max_steps}", _at(source, max(firings[max_steps].line, 1)),
                 "raise the limit with --max-steps")
        firings = firings[:max_steps]
    by_name = {t.name: t.index for t in net.transitions}
    rule = net.rule
    marking = set(net.initial)
    steps: list[Step] = []
    for k, f in enumerate(firings, start=1):
        t = by_name.get(f.transition)
        where = _at(source, max(f.line, 1))
        if t is None:
            bag.error("E853", f"step {k} fires '{f.transition}', which is not a transition "
                      "of the flattened net", where,
                      "was the trace made from this specification?")
            return None
        missing = rule.missing(marking, t)
        if missing:
            bag.error("E854", f"step {k} fires '{f.transition}', which is not enabled: "
                      f"{', '.join(net.places[p].name for p in missing)} not marked", where,
                      "the trace does not follow from the initial marking of this net")
            return None
        unsafe = rule.fire_in_place(marking, t)
        steps.append(Step(f.transition, tuple(sorted(marking)), unsafe, f.line))
    return Playback(source, kind, tuple(sorted(net.initial)), tuple(steps))


def load_playback(path: Path, net: FlatNet, bag: DiagnosticBag,
                  max_steps: int = MAX_STEPS) -> Playback | None:
    read = read_firings(path, bag)
    if read is None:
        return None
    kind, firings = read
    return play(net, firings, str(path), kind, bag, max_steps)
