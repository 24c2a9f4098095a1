"""The trace of a run, defined once: what is written, how, and how it is read back.

A trace is a text file of JSON lines, one object per line, each with ``"event"`` naming its
kind. Two programs write traces, each with its own set of kinds (its *source*):

* ``"interpreter"`` — ``rssmc simulate`` and ``rssmc run``: the firings of the flat net and
  what they did. Every event has ``"step"`` (firings so far) and ``"time"`` (seconds,
  simulated or wall-clock); names are the paper's notation (``t[1,c,cw,4]``), spans are
  ``file:line:column`` of the specification;
* ``"node"`` — a generated ROS 2 subsystem node (parameter ``rssm.trace_file`` or
  ``$RSSM_TRACE_DIR``): one event per iteration and per behaviour switch of its subsystem;
  every event has ``"i"``, the subsystem's iteration counter.

The first line is the header, a ``start`` event with ``"format"`` (:data:`FORMAT_VERSION`) and
``"source"``. Files written before the header had these fields are read as format 1 (their
lines are the same); a node trace without a header is recognised by the ``"i"`` of its first
event.

| source      | event     | fields (``?``: may be absent; ``|null``: may be null)              |
|-------------|-----------|--------------------------------------------------------------------|
| both        | start     | format, source, system?, mode?, seed?, places?, transitions?; the   |
|             |           | interpreter adds spec and replay (kept in ``extra``)               |
| interpreter | fire      | transition, role?, label?, span?, subsystem?, forced? (true when a  |
|             |           | replay forced a firing whose condition did not hold)               |
| interpreter | enter     | subsystem, behaviour|null, transition, span                        |
| interpreter | switch    | subsystem, from, to|null (the subsystem ends), condition,           |
|             |           | conditions, transition, span                                       |
| interpreter | send      | subsystem, buffer, channel, value, overwrote, place, span           |
| interpreter | receive   | subsystem, buffer, channel, value, place, span                      |
| interpreter | error     | code, message, span, subsystem|null, place, handled                 |
| interpreter | deadlock  | marking (place names), waiting (subsystem -> place)                 |
| interpreter | stalled   | waiting (stalled subsystem -> the place it waits in; E809)          |
| interpreter | end       | reason, message, problems, summary                                  |
| node        | enter     | from (null), to, i, conditions                                      |
| node        | switch    | from, to|null, i, conditions                                        |
| node        | iteration | i, behaviour, new, cases, sent, received, conditions, t             |
| node        | error     | i, behaviour|null, code, message, where|null, handled               |

``fire`` needs only ``"transition"``: a hand-written firing sequence is a trace too (the
playback and the replay read nothing else). A kind the reader does not know is kept as an
:class:`Other` event (readers skip it), and fields a kind does not define are kept in its
``extra``: a reader of format 1 reads what a later writer of format 1 adds.

Values (``value``, ``received``, ``summary``, ...) are written as
:func:`rssm_core.values.to_json` gives them: numpy arrays and scalars as plain JSON, non-finite
floats as the strings ``"nan"``, ``"inf"`` and ``"-inf"``, anywhere in the event.

:class:`TraceWriter` writes (buffered, thread-safe); :func:`read_trace` / :func:`parse_trace` /
:func:`iter_events` read and validate, giving typed events (:class:`Fire`, :class:`Switch`,
...), and raise :class:`TraceFormatError`, which names the line, for a malformed one.
"""

from __future__ import annotations

import json
import threading
import time
from collections.abc import Callable, Iterable, Iterator, Mapping
from dataclasses import field
from pathlib import Path
from typing import Any, BinaryIO, ClassVar, TypeVar

from rssm_core.records import dataclass

from .values import to_json

FORMAT_VERSION = 1
SOURCE_INTERPRETER = "interpreter"
SOURCE_NODE = "node"
SOURCES = (SOURCE_INTERPRETER, SOURCE_NODE)
BATCH = 4096                 # lines kept before they are written


# ---------------------------------------------------------------- field types


@dataclass(frozen=True, slots=True)
class _Type:
    what: str                      # for error messages: "a string", ...
    test: Callable[[Any], bool]


def _is_int(v: Any) -> bool:
    return isinstance(v, int) and not isinstance(v, bool)


def _is_num(v: Any) -> bool:
    return isinstance(v, int | float) and not isinstance(v, bool)


def _dict_of(values: Callable[[Any], bool]) -> Callable[[Any], bool]:
    return lambda v: isinstance(v, dict) and all(values(x) for x in v.values())


