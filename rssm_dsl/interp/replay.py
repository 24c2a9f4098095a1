"""Replay a counterexample of `rssmc verify` (or a trace of `rssmc simulate`) step by step.

Accepted files (told apart by their content):

* a verification report (``rssmc verify --format json``): its first counterexample is
  replayed, deadlocks first, then an unsafe firing, then a loss of progress, then the
  counterexample of the first violated property stated in the spec (``user_properties``, in
  the order of the spec);
* one counterexample object: ``{"kind": "deadlock" | "unsafe" | "progress" | "property",
  "steps": [...], "marking": [...], ...}`` as in the report
  (``rssm_dsl.verify.report.Counterexample``; a property's names the property in
  ``"subsystem"``), or one entry of ``user_properties`` (its ``counterexample``);
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
marking reached; an unsafe firing: the last step double-marks a place), or, for a property, by
the property's own expressions evaluated on the simulator's state (:class:`PropertyWatch`):
`always P`, P false in the state reached; `whenever P eventually Q`, P true at the end of the
path and Q false at every state from there on, the cycle replayed twice.
"""

from __future__ import annotations

import json
from collections.abc import Callable, Iterator
from dataclasses import field, replace
from pathlib import Path
from typing import IO, TYPE_CHECKING, Any

from rssm_core.firing import Net, NotEnabled
from rssm_core.records import dataclass
from rssm_core.trace import Fire, TraceFormatError, iter_events
from rssm_core.values import short
from rssm_dsl.diagnostics import Diagnostic
from rssm_dsl.hpn.flat import FlatNet, Role
from rssm_dsl.interp.scheduler import RunResult, Simulator
from rssm_dsl.source import Span

if TYPE_CHECKING:
    from rssm_dsl.interp.program import Runtime
    from rssm_dsl.semantics.model import Property

CYCLES = 2
_LIST_KEYS = ("counterexample", "steps", "trace", "firings", "path")


class ReplayFileError(Exception):
    """The file holds no firing sequence that can be replayed."""


@dataclass(frozen=True)
class Counterexample:
    kind: str                              # deadlock | unsafe | progress | property | trace
    steps: tuple[str, ...]
    marking: tuple[str, ...] = ()          # labels of the places marked at the end of steps
    subsystem: str | None = None           # a property's counterexample: the property
    to_cycle: tuple[str, ...] = ()
    cycle: tuple[str, ...] = ()
    cycle_marking: tuple[str, ...] = ()
    # values the verifier chose where the data does not decide them (a device's reading):
    # (position in steps + to_cycle + cycle, subsystem, variable, value); see ValueChoices
    values: tuple[tuple[int, str, str, Any], ...] = ()

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


def _values(items: Any) -> tuple[tuple[int, str, str, Any], ...]:
    """The report's ``values``: ``{"step": n, "subsystem": s, "variable": v, "value": x}``
    (``step`` from 1, as the report numbers the steps)."""
    if not isinstance(items, list):
        raise ReplayFileError("\"values\" is not a list")
    out: list[tuple[int, str, str, Any]] = []
    for k, item in enumerate(items, start=1):
        ok = (isinstance(item, dict) and isinstance(item.get("step"), int)
              and item["step"] >= 1 and isinstance(item.get("subsystem"), str)
              and isinstance(item.get("variable"), str)
              and isinstance(item.get("value"), (bool, int, str)))
        if not ok:
            raise ReplayFileError(f"\"values\", entry {k}: expected {{\"step\": n, "
                                  "\"subsystem\": ..., \"variable\": ..., \"value\": ...}")
        out.append((item["step"] - 1, item["subsystem"], item["variable"], item["value"]))
    return tuple(out)


def _strings(items: Any) -> tuple[str, ...]:
    return tuple(str(x) for x in items) if isinstance(items, list) else ()


REPORT_KEYS = ("deadlocks", "unsafe", "progress", "user_properties")   # the replay's order


def _from_object(d: dict[str, Any]) -> Counterexample:
    if any(k in d for k in REPORT_KEYS) and "steps" not in d:
        for c in d.get("deadlocks") or []:
            return _from_object(c)
        if isinstance(d.get("unsafe"), dict):
            return _from_object(d["unsafe"])
        for c in d.get("progress") or []:
            return _from_object(c)
        for p in d.get("user_properties") or []:
            if isinstance(p, dict) and p.get("holds") is False \
                    and isinstance(p.get("counterexample"), dict):
                return _property(p)
        verdict = d.get("verdict", "?")
        raise ReplayFileError(f"the report holds no counterexample (verdict: {verdict})")
    if isinstance(d.get("counterexample"), dict) and isinstance(d.get("name"), str) \
            and d.get("kind") in ("always", "response"):
        return _property(d)                  # one entry of the report's user_properties
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
                _strings(d.get("cycle_marking")), _values(d.get("values", [])))
    raise ReplayFileError("no firing sequence (\"steps\") in the file")


