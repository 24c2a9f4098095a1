"""Token-game playback: read a firing sequence and fire it on the flat net, so the explorer
only has to display the markings.

Two inputs are accepted (told apart by their content):

* a trace of `rssmc simulate`: JSON lines, read and validated by the one trace reader
  (:mod:`rssm_core.trace`) one line at a time, so a trace of any length is read in bounded
  memory; its `fire` events name the fired transition in `"transition"` (its id in the
  paper's notation, e.g. `"t[1,lwr,move,4]"`) and the time in `"time"`; every other event
  (behaviour switches, buffer values, ...) is skipped;
* a verifier counterexample: the JSON report of `rssmc verify --format json` (its first
  counterexample is played: deadlocks first, then an unsafe firing, then a loss of progress,
  whose way to the cycle and then the cycle, twice, follow its steps), one counterexample
  object (`{"kind": ..., "steps": [...]}`), or a plain list. Steps are transition ids, or
  objects naming one in `"name"` or `"transition"`.

Firing follows the rule of :mod:`rssm_core.firing`: a transition is enabled when all its
input places are marked; firing removes their tokens and marks its output places. A firing that
would put a second token into a place is played (that is what a safeness counterexample shows)
and the step records those places as unsafe. Every firing of the file is checked; problems are
diagnostics E852-E854 at the line of the file, never exceptions.

The explorer embeds a *window* of the run (:class:`Window`): at most `max_steps` firings from
step `from_step` (the marking after that many firings; 0 is the initial marking) or from the
first firing at or after `from_time` seconds. A window that is not the whole file is told by
warning W855, which names the steps shown and the options that choose another. The window is
kept compactly (:class:`Playback`): the index of each fired transition, and the whole marking
every `every` steps (checkpoints), from which any step's marking is found by firing at most
`every - 1` transitions.
"""

from __future__ import annotations

import json
from collections.abc import Iterable, Iterator
from dataclasses import field
from pathlib import Path
from typing import Any

from rssm_core.records import dataclass
from rssm_core.trace import Fire, TraceFormatError, iter_events
from rssm_dsl.diagnostics import DiagnosticBag
from rssm_dsl.hpn.flat import FlatNet
from rssm_dsl.render import CHECKPOINT_EVERY, MAX_STEPS, MAX_STEPS_LIMIT
from rssm_dsl.source import Span

MAX_TRACE_BYTES = 256 * 1024 * 1024     # a JSON document (counterexample) is read whole
_LIST_KEYS = ("counterexample", "steps", "trace", "firings", "path")
_REPORT_KEYS = ("deadlocks", "unsafe", "progress")
PROGRESS_CYCLES = 2
WINDOW_HINT = ("choose the window with --from-step N or --from-time SECONDS and its length "
               f"with --max-steps (at most {MAX_STEPS_LIMIT:,})")


@dataclass(frozen=True, slots=True)
class Firing:
    transition: str
    line: int                      # 1-based line of the file it came from (0: not known)
    time: float | None = None      # seconds, when the file says


@dataclass(frozen=True, slots=True)
class Step:
    transition: str
    marking: tuple[int, ...]       # flat place indices marked after the firing
    unsafe: tuple[int, ...]        # places that would hold a second token
    line: int
    time: float | None = None


@dataclass(frozen=True, slots=True)
class Window:
    """Which part of a firing sequence the explorer embeds: `max_steps` firings from step
    `from_step`, or, when `from_time` is given, from the first firing at or after it."""

    from_step: int = 0
    from_time: float | None = None
    max_steps: int = MAX_STEPS


class WindowError(Exception):
    """A window the file cannot give (--from-time on firings without times)."""


class _Unreadable(Exception):
    """A line of a trace that is not one (becomes E852)."""

    def __init__(self, line: int, message: str) -> None:
        super().__init__(message)
        self.line = line
        self.message = message


