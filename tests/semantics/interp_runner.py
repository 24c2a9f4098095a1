"""Run a specification in the interpreter (deterministic mode, simulated clock) through its
public entry points, with a trace, and read the run back: the trace's events, the marking of
the flat net at every step (the trace's firings replayed on the net: a traced run fires
every transition one by one), the subsystems' final variables."""

from __future__ import annotations

import json
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from rssm_dsl.hpn.flat import FlatNet
from rssm_dsl.interp import RunConfig, SimOptions, Simulator, build_runtime
from rssm_dsl.interp.trace import TraceWriter
from tests.semantics.netview import compile_spec, flat_net

Event = dict[str, Any]


@dataclass
class InterpRun:
    path: Path
    net: FlatNet
    events: list[Event]
    reason: str
    message: str
    codes: list[str]                      # diagnostic codes of the run
    memory: dict[str, dict[str, Any]]     # subsystem id -> its variables at the end
    summary: dict[str, Any]

    def of(self, kind: str) -> list[Event]:
        return [e for e in self.events if e["event"] == kind]

    def firings(self) -> Iterator[tuple[Event, frozenset[int], frozenset[int]]]:
        """Every fire event with the marking before and after it (the trace replayed on the
        flat net; a firing that is not enabled fails the test)."""
        index = {t.name: t for t in self.net.transitions}
        marking = frozenset(self.net.initial)
        for e in self.events:
            if e["event"] != "fire":
                continue
            t = index[e["transition"]]
            assert set(t.pre) <= marking, f"{t.name} fired but is not enabled (step {e['step']})"
            after = (marking - set(t.pre)) | set(t.post)
            yield e, marking, after
            marking = after

    def iterations(self, subsystem: str) -> dict[str, int]:
        view = next(s for s in self.summary["subsystems"] if s["id"] == subsystem)
        return dict(view["iterations"])


def simulate(path: Path, until: float | None = None, steps: int | None = None,
             seed: int = 0) -> InterpRun:
    comp = compile_spec(path)
    rt = build_runtime(comp, RunConfig(base_dir=path.parent))
    trace = path.with_suffix(f".{seed}.jsonl")
    rt.tracer = TraceWriter(trace)
    try:
        result = Simulator(rt, SimOptions(seed=seed, until=until, max_steps=steps)).run()
    finally:
        rt.tracer.close()
    events = [json.loads(x) for x in trace.read_text().splitlines() if x.strip()]
    memory = {sid: dict(s.vars) for sid, s in rt.subsystems.items()}
    summary = result.summary.to_json() if result.summary is not None else {}
    return InterpRun(path, flat_net(comp), events, result.reason, result.message,
                     [d.code for d in result.diagnostics], memory, summary)
