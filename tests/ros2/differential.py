"""Differential comparison of generated ROS 2 nodes with the interpreter, for any
specification.

Two records per designed subsystem (control, virtual effectors and receptors; devices have
no node trace): what the interpreter did (``interpreter_records``, from its trace) and what
the subsystem's node did (``node_record``, from the node's trace file): the behaviour
switches, the iterations (behaviour, ``new(x)`` flags, data case of every partial function),
the values taken per input buffer, and (interpreter only) the values sent per output buffer.

Which parts of a run the semantics determine
--------------------------------------------

The nodes run on real clocks and real DDS; the interpreter interleaves its firings its own way
(simulated time, a seeded choice). Only what the semantics guarantee whatever the timing may
be compared. The rule (``deterministic_subsystems``):

A designed subsystem S is *deterministic* when every input buffer of S

* is consumed **blocking** (a receive waits for a sample newer than the last one taken), and
* is produced **blocking** (the producer waits until its sample is taken, so no sample is
  overwritten and none is taken twice), and
* is produced by a designed subsystem (not a device: a device node steps a physical or
  replayed process on its own clock, so the values it sends depend on timing), which is
  itself deterministic.

The deterministic subsystems are the greatest set closed under this rule (cycles of blocking
channels included): together they form a Kahn process network whose channels are bounded
one-place FIFOs with blocking reads and writes, whose sequences of values exchanged, and
hence each process's sequence of states, do not depend on the interleaving (Kahn 1974; a
bounded network can only deadlock earlier, and at the same point in every schedule). The
remaining ingredients of a subsystem's state are timing-free too: the expressions of the
language read no clock (there is no time builtin; a frequency only paces the iterations),
``new(x)`` after a blocking receive is true, and external operations are taken as the
(pure) functions the semantics make of them. A subsystem without inputs is deterministic.

For a deterministic subsystem the node's record must be a *prefix* of the interpreter's:
switches, iterations (behaviour, new flags, cases), values taken per buffer; equal when both
ended. (Prefix only: the node may be stopped before it ends, a nonterminating system is run
for a while, and the interpreter's run is bounded.) Where the interpreter's record of the
subsystem is complete the node cannot have done more than it: when the subsystem ended
there (its ending is part of its determined sequence), or when the run ended by itself
(finished or deadlocked) and the whole system is deterministic (every designed subsystem, no
device). Not merely when the run ended: a deterministic subsystem can be held up by the
back-pressure of a blocking output whose consumer is not deterministic (it ends, or stops
taking, at a point that depends on timing), so where it stops is not determined.

For any other subsystem only its inputs are compared, one at a time. When the producer P of
input x is a deterministic designed subsystem, the values P sends are determined (the
interpreter's ``send`` events of that buffer), and:

* P blocking (either consumer mode): each sample is taken exactly once, in order, so the
  values taken are a prefix of the values sent;
* P non-blocking: a sample can be overwritten before it is taken, and is never taken twice,
  so the values taken are a subsequence of the values sent, in order.

Both are checked exactly through the sequence numbers the samples carry (docs/ros2.md: a
producer numbers its samples from 1): the sample numbered s that the node took must be the
s-th value P sent in the interpreter's run (when that run has an s-th; when the run is complete
it must have one).

Whatever the producer (a device too, deterministic or not), the sequence numbers taken
increase strictly, and when the producer blocks they are exactly 1, 2, 3, ... (a blocking
producer waits for the take of each sample before it sends the next: none is skipped).
Nothing else is asserted: the behaviours, switches and iterations of a non-deterministic
subsystem depend on when its samples arrive.
"""

from __future__ import annotations

import itertools
import json
import re
from collections.abc import Iterable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from rssm_core.modes import Mode
from rssm_dsl.hpn.ir import CondKind
from rssm_dsl.interp import RunConfig, SimOptions, Simulator, build_runtime
from rssm_dsl.interp.trace import TraceWriter, read_trace
from rssm_dsl.pipeline import Compilation, compile_file
from rssm_dsl.semantics.model import Buffer, System
from tests.conftest import ROOT

_INDEX = re.compile(r"\[([^\]]*)\]$")

Iteration = tuple[str, list[bool], list[int]]       # behaviour, new(x), case per function
SwitchRec = tuple[str | None, str | None]            # from, to (None: entry / end)