def _list_of(items: Callable[[Any], bool]) -> Callable[[Any], bool]:
    return lambda v: isinstance(v, list) and all(items(x) for x in v)


def _received(v: Any) -> bool:
    return isinstance(v, dict) and "value" in v and _is_int(v.get("seq"))


def _null_or(t: _Type) -> _Type:
    return _Type(t.what + " or null", lambda v: v is None or t.test(v))


_STR = _Type("a string", lambda v: isinstance(v, str))
_INT = _Type("an integer", _is_int)
_NUM = _Type("a number", _is_num)
_BOOL = _Type("true or false", lambda v: isinstance(v, bool))
_ANY = _Type("a JSON value", lambda v: True)
_OBJECT = _Type("an object", lambda v: isinstance(v, dict))
_STRS = _Type("a list of strings", _list_of(lambda x: isinstance(x, str)))
_BOOLS = _Type("a list of booleans", _list_of(lambda x: isinstance(x, bool)))
_INTS = _Type("a list of integers", _list_of(_is_int))
_FLAGS = _Type("an object of booleans", _dict_of(lambda x: isinstance(x, bool)))
_NAMES = _Type("an object of strings", _dict_of(lambda x: isinstance(x, str)))
_COUNTS = _Type("an object of integers", _dict_of(_is_int))
_RECEIVED = _Type('an object of {"seq": integer, "value": ...}', _dict_of(_received))


@dataclass(frozen=True, slots=True)
class _Field:
    name: str                      # in the file
    attr: str                      # on the event class
    type: _Type
    required: bool = True
    default: Any = None            # an optional field equal to it is not written ...
    always: bool = False           # ... unless always written
    absent: Any = None             # an optional field missing from the file reads as this


def _f(name: str, type: _Type, attr: str | None = None) -> _Field:
    return _Field(name, attr or name, type)


def _opt(name: str, type: _Type, default: Any = None) -> _Field:
    return _Field(name, name, type, required=False, default=default)


def _header(name: str, type: _Type, before: Any) -> _Field:
    """A header field written since format 1; ``before``: its value in older files."""
    return _Field(name, name, type, required=False, always=True, absent=before)


_RUN = (_opt("step", _INT), _opt("time", _NUM))      # every interpreter event has them


# ---------------------------------------------------------------- events


@dataclass(frozen=True, kw_only=True)
class Event:
    """One line of a trace. ``line``: 1-based line of the file it was read from (0: not read
    from a file; not compared). ``extra``: fields the kind does not define."""

    KIND: ClassVar[str] = ""
    FIELDS: ClassVar[tuple[_Field, ...]] = ()

    extra: dict[str, Any] = field(default_factory=dict)
    line: int = field(default=0, compare=False)

    @property
    def kind(self) -> str:
        return self.KIND

    def to_json(self) -> dict[str, Any]:
        """The object written for this event (required fields always, optional ones when
        they differ from their default, then ``extra``)."""
        out: dict[str, Any] = {"event": self.kind}
        for f in self.FIELDS:
            value = getattr(self, f.attr)
            if f.required or f.always or value != f.default:
                out[f.name] = value
        out.update(self.extra)
        return out


@dataclass(frozen=True, kw_only=True)
class Start(Event):
    """The header: first line of every trace written since format 1."""

    KIND = "start"
    FIELDS = (_header("format", _INT, 1), _header("source", _STR, SOURCE_INTERPRETER),
              _opt("system", _STR), _opt("mode", _STR),
              _opt("seed", _INT), _opt("places", _INT), _opt("transitions", _INT), *_RUN)
    format: int = FORMAT_VERSION
    source: str = SOURCE_INTERPRETER
    system: str | None = None
    mode: str | None = None
    seed: int | None = None
    places: int | None = None
    transitions: int | None = None
    step: int | None = None
    time: float | None = None


@dataclass(frozen=True, kw_only=True)
class Fire(Event):
    """A transition of the flat net fired (interpreter)."""

    KIND = "fire"
    FIELDS = (_f("transition", _STR), _opt("role", _STR), _opt("label", _STR), _opt("span", _STR),
              _opt("subsystem", _STR), _opt("forced", _BOOL, False), *_RUN)
    transition: str
    role: str | None = None
    label: str | None = None
    span: str | None = None
    subsystem: str | None = None
    forced: bool = False
    step: int | None = None
    time: float | None = None