@dataclass(frozen=True)
class Playback:
    """A window of a firing sequence fired on the flat net. Window step 0 is the run's step
    `first` (its marking is `initial`); window step k > 0 follows the firing of `fired[k-1]`
    (an index into the net's transitions), which is the run's step `first + k`."""

    source: str                    # the file as given on the command line
    kind: str                      # "trace" or "counterexample" (or its kind)
    initial: tuple[int, ...]       # the marking at the window's first step
    fired: tuple[int, ...]         # flat transition index of each firing shown
    lines: tuple[int, ...]         # its line in the file
    times: tuple[float | None, ...]  # its time, seconds (None: the file does not say)
    checkpoints: tuple[tuple[int, ...], ...]  # the marking at window steps 0, every, 2 every, ...
    net: FlatNet = field(compare=False, repr=False)
    first: int = 0                 # the run's step of window step 0
    total: int = 0                 # firings in the file
    start_time: float | None = None  # the time of window step 0
    every: int = CHECKPOINT_EVERY
    span: tuple[float, float] | None = None  # times of the file's first and last firing

    @property
    def last(self) -> int:
        """The run's step of the window's last step."""
        return self.first + len(self.fired)

    @property
    def whole(self) -> bool:
        """The window is the whole firing sequence."""
        return self.first == 0 and len(self.fired) == self.total

    def marking_at(self, k: int) -> tuple[int, ...]:
        """The marking at window step k (0 <= k <= len(fired)), fired from its checkpoint."""
        if not 0 <= k <= len(self.fired):
            raise IndexError(f"window step {k} not in 0..{len(self.fired)}")
        c = min(k // self.every, len(self.checkpoints) - 1)
        marking = set(self.checkpoints[c])
        rule = self.net.rule
        for t in self.fired[c * self.every:k]:
            rule.fire_in_place(marking, t)
        return tuple(sorted(marking))

    @property
    def steps(self) -> tuple[Step, ...]:
        """Every step of the window with its whole marking (computed on demand)."""
        rule, names = self.net.rule, [t.name for t in self.net.transitions]
        marking = set(self.initial)
        out: list[Step] = []
        for t, line, time in zip(self.fired, self.lines, self.times, strict=True):
            unsafe = rule.fire_in_place(marking, t)
            out.append(Step(names[t], tuple(sorted(marking)), unsafe, line, time))
        return tuple(out)


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


def _unreadable(bag: DiagnosticBag, source: str, e: _Unreadable) -> None:
    bag.error("E852", f"line {e.line} of the trace: {e.message}", _at(source, e.line),
              "a trace has one JSON object per line, each with \"event\"; a fire event "
              "names its transition in \"transition\"")


def _jsonl(path: Path, source: str) -> Iterator[Firing]:
    """The fire events of a JSON-lines trace, one line at a time; raises :class:`_Unreadable`
    at the first malformed line."""
    with path.open("rb") as f:
        try:
            for event in iter_events(f, source):
                if isinstance(event, Fire):
                    yield Firing(event.transition, event.line, event.time)
        except TraceFormatError as e:
            raise _Unreadable(e.line, e.message) from None


def _first_line(path: Path) -> Any:
    """The JSON value of the first non-blank line of the file, or None."""
    with path.open("rb") as f:
        for raw in f:
            if raw.strip():
                try:
                    return json.loads(raw)
                except (json.JSONDecodeError, UnicodeDecodeError):
                    return None
    return None


def _document(path: Path, source: str, bag: DiagnosticBag) -> tuple[str, Iterator[Firing]] | None:
    """A file read whole: a JSON document (a counterexample), else JSON lines."""
    if path.stat().st_size > MAX_TRACE_BYTES:
        bag.error("E852", f"'{path}' is larger than {MAX_TRACE_BYTES >> 20} MB and is no "
                  "trace of JSON lines", _at(source))
        return None
    text = path.read_text(encoding="utf-8")
    if not text.strip():                  # as `simulate --replay` says of it
        bag.error("E852", f"'{path}' holds no firing sequence (the file is empty)",
                  _at(source), "give a trace of `rssmc simulate` (JSON lines) or a verifier "
                  "counterexample (a list of transition ids)")
        return None
    try:
        doc = json.loads(text)
    except json.JSONDecodeError:
        return "trace", _jsonl(path, source)
    if isinstance(doc, dict) and "event" in doc:
        return "trace", _jsonl(path, source)
    found = _counterexample(doc)
    if found is None:
        verdict = doc.get("verdict") if isinstance(doc, dict) else None
        bag.error("E852", f"'{path}' holds no firing sequence"
                  + (f" (verdict: {verdict})" if isinstance(verdict, str) else ""),
                  _at(source), "give a trace of `rssmc simulate` (JSON lines) or a verifier "
                  "counterexample (a list of transition ids)")
        return None
    kind, names = found
    return kind, iter([Firing(name, 0) for name in names])


def open_firings(path: Path, bag: DiagnosticBag) -> tuple[str, Iterator[Firing]] | None:
    """The kind of the file and its firing sequence, read as it is iterated (which may raise
    :class:`_Unreadable`: :func:`play` turns that into E852); None (with a diagnostic) if the
    file cannot be opened as either form."""
    source = str(path)
    try:
        head = _first_line(path)
        if isinstance(head, dict) and "event" in head:
            return "trace", _jsonl(path, source)      # JSON lines: streamed, any length
        return _document(path, source, bag)
    except FileNotFoundError:
        bag.error("E852", f"cannot read '{path}': no such file", _at(source))
    except (OSError, UnicodeDecodeError) as e:
        bag.error("E852", f"cannot read '{path}': {e}", _at(source))
    return None


def read_firings(path: Path, bag: DiagnosticBag) -> tuple[str, list[Firing]] | None:
    """The kind of the file and its whole firing sequence; None (with a diagnostic) if
    unreadable."""
    opened = open_firings(path, bag)
    if opened is None:
        return None
    kind, firings = opened
    try:
        return kind, list(firings)
    except _Unreadable as e:
        _unreadable(bag, str(path), e)
        return None


class _Player:
    """Fires a sequence on the net from its initial marking, checking each firing, and keeps
    the window's part of it."""

    def __init__(self, net: FlatNet, source: str, bag: DiagnosticBag, window: Window,
                 every: int) -> None:
        self.net, self.source, self.bag, self.window = net, source, bag, window
        self.every = max(1, every)
        self.by_name = net.transition_index
        self.marking = set(net.initial)
        self.start: int | None = window.from_step if window.from_time is None else None
        self.begin: tuple[int, ...] | None = None
        self.first = 0
        self.start_time: float | None = None
        self.fired: list[int] = []
        self.lines: list[int] = []
        self.times: list[float | None] = []
        self.checkpoints: list[tuple[int, ...]] = []
        self.total = 0
        self.after_line = 0            # line of the first firing after the window
        self.prev_time: float | None = None
        self.span: tuple[float, float] | None = None

    def _locate(self, f: Firing) -> None:
        """Open the window before firing f when it starts there."""
        w = self.window
        if self.start is None and w.from_time is not None:
            if f.time is None:
                raise WindowError(
                    f"--from-time needs the time of each firing, and the firing at line "
                    f"{f.line} of {self.source} has none (a counterexample has none): use "
                    "--from-step N")
            if f.time >= w.from_time:
                self.start = self.total
        if self.begin is None and self.start == self.total:
            self._open(self.prev_time if self.total else (0.0 if f.time is not None else None))

    def _open(self, time: float | None) -> None:
        """The window starts at the current marking."""
        self.first = self.total
        self.begin = tuple(sorted(self.marking))
        self.checkpoints.append(self.begin)
        self.start_time = time

    def _fire(self, f: Firing) -> int | None:
        """Fire f (the run's step total + 1); its transition index, or None (diagnostic)."""
        k = self.total + 1
        t = self.by_name.get(f.transition)
        where = _at(self.source, max(f.line, 1))
        if t is None:
            self.bag.error("E853", f"step {k} fires '{f.transition}', which is not a "
                           "transition of the flattened net", where,
                           "was the trace made from this specification?")
            return None
        rule = self.net.rule
        missing = rule.missing(self.marking, t)
        if missing:
            self.bag.error("E854", f"step {k} fires '{f.transition}', which is not enabled: "
                           f"{', '.join(self.net.places[p].name for p in missing)} not marked",
                           where, "the trace does not follow from the initial marking of "
                           "this net")
            return None
        rule.fire_in_place(self.marking, t)
        return t

    def take(self, f: Firing) -> bool:
        """Play one firing; False (with a diagnostic) if it cannot be fired."""
        self._locate(f)
        inside = self.begin is not None and len(self.fired) < self.window.max_steps
        if inside and self.fired and len(self.fired) % self.every == 0:
            self.checkpoints.append(tuple(sorted(self.marking)))
        t = self._fire(f)
        if t is None:
            return False
        self.total += 1
        if inside:
            self.fired.append(t)
            self.lines.append(f.line)
            self.times.append(f.time)
        elif self.begin is not None and not self.after_line:
            self.after_line = max(f.line, 1)
        if f.time is not None:
            self.span = (self.span[0] if self.span else f.time, f.time)
        self.prev_time = f.time
        return True

    def playback(self, kind: str) -> Playback:
        if self.begin is None:         # the window starts after the last firing
            self._open(self.prev_time)
        assert self.begin is not None
        return Playback(self.source, kind, self.begin, tuple(self.fired), tuple(self.lines),
                        tuple(self.times), tuple(self.checkpoints), self.net, self.first,
                        self.total, self.start_time, self.every, self.span)


def _seconds(t: float | None) -> str:
    return "?" if t is None else f"{t:g} s"


def _window_warning(pb: Playback, window: Window, after_line: int, bag: DiagnosticBag) -> None:
    """W855 when the window is not the whole sequence: which steps are shown, and how to see
    others."""
    if pb.whole:
        return
    what = "trace" if pb.kind == "trace" else pb.kind
    whole = f"the {what} has {pb.total:,} firings"
    if pb.span is not None:
        whole += f" (t = {_seconds(pb.span[0])} to {_seconds(pb.span[1])})"
    if not pb.fired and pb.first == pb.total and (window.from_step > pb.total
                                                  or window.from_time is not None):
        asked = (f"--from-time {window.from_time:g}" if window.from_time is not None
                 else f"--from-step {window.from_step}")
        shown = f"{asked} is past its end: the explorer shows its last marking (step {pb.total:,})"
    else:
        shown = f"the explorer shows steps {pb.first:,} to {pb.last:,}"
        if pb.times and pb.times[-1] is not None:
            shown += f" (t = {_seconds(pb.start_time)} to {_seconds(pb.times[-1])})"
    line = after_line or (pb.lines[0] if pb.lines else 1)
    bag.warn("W855", f"{whole}; {shown}", _at(pb.source, max(line, 1)), WINDOW_HINT)


def play(net: FlatNet, firings: Iterable[Firing], source: str, kind: str,
         bag: DiagnosticBag, window: Window | None = None,
         every: int = CHECKPOINT_EVERY) -> Playback | None:
    """Fire the whole sequence from the initial marking, keeping the window's firings; None
    (with a diagnostic) if it cannot be fired. Raises :class:`WindowError` for a window the
    sequence cannot give."""
    window = window or Window()
    player = _Player(net, source, bag, window, every)
    try:
        for f in firings:
            if not player.take(f):
                return None
    except _Unreadable as e:
        _unreadable(bag, source, e)
        return None
    pb = player.playback(kind)
    _window_warning(pb, window, player.after_line, bag)
    return pb


def load_playback(path: Path, net: FlatNet, bag: DiagnosticBag, window: Window | None = None,
                  every: int = CHECKPOINT_EVERY) -> Playback | None:
    opened = open_firings(path, bag)
    if opened is None:
        return None
    kind, firings = opened
    return play(net, firings, str(path), kind, bag, window, every)