@dataclass
class Record:
    """What one subsystem did."""

    switches: list[SwitchRec] = field(default_factory=list)
    iterations: list[Iteration] = field(default_factory=list)
    received: dict[str, list[Any]] = field(default_factory=dict)   # buffer -> values taken
    seqs: dict[str, list[int]] = field(default_factory=dict)       # buffer -> seqs (nodes)
    sent: dict[str, list[Any]] = field(default_factory=dict)       # buffer -> values (interp)

    @property
    def ended(self) -> bool:
        return bool(self.switches) and self.switches[-1][1] is None


@dataclass
class InterpreterRun:
    records: dict[str, Record]
    reason: str                  # "finished", "deadlock", "max_steps", "until", ...

    @property
    def complete(self) -> bool:
        """The run ended by itself (not cut by a bound)."""
        return self.reason in ("finished", "deadlock")


def compile_spec(spec: Path) -> Compilation:
    comp = compile_file(spec.relative_to(ROOT) if spec.is_relative_to(ROOT) else spec)
    assert comp.ok and comp.hpn is not None and comp.system is not None, comp.diagnostics
    return comp


def subsystem_ids(system: System) -> list[str]:
    return [s.id for s in system.subsystems()]


def _last_indices(name: str) -> list[str]:
    m = _INDEX.search(name)
    assert m is not None, name
    return m.group(1).split(",")


def interpreter_records(spec: Path, trace: Path, *, until: float | None = None,
                        max_steps: int = 300_000) -> InterpreterRun:
    """Run the interpreter on ``spec`` (seed 0) and gather each subsystem's record."""
    comp = compile_spec(spec)
    assert comp.hpn is not None and comp.system is not None
    rt = build_runtime(comp, RunConfig(base_dir=spec.parent))
    rt.tracer = TraceWriter(trace)
    result = Simulator(rt, SimOptions(seed=0, max_steps=max_steps, until=until)).run()
    hpn, system = comp.hpn, comp.system
    functions = {(s.id, b.name): len(b.functions) for s in system.subsystems()
                 for b in s.behaviours}
    pending: dict[str, list[tuple[int, int, tuple[bool, ...], str]]] = {}
    out = {sid: Record() for sid in subsystem_ids(system)}
    for e in read_trace(trace):
        kind = e["event"]
        if kind == "fire":
            t = hpn.transitions[e["transition"]]
            c = t.condition
            if c is None or c.kind is not CondKind.CASE:
                continue
            assert c.behaviour is not None and c.new is not None
            psi, varpi = (int(x) for x in _last_indices(t.id)[-2:])
            group = pending.setdefault(c.subsystem, [])
            group.append((psi, varpi, c.new, c.behaviour))
            if len(group) == functions[c.subsystem, c.behaviour]:
                group.sort()
                out[c.subsystem].iterations.append(
                    (c.behaviour, list(c.new), [v for _, v, _, _ in group]))
                pending[c.subsystem] = []
        elif kind == "receive" and e["subsystem"] in out:
            out[e["subsystem"]].received.setdefault(e["buffer"], []).append(e["value"])
        elif kind == "send" and e["subsystem"] in out:
            out[e["subsystem"]].sent.setdefault(e["buffer"], []).append(e["value"])
        elif kind == "enter" and e["subsystem"] in out:
            out[e["subsystem"]].switches.append((None, e["behaviour"]))
        elif kind == "switch" and e["subsystem"] in out:
            out[e["subsystem"]].switches.append((e["from"], e["to"]))
    return InterpreterRun(out, result.reason)


def node_record(trace: Path) -> Record:
    """A node's record from its trace file (empty when the node wrote none)."""
    rec = Record()
    if not trace.exists():
        return rec
    for line in trace.read_text().splitlines():
        if not line.strip():
            continue
        try:
            e = json.loads(line)
        except json.JSONDecodeError:       # a last line cut by a kill
            break
        if e["event"] == "iteration":
            rec.iterations.append((e["behaviour"], e["new"], e["cases"]))
            for buffer, got in e["received"].items():
                rec.received.setdefault(buffer, []).append(got["value"])
                rec.seqs.setdefault(buffer, []).append(got["seq"])
        elif e["event"] in ("enter", "switch"):
            rec.switches.append((e["from"], e["to"]))
    return rec


def _producers(system: System) -> dict[tuple[str, str], Buffer]:
    """(consumer id, input buffer) -> the producer's buffer."""
    return {(ch.consumer.owner, ch.consumer.name): ch.producer for ch in system.channels}


def deterministic_subsystems(system: System) -> set[str]:
    """The greatest set of designed subsystems closed under the rule of the module's
    docstring."""
    subsystems = {s.id: s for s in system.subsystems()}
    producers = _producers(system)
    det = set(subsystems)
    changed = True
    while changed:
        changed = False
        for sid in sorted(det):
            for x in subsystems[sid].inputs:
                p = producers.get((sid, x.name))
                if (p is None or x.mode is not Mode.BLOCKING or p.mode is not Mode.BLOCKING
                        or p.owner not in det):
                    det.discard(sid)
                    changed = True
                    break
    return det