@dataclass(frozen=True, kw_only=True)
class Enter(Event):
    """A subsystem starts in its initial behaviour (interpreter)."""

    KIND = "enter"
    FIELDS = (_f("subsystem", _STR), _f("behaviour", _null_or(_STR)), _f("transition", _STR),
              _f("span", _STR), *_RUN)
    subsystem: str
    behaviour: str | None
    transition: str
    span: str
    step: int | None = None
    time: float | None = None


@dataclass(frozen=True, kw_only=True)
class Switch(Event):
    """A behaviour switch of a subsystem; ``to`` None: the subsystem ends (interpreter)."""

    KIND = "switch"
    FIELDS = (_f("subsystem", _STR), _f("from", _STR, "from_"), _f("to", _null_or(_STR)),
              _f("condition", _STR), _f("conditions", _FLAGS), _f("transition", _STR),
              _f("span", _STR), *_RUN)
    subsystem: str
    from_: str
    to: str | None
    condition: str
    conditions: dict[str, bool]
    transition: str
    span: str
    step: int | None = None
    time: float | None = None


@dataclass(frozen=True, kw_only=True)
class Send(Event):
    """A value put into a channel slot (interpreter)."""

    KIND = "send"
    FIELDS = (_f("subsystem", _STR), _f("buffer", _STR), _f("channel", _STR), _f("value", _ANY),
              _f("overwrote", _BOOL), _f("place", _STR), _f("span", _STR), *_RUN)
    subsystem: str
    buffer: str
    channel: str
    value: Any
    overwrote: bool
    place: str
    span: str
    step: int | None = None
    time: float | None = None


@dataclass(frozen=True, kw_only=True)
class Receive(Event):
    """A value taken from a channel slot (interpreter)."""

    KIND = "receive"
    FIELDS = (_f("subsystem", _STR), _f("buffer", _STR), _f("channel", _STR), _f("value", _ANY),
              _f("place", _STR), _f("span", _STR), *_RUN)
    subsystem: str
    buffer: str
    channel: str
    value: Any
    place: str
    span: str
    step: int | None = None
    time: float | None = None


@dataclass(frozen=True, kw_only=True)
class Error(Event):
    """An operation failed; ``handled``: the behaviour takes its error condition
    (interpreter)."""

    KIND = "error"
    FIELDS = (_f("code", _STR), _f("message", _STR), _f("span", _STR),
              _f("subsystem", _null_or(_STR)), _f("place", _STR), _f("handled", _BOOL), *_RUN)
    code: str
    message: str
    span: str
    subsystem: str | None
    place: str
    handled: bool
    step: int | None = None
    time: float | None = None


@dataclass(frozen=True, kw_only=True)
class Deadlock(Event):
    """Nothing can fire and the system has not finished (interpreter)."""

    KIND = "deadlock"
    FIELDS = (_f("marking", _STRS), _f("waiting", _NAMES), *_RUN)
    marking: list[str]
    waiting: dict[str, str]
    step: int | None = None
    time: float | None = None


@dataclass(frozen=True, kw_only=True)
class Stalled(Event):
    """Subsystems complete no iteration while the rest of the system runs on (interpreter,
    E809): each stalled subsystem and the place it waits in."""

    KIND = "stalled"
    FIELDS = (_f("waiting", _NAMES), *_RUN)
    waiting: dict[str, str]
    step: int | None = None
    time: float | None = None


@dataclass(frozen=True, kw_only=True)
class End(Event):
    """The last line of a run: why it ended and the final summary (interpreter)."""

    KIND = "end"
    FIELDS = (_f("reason", _STR), _f("message", _STR), _f("problems", _STRS),
              _f("summary", _OBJECT), *_RUN)
    reason: str
    message: str
    problems: list[str]
    summary: dict[str, Any]
    step: int | None = None
    time: float | None = None


@dataclass(frozen=True, kw_only=True)
class NodeEnter(Event):
    """The node's subsystem starts in its initial behaviour ``to`` (node)."""

    KIND = "enter"
    FIELDS = (_f("from", _null_or(_STR), "from_"), _f("to", _STR), _f("i", _INT),
              _f("conditions", _FLAGS))
    from_: str | None
    to: str
    i: int
    conditions: dict[str, bool]


@dataclass(frozen=True, kw_only=True)
class NodeSwitch(Event):
    """A behaviour switch; ``to`` None: the subsystem ends (node)."""

    KIND = "switch"
    FIELDS = (_f("from", _STR, "from_"), _f("to", _null_or(_STR)), _f("i", _INT),
              _f("conditions", _FLAGS))
    from_: str
    to: str | None
    i: int
    conditions: dict[str, bool]