def _property(p: dict[str, Any]) -> Counterexample:
    """The counterexample of an entry of the report's ``user_properties``."""
    cx = _from_object(p["counterexample"])
    return replace(cx, kind="property", subsystem=str(p["name"]))


# the largest JSON document --replay reads whole: `rssmc verify --format json` writes a
# counterexample per violated property, each of up to hundreds of thousands of steps (a
# two-agent report with three is 9 MB), so not the cap of a spec file's size
MAX_REPORT_BYTES = 256 * 2**20


def load_counterexample(path: Path) -> Counterexample:
    """The firing sequence of a replay file (see the module docstring), or
    :class:`ReplayFileError`. Read within bounds (rssm_dsl/interp/trace.py): a regular file;
    a trace of JSON lines streamed a line at a time, each line at most ``MAX_FILE_BYTES``; a
    JSON document (a report, a counterexample, a list) at most ``MAX_REPORT_BYTES`` in all."""
    from rssm_dsl.gcpause import collector_paused
    from rssm_dsl.interp.trace import TraceFileError, check_trace_file

    try:
        size = check_trace_file(path)
        with path.open("rb") as f, collector_paused():
            return _load(path, f, size)
    except TraceFileError as e:            # its message names the line where it is one's
        raise ReplayFileError(_coded(e.message)) from None
    except OSError as e:
        raise ReplayFileError(_coded(f"cannot read '{path}': {e.strerror or e}")) from None


def _coded(message: str) -> str:
    """A problem of the replay file as `simulate` prints it (after ``rssmc: --replay:``):
    with its code, E852 (a trace or counterexample file that cannot be read)."""
    return f"error[E852]: {message}"


def _load(path: Path, f: IO[bytes], size: int) -> Counterexample:
    from rssm_dsl.interp.trace import (
        bounded_lines,
        json_problem,
        starts_with_event,
        too_large,
    )

    if starts_with_event(f):                          # JSON lines: streamed, any length
        f.seek(0)
        return _from_trace(path, bounded_lines(f))
    if size > MAX_REPORT_BYTES:
        raise too_large(path, size, MAX_REPORT_BYTES)
    f.seek(0)
    data_bytes = f.read(MAX_REPORT_BYTES + 1)
    try:
        text = data_bytes.decode("utf-8")
    except UnicodeDecodeError as e:
        line = data_bytes.count(b"\n", 0, e.start) + 1
        raise ReplayFileError(_coded(f"line {line}: not UTF-8 text (byte {e.start})")) from None
    try:
        data = json.loads(text)
    except json.JSONDecodeError:
        data = None
    except (ValueError, RecursionError) as e:
        problem = json_problem(e)
        if problem is None:
            raise
        raise ReplayFileError(_coded(problem)) from None
    if data is None or (isinstance(data, dict) and "event" in data):   # JSON lines
        return _from_trace(path, iter(text.split("\n")))
    try:
        if isinstance(data, list):
            return Counterexample("trace", _names(data, "the list"))
        if isinstance(data, dict):
            return _from_object(data)
    except RecursionError as e:            # reports nested in reports: _from_object recurses
        raise ReplayFileError(_coded(str(json_problem(e)))) from None
    except ReplayFileError as e:
        raise ReplayFileError(_coded(str(e))) from None
    raise ReplayFileError(_coded(f"{path} holds no firing sequence"))


def _from_trace(path: Path, lines: Iterator[str | bytes]) -> Counterexample:
    """The fire events of a trace of JSON lines, read by the one trace reader: a malformed
    line is that reader's error (a :class:`TraceFormatError`, word for word)."""
    from rssm_dsl.interp.trace import json_problem

    names: dict[str, str] = {}             # one string per transition, however many firings
    steps: list[str] = []
    count = 0

    def counted() -> Iterator[str | bytes]:
        nonlocal count
        for raw in lines:
            count += 1
            yield raw

    try:
        for event in iter_events(counted(), str(path)):
            if isinstance(event, Fire):
                steps.append(names.setdefault(event.transition, event.transition))
    except TraceFormatError as e:
        raise ReplayFileError(str(e)) from None
    except (ValueError, RecursionError) as e:
        problem = json_problem(e)
        if problem is None:
            raise
        raise ReplayFileError(_coded(f"line {count}: {problem}")) from None
    if not steps:
        raise ReplayFileError(_coded(f"{path} holds no firing sequence"))
    return Counterexample("trace", tuple(steps))


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
          sim: Simulator, watch: PropertyWatch | None = None,
          values: ValueChoices | None = None) -> ReplayVerdict:
    """Does the replayed run end where the verifier said? (A property's counterexample:
    judged by its ``watch``.) The values set as the verifier chose them (``values``) are
    listed in the message."""
    verdict = watch.judge(result) if watch is not None else _judge(cx, forced, result, sim)
    if values is not None and values.note():
        verdict = replace(verdict, message=verdict.message + values.note())
    return verdict