def _prefix(what: str, got: list[Any], want: list[Any], *, want_complete: bool,
            got_ended: bool, want_ended: bool) -> list[str]:
    n = min(len(got), len(want))
    for k in range(n):
        if got[k] != want[k]:
            return [f"{what}: #{k} is {got[k]!r}, the interpreter's {want[k]!r} "
                    f"(first {k} agree)"]
    if want_complete and len(got) > len(want):
        return [f"{what}: the node has {len(got)} entries, the interpreter's complete run "
                f"{len(want)}; next {got[len(want)]!r}"]
    if got_ended and want_ended and len(got) != len(want):
        return [f"{what}: both ended, {len(got)} entries against {len(want)}"]
    return []


@dataclass
class Comparison:
    """What was compared (for the report) and what disagreed."""

    full: list[str] = field(default_factory=list)          # deterministic subsystems
    inputs: list[str] = field(default_factory=list)        # inputs from deterministic producers
    consecutive: list[str] = field(default_factory=list)   # inputs from blocking producers
    compared_iterations: int = 0
    compared_values: int = 0
    mismatches: list[str] = field(default_factory=list)


def compare(system: System, interp: InterpreterRun, nodes: dict[str, Record]) -> Comparison:
    det = deterministic_subsystems(system)
    producers = _producers(system)
    out = Comparison()
    whole = interp.complete and det == set(interp.records) and not any(
        a.devices for a in system.agents)
    for s in system.subsystems():
        sid = s.id
        want, got = interp.records[sid], nodes[sid]
        complete = whole or want.ended
        if sid in det:
            out.full.append(sid)
            out.compared_iterations += min(len(got.iterations), len(want.iterations))
            # the interpreter's side is the data case that ran, whose new(x) is None for an
            # input no case clause of the behaviour splits (semantics/cases.py): the node's
            # flag of such an input selects nothing and is not compared
            seen = [(b, [None if c is None else n for n, c in zip(new, case[1], strict=True)],
                     cases) if case is not None and len(new) == len(case[1]) else (b, new, cases)
                    for (b, new, cases), case in itertools.zip_longest(
                        got.iterations, want.iterations[:len(got.iterations)])]
            for what, g, w in (("switches", got.switches, want.switches),
                               ("iterations", seen, want.iterations)):
                out.mismatches += [f"{sid} {m}" for m in _prefix(
                    what, g, w, want_complete=complete, got_ended=got.ended,
                    want_ended=want.ended)]
        for x in s.inputs:
            p = producers.get((sid, x.name))
            taken = got.received.get(x.name, [])
            seqs = got.seqs.get(x.name, [])
            if any(b <= a for a, b in itertools.pairwise(seqs)):
                out.mismatches.append(f"{sid}.{x.name}: seqs taken not increasing: {seqs}")
            if p is not None and p.mode is Mode.BLOCKING:
                out.consecutive.append(f"{sid}.{x.name}")
                if seqs != list(range(1, len(seqs) + 1)):
                    out.mismatches.append(f"{sid}.{x.name}: a blocking producer's samples "
                                          f"skipped or repeated: seqs {seqs}")
            if p is None or p.owner not in det:
                continue
            sent = interp.records[p.owner].sent.get(p.name, [])
            p_complete = whole or interp.records[p.owner].ended
            out.inputs.append(f"{sid}.{x.name}: sample #seq of {p.qualified} "
                              f"({p.mode.value} producer)")
            for seq, value in zip(seqs, taken, strict=True):
                if seq <= len(sent):
                    out.compared_values += 1
                    if value != sent[seq - 1]:
                        out.mismatches.append(
                            f"{sid}.{x.name}: sample {seq} taken is {value!r}, "
                            f"{p.qualified} sent {sent[seq - 1]!r} as its sample {seq}")
                        break
                elif p_complete:
                    out.mismatches.append(
                        f"{sid}.{x.name}: sample {seq} taken, {p.qualified} sent only "
                        f"{len(sent)} in the interpreter's complete run")
                    break
    return out


def describe(comparisons: Iterable[tuple[str, Comparison]]) -> str:
    return "\n".join(f"{name}: full {c.full}, inputs {c.inputs}, consecutive {c.consecutive}, "
                     f"{c.compared_iterations} iterations, {c.compared_values} values"
                     for name, c in comparisons)