@dataclass(frozen=True, kw_only=True)
class Iteration(Event):
    """One iteration of the behaviour pattern (node): new(x) of the inputs, the data case of
    each partial function, the sequence numbers sent, the samples taken, the terminal and error
    conditions, seconds since the node started."""

    KIND = "iteration"
    FIELDS = (_f("i", _INT), _f("behaviour", _STR), _f("new", _BOOLS), _f("cases", _INTS),
              _f("sent", _COUNTS), _f("received", _RECEIVED), _f("conditions", _FLAGS),
              _f("t", _NUM))
    i: int
    behaviour: str
    new: list[bool]
    cases: list[int]
    sent: dict[str, int]
    received: dict[str, dict[str, Any]]
    conditions: dict[str, bool]
    t: float


@dataclass(frozen=True, kw_only=True)
class NodeError(Event):
    """An operation failed (node); ``where``: the place in the specification."""

    KIND = "error"
    FIELDS = (_f("i", _INT), _f("behaviour", _null_or(_STR)), _f("code", _STR),
              _f("message", _STR), _f("where", _null_or(_STR)), _f("handled", _BOOL))
    i: int
    behaviour: str | None
    code: str
    message: str
    where: str | None
    handled: bool


@dataclass(frozen=True, kw_only=True)
class Other(Event):
    """An event of a kind this reader does not know: its fields are in ``extra``."""

    name: str

    @property
    def kind(self) -> str:
        return self.name


KINDS: dict[str, dict[str, type[Event]]] = {
    SOURCE_INTERPRETER: {c.KIND: c for c in (Start, Fire, Enter, Switch, Send, Receive, Error,
                                             Deadlock, Stalled, End)},
    SOURCE_NODE: {c.KIND: c for c in (Start, NodeEnter, NodeSwitch, Iteration, NodeError)},
}


def start_event(source: str, **fields: Any) -> dict[str, Any]:
    """The header line of a trace written by ``source`` (more fields may follow)."""
    if source not in SOURCES:
        raise ValueError(f"unknown trace source {source!r}")
    return {"event": Start.KIND, "format": FORMAT_VERSION, "source": source, **fields}


# ---------------------------------------------------------------- writing


def encode(event: Mapping[str, Any] | Event) -> str:
    """One line of JSON (without the newline): compact, values in the :func:`to_json` form."""
    obj = event.to_json() if isinstance(event, Event) else event
    try:
        return json.dumps(obj, separators=(",", ":"), allow_nan=False, default=to_json)
    except ValueError:         # a non-finite float that json itself would write as NaN
        return json.dumps(to_json(obj), separators=(",", ":"), allow_nan=False)


class TraceWriter:
    """Writes events as JSON lines to ``path``: kept in memory and written ``batch`` lines at
    a time, and every ``flush_every`` seconds if given (a long-running node); :meth:`flush`
    and :meth:`close` write the rest. Thread-safe (the interpreter's operations run in worker
    threads in concurrent mode). ``count``: events emitted so far."""

    def __init__(self, path: Path, *, batch: int = BATCH,
                 flush_every: float | None = None) -> None:
        self.path = path
        self.batch = max(1, batch)
        self.flush_every = flush_every
        self._file: BinaryIO | None = path.open("wb")
        self._lines: list[str] = []
        self._lock = threading.Lock()
        self._flushed = time.monotonic()
        self.count = 0

    def emit(self, event: Mapping[str, Any] | Event) -> None:
        line = encode(event)
        with self._lock:
            self._lines.append(line)
            self.count += 1
            if len(self._lines) >= self.batch:
                self._write()
            if self.flush_every is not None:
                now = time.monotonic()
                if now - self._flushed >= self.flush_every:
                    self._flushed = now
                    self._write()
                    if self._file is not None:
                        self._file.flush()

    def _write(self) -> None:
        if self._lines and self._file is not None:
            self._file.write(("\n".join(self._lines) + "\n").encode("utf-8"))
        self._lines = []

    @property
    def closed(self) -> bool:
        return self._file is None

    def flush(self) -> None:
        with self._lock:
            self._write()
            if self._file is not None:
                self._file.flush()

    def close(self) -> None:
        with self._lock:
            self._write()
            if self._file is not None:
                self._file.close()
                self._file = None

    def __enter__(self) -> TraceWriter:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


# ---------------------------------------------------------------- reading


class TraceFormatError(ValueError):
    """A line of a trace that is not what the format says; ``line`` is 1-based."""

    def __init__(self, source: str, line: int, message: str) -> None:
        super().__init__(f"{source}:{line}: {message}")
        self.source = source
        self.line = line
        self.message = message