def _judge(cx: Counterexample, forced: list[int], result: RunResult,
           sim: Simulator) -> ReplayVerdict:
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
    if (result.reason == "finished" and cx.kind == "trace" and forced
            and result.steps == len(forced)):
        # the last firing of the trace finished the system: the run it recorded ended there
        return ReplayVerdict(True, f"replayed {result.steps} firings; the system finished, "
                             "as in the trace", result.diagnostics)
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


# ---------------------------------------------------------------------- chosen values


class ValueChoices:
    """The values a counterexample's verifier chose where the data does not decide them
    (``Counterexample.values``: what a device reads, a value computed from untracked data),
    set in the replayed run. The verifier takes any value of the domain there, the
    interpreter the device's: without them a run the verifier found possible would replay
    with other data. A value chosen at the fork of a transition function is set where the
    function writes it (into the staged values, before the join commits them), else at the
    join; one chosen elsewhere (a receive) at once. Each value that differs from the run's
    own is listed in ``set``, as a forced condition is marked in the trace.

    ``observe`` is the simulator's hook after each firing; ``apply`` sets what is pending
    after a firing the replay makes outside the sequence (``PropertyWatch._settle``)."""

    def __init__(self, rt: Runtime, cx: Counterexample) -> None:
        self.rt = rt
        self.at: dict[int, list[tuple[str, str, Any]]] = {}
        for i, sub, var, value in cx.values:
            self.at.setdefault(i, []).append((sub, var, value))
        self.base, self.size = len(cx.steps) + len(cx.to_cycle), len(cx.cycle)
        self.forks = dict(rt.net.new_sites.forks)
        self.joins = dict(rt.net.new_sites.joins)
        self.pending: dict[str, dict[str, tuple[Any, int]]] = {}   # value, step chosen
        self.fired = 0
        self.set: list[str] = []

    def observe(self, t: int) -> None:
        pos = self.fired
        self.fired += 1
        if self.size and pos >= self.base + self.size:
            pos = self.base + (pos - self.base) % self.size
        for sub, var, value in self.at.get(pos, ()):
            if sub not in self.rt.subsystems:
                continue
            if self.forks.get(t) == sub:
                self.pending.setdefault(sub, {})[var] = (value, self.fired)
            else:
                self._put(sub, var, value, self.fired)
        self.apply(t)

    def apply(self, t: int) -> None:
        for sub in list(self.pending):
            st = self.rt.subsystems[sub]
            joined = self.joins.get(t) == sub
            for var, (value, step) in list(self.pending[sub].items()):
                if var in st.stage or joined:
                    self._put(sub, var, value, step)
                    del self.pending[sub][var]
            if joined or not self.pending[sub]:
                del self.pending[sub]

    def _put(self, sub: str, var: str, value: Any, step: int) -> None:
        """Set ``var`` of ``sub`` (staged when its transition function has written it) to
        the ``value`` chosen at firing ``step`` (from 1)."""
        st = self.rt.subsystems[sub]
        where = st.stage if var in st.stage else st.vars
        old = where.get(var)
        if type(old) is not type(value) or old != value:
            self.set.append(f"{sub}.{var} = {short(value)} (chosen at step {step}; the run "
                            f"had {short(old)})")
        where[var] = value

    def note(self) -> str:
        """What the replay set, for the verdict's message ("" when nothing)."""
        if not self.set:
            return ""
        return ("; values the data does not decide, set as the verifier chose them: "
                + ", ".join(self.set))


def chain(*hooks: Callable[[int], None] | None) -> Callable[[int], None] | None:
    """One ``SimOptions.observe`` calling each hook given, in order (None when none)."""
    live = [h for h in hooks if h is not None]
    if not live:
        return None
    if len(live) == 1:
        return live[0]

    def observe(t: int) -> None:
        for h in live:
            h(t)

    return observe


# ---------------------------------------------------------------------- properties

_PENDING = object()          # a value a transition function under way has yet to commit
SETTLE_STEPS = 10_000        # local steps allowed to complete a transition function


@dataclass
class _Seen:
    """One state of a replayed property counterexample: after ``step`` firings."""

    step: int
    ins: dict[tuple[str, str], bool]
    vals: dict[tuple[str, str], Any]
    marking: frozenset[int]


class PropertyWatch:
    """Judges a replayed counterexample of a property stated in the spec (`always P`,
    `whenever P eventually Q`) on the simulator's state, with the property's expressions
    compiled by :class:`rssm_dsl.semantics.properties.Formula` (the code the interpreter runs,
    by which the verifier evaluates them too).

    The atoms are read as the verifier reads them: `SUB in BEH` is true when a place of BEH's
    page of SUB is marked; `SUB.NAME` is the variable's value, where a transition function
    under way (its fork fired, its join not yet) counts as applied. The verifier applies a
    transition function at its fork, the interpreter commits it at its join, and nothing
    changes the subsystem's variables in between, so such a value is read when the join
    fires; one still under way when the replay ends is completed by its own local steps
    first (they change no behaviour and nothing of another subsystem, and are not part of
    the replayed sequence).

    ``observe`` is the simulator's hook after each firing (SimOptions.observe); ``attach``
    is called with the simulator before the run."""

    def __init__(self, rt: Runtime, prop: Property, cx: Counterexample) -> None:
        from rssm_dsl.semantics.properties import Formula, InBehaviour, Value

        self.rt, self.prop, self.cx = rt, prop, cx
        self.formulas = [Formula(rt.system, e) for e in prop.expressions]
        net = rt.net
        self.forks = dict(net.new_sites.forks)
        self.joins = dict(net.new_sites.joins)
        atoms = [a for f in self.formulas for a in f.atoms]
        self.behaviours = {
            (a.subsystem_id, a.behaviour): tuple(
                p.index for p in net.places
                if p.subsystem == a.subsystem_id and p.behaviour == a.behaviour)
            for a in atoms if isinstance(a, InBehaviour)}
        self.values = sorted({(a.subsystem_id, a.variable_name) for a in atoms
                              if isinstance(a, Value)})
        self.start = len(cx.steps)    # the state judged (always) / where P holds (response)
        self.under_way: set[str] = set()
        self.fired = 0
        self.seen: list[_Seen] = []
        self.sim: Simulator | None = None
        self.chosen: ValueChoices | None = None   # the chosen values, set in _settle too

    # -- during the run
    def attach(self, sim: Simulator) -> None:
        self.sim = sim
        if self.start == 0:
            self._look()

    def observe(self, t: int) -> None:
        self.fired += 1
        sid = self.joins.get(t)
        if sid is not None:
            self.under_way.discard(sid)
            self._resolve(sid)
        sid = self.forks.get(t)
        if sid is not None:
            self.under_way.add(sid)
        if self.fired == self.start or (self.fired > self.start
                                        and self.prop.kind == "response"):
            self._look()

    def _look(self) -> None:
        assert self.sim is not None
        marking = self.sim.game.marking()
        ins = {k: any(p in marking for p in places) for k, places in self.behaviours.items()}
        vals = {(sid, name): _PENDING if sid in self.under_way
                else self.rt.subsystems[sid].vars[name] for sid, name in self.values}
        self.seen.append(_Seen(self.fired, ins, vals, marking))

    def _resolve(self, sid: str) -> None:
        variables = self.rt.subsystems[sid].vars
        for seen in self.seen:
            for (owner, name), v in seen.vals.items():
                if owner == sid and v is _PENDING:
                    seen.vals[owner, name] = variables[name]

    def _settle(self) -> None:
        """Complete the transition functions still under way (see the class docstring)."""
        sim = self.sim
        assert sim is not None
        game, net, guards = sim.game, self.rt.net, self.rt.guards
        for sid in sorted(self.under_way & {sid for sid, _ in self.values}):
            for _ in range(SETTLE_STEPS):
                ready = [t for t in sorted(game.enabled) if net.transitions[t].subsystem == sid
                         and (guards[t] is None or guards[t]())]   # type: ignore[misc]
                if not ready:
                    break
                sim.fire[ready[0]]()
                if self.chosen is not None:
                    self.chosen.apply(ready[0])
                if ready[0] in self.joins:
                    self._resolve(sid)
                    break

    # -- after the run
    def _holds(self, k: int, seen: _Seen) -> bool:
        def value(sid: str, name: str) -> Any:
            v = seen.vals[sid, name]
            if v is _PENDING:
                raise LookupError("its transition function could not be completed")
            return v

        return self.formulas[k](lambda s, b: seen.ins.get((s, b), False), value)

    def _atoms(self, seen: _Seen) -> str:
        from rssm_dsl.semantics.properties import written

        system = self.rt.system
        parts = [f"{written(system, s)} in {b} = {str(v).lower()}"
                 for (s, b), v in seen.ins.items()]
        parts += [f"{written(system, s)}.{n} = "
                  + (str(v).lower() if isinstance(v, bool) else str(v))
                  for (s, n), v in seen.vals.items()]
        return ", ".join(parts)

    def judge(self, result: RunResult) -> ReplayVerdict:
        from rssm_dsl.interp.errors import EvalError
        from rssm_dsl.semantics.properties import PropertyError, UnknownValue
        from rssm_dsl.syntax.printer import expr_text

        name = self.prop.name
        texts = [f"`{expr_text(e)}`" for e in self.prop.expressions]
        fail = f"the violation of property {name} is not reproduced"
        # a response property violated by the system's end: the run finishes on the path
        ended = result.reason == "finished" and self.prop.kind == "response"
        if result.reason != "replayed" and not ended:
            what = f"stopped at step {result.steps}" if result.reason == "error" else \
                f"stopped early ({result.reason})"
            return ReplayVerdict(False, f"the replay {what}: {result.message}; {fail}",
                                 result.diagnostics)
        try:
            self._settle()
        except EvalError as e:
            return ReplayVerdict(False, f"completing a transition function under way failed: "
                                 f"{e.message}; {fail}")
        try:
            return self._always(texts[0], fail) if self.prop.kind == "always" else \
                self._response(texts[0], texts[1], fail, ended)
        except (UnknownValue, PropertyError, EvalError) as e:
            message = e.message if isinstance(e, EvalError) else str(e)
            return ReplayVerdict(False, f"{', '.join(texts)} cannot be evaluated on the "
                                 f"replayed state: {message}; {fail}")

    def _always(self, p: str, fail: str) -> ReplayVerdict:
        name, n = self.prop.name, self.start
        seen = self.seen[-1] if self.seen else None
        if seen is None or seen.step != n:
            return ReplayVerdict(False, f"the state after {n} firings was not observed; {fail}")
        if self._holds(0, seen):
            return ReplayVerdict(False, f"after the {n} firings of the counterexample {p} "
                                 f"holds ({self._atoms(seen)}): {fail}")
        return ReplayVerdict(True, f"property {name} violated: after {n} firings {p} is false "
                             f"({self._atoms(seen)})")

    def _response(self, p: str, q: str, fail: str, ended: bool = False) -> ReplayVerdict:
        name, n, cx = self.prop.name, self.start, self.cx
        at = {s.step: s for s in self.seen}
        first = at.get(n)
        if first is None:
            return ReplayVerdict(False, f"the state after {n} firings was not observed; {fail}")
        if not self._holds(0, first):
            return ReplayVerdict(False, f"after the {n} firings of the path {p} does not hold "
                                 f"({self._atoms(first)}): {fail}")
        for seen in self.seen:
            if seen.step >= n and self._holds(1, seen):
                return ReplayVerdict(False, f"{q} holds after {seen.step} firings "
                                     f"({self._atoms(seen)}): {fail}")
        later = len(self.seen) - 1
        if ended:
            return ReplayVerdict(True, f"property {name} violated: after {n} firings {p} "
                                 f"holds ({self._atoms(first)}), and {q} holds at none of the "
                                 f"{later} states that follow, up to the system's end (every "
                                 "agent terminated)")
        entry, size = n + len(cx.to_cycle), len(cx.cycle)
        if size == 0:
            assert self.sim is not None
            marking = self.sim.game.marking()
            enabled = self.sim.game.rule.enabled_set(marking)
            if enabled:
                return ReplayVerdict(False, f"the path ends where {len(enabled)} transition(s) "
                                     f"are still enabled, and the counterexample has no cycle "
                                     f"to repeat: {fail}")
            return ReplayVerdict(True, f"property {name} violated: after {n} firings {p} "
                                 f"holds ({self._atoms(first)}), and {q} holds at none of the "
                                 f"{later} states that follow, up to a marking where nothing "
                                 "can fire")
        ends = [at.get(entry + k * size) for k in range(CYCLES + 1)]
        marks = {e.marking if e is not None else None for e in ends}
        if None in marks or len(marks) != 1:
            return ReplayVerdict(False, f"the cycle does not come back to the marking it "
                                 f"started from: {fail}")
        return ReplayVerdict(True, f"property {name} violated: after {n} firings {p} holds "
                             f"({self._atoms(first)}), and {q} holds at none of the {later} "
                             f"states that follow, the cycle of {size} firings replayed "
                             f"{CYCLES} times back to the marking it started from")