def parse_event(obj: Any, source: str = SOURCE_INTERPRETER, *, line: int = 0,
                where: str = "<trace>") -> Event:
    """The typed event of one decoded line written by ``source``; raises
    :class:`TraceFormatError` (naming ``where`` and ``line``) if it does not fit."""
    def fail(message: str) -> TraceFormatError:
        return TraceFormatError(where, line, message)

    if not isinstance(obj, dict):
        found = "a list" if isinstance(obj, list) else type(obj).__name__
        raise fail(f"not a JSON object (found {found})")
    kind = obj.get("event")
    if not isinstance(kind, str):
        raise fail('no "event" string' if kind is None else '"event" is not a string')
    cls = KINDS.get(source, {}).get(kind)
    if cls is None:
        return Other(name=kind, extra={k: v for k, v in obj.items() if k != "event"}, line=line)
    values: dict[str, Any] = {}
    known = {"event"}
    for f in cls.FIELDS:
        known.add(f.name)
        if f.name not in obj:
            if f.required:
                raise fail(f'{kind} event without "{f.name}"')
            if f.absent is not None:
                values[f.attr] = f.absent
            continue
        value = obj[f.name]
        if not f.type.test(value):
            raise fail(f'"{f.name}" of a {kind} event must be {f.type.what}, not '
                       f"{json.dumps(value)[:60]}")
        values[f.attr] = value
    extra = {k: v for k, v in obj.items() if k not in known}
    event = cls(**values, extra=extra, line=line)
    if isinstance(event, Start):
        if event.source not in SOURCES:
            raise fail(f'unknown trace source "{event.source}" (known: {", ".join(SOURCES)})')
        if not 1 <= event.format <= FORMAT_VERSION:
            raise fail(f"trace format {event.format} is not supported (this reader reads "
                       f"format 1 to {FORMAT_VERSION})")
    return event


def iter_events(lines: Iterable[str | bytes], where: str = "<trace>") -> Iterator[Event]:
    """The events of the lines of a trace, validated one at a time (blank lines are skipped
    but counted); raises :class:`TraceFormatError` at the first malformed line."""
    source: str | None = None
    for n, raw in enumerate(lines, start=1):
        if isinstance(raw, bytes):
            try:
                text = raw.decode("utf-8")
            except UnicodeDecodeError as e:
                raise TraceFormatError(where, n, f"not UTF-8 text ({e.reason})") from None
        else:
            text = raw
        if not text.strip():
            continue
        try:
            obj = json.loads(text)
        except json.JSONDecodeError as e:
            raise TraceFormatError(where, n, f"not JSON ({e.msg}, column {e.colno})") from None
        if source is None:
            if isinstance(obj, dict) and obj.get("event") == Start.KIND:
                header = parse_event(obj, SOURCE_INTERPRETER, line=n, where=where)
                assert isinstance(header, Start)
                source = header.source
                yield header
                continue
            source = SOURCE_NODE if isinstance(obj, dict) and "i" in obj else SOURCE_INTERPRETER
        event = parse_event(obj, source, line=n, where=where)
        if isinstance(event, Start):
            raise TraceFormatError(where, n, "a start event after the first line (two traces "
                                   "in one file?)")
        yield event


E = TypeVar("E", bound=Event)


@dataclass(frozen=True)
class Trace:
    """A whole trace: who wrote it, its header (None for a file without one) and its events
    (the header first)."""

    source: str
    format: int
    header: Start | None
    events: tuple[Event, ...]

    def of(self, kind: type[E]) -> list[E]:
        """The events of one class, in file order."""
        return [e for e in self.events if isinstance(e, kind)]

    def fires(self) -> list[Fire]:
        return self.of(Fire)


def parse_trace(lines: Iterable[str | bytes], where: str = "<trace>") -> Trace:
    """A whole trace from its lines (see :func:`iter_events`)."""
    events = tuple(iter_events(lines, where))
    header = events[0] if events and isinstance(events[0], Start) else None
    if header is not None:
        return Trace(header.source, header.format, header, events)
    node = any(isinstance(e, NodeEnter | NodeSwitch | Iteration | NodeError) for e in events)
    return Trace(SOURCE_NODE if node else SOURCE_INTERPRETER, 1, None, events)


def read_trace(path: Path) -> Trace:
    """Read and validate a trace file. Raises :class:`TraceFormatError` for a malformed line
    (``OSError`` if the file cannot be read)."""
    with path.open("rb") as f:
        return parse_trace(f, str(path))
