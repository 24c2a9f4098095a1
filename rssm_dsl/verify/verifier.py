"""``verify(net, options)``: place invariants, then the state space, then the verdict.

Pipeline:

1. Minimal P-semiflows (``invariants``). If the invariants carrying one token cover every
   place, the net is safe without exploring a state; either way the places they prove safe
   need no watching in the reduced search.
2. State space, by ``options.reduction``:
   - ``"off"``: full breadth-first exploration (``statespace``) with the reachability graph:
     safeness, deadlocks, dead transitions, unreachable behaviours, progress (``progress``).
   - ``"on"``: stubborn-set exploration only (``stubborn``): exact deadlock and safeness
     verdicts on far fewer states; with ``check_progress`` the search applies the cycle
     proviso and keeps its graph, on which progress is decided (see ``stubborn``); dead
     transitions and unreachable behaviours are not computed (the report says so).
   - ``"auto"`` (default): full exploration up to ``auto_full_states`` markings (it gives dead
     transitions and unreachable behaviours too); beyond, the stubborn-set search (as for
     ``"on"``, up to ``max_states``) takes over.
3. Verdict: *violated* when any violation was found (a found deadlock or unsafe firing is real
   even if the search was cut short); *verified* when safeness, deadlock freedom and (when
   checked) progress are all established; otherwise *inconclusive*, with the reason in the
   notes.

A marking is *final* when the net has final places and all of them are marked; a deadlock in
a final marking is the system having finished, not an error.
"""

from __future__ import annotations

import time
from dataclasses import dataclass

from rssm_dsl.hpn.flat import FlatNet
from rssm_dsl.verify.invariants import DEFAULT_MAX_ROWS, InvariantResult, place_invariants
from rssm_dsl.verify.netbits import NetBits, bits, to_mask
from rssm_dsl.verify.progress import ProgressResult, check_progress, subsystems_of
from rssm_dsl.verify.report import (
    Counterexample,
    InvariantLine,
    Verdict,
    VerifyReport,
    marking_labels,
)
from rssm_dsl.verify.statespace import ProgressCallback, SearchResult, Trace, explore_full
from rssm_dsl.verify.stubborn import explore_reduced


@dataclass(frozen=True)
class VerifyOptions:
    max_states: int = 5_000_000          # per exploration
    auto_full_states: int = 1_000_000    # "auto": the full search's share before stubborn sets
    time_limit: float | None = 300.0     # seconds for the whole verification
    reduction: str = "auto"              # "auto", "on" (stubborn sets only), "off" (full only)
    invariants: bool = True
    max_invariant_rows: int = DEFAULT_MAX_ROWS
    check_progress: bool = True
    max_counterexamples: int = 3
    on_progress: ProgressCallback | None = None

    def __post_init__(self) -> None:
        if self.reduction not in ("auto", "on", "off"):
            raise ValueError(f"reduction must be 'auto', 'on' or 'off', not {self.reduction!r}")


def verify(net: FlatNet, options: VerifyOptions | None = None) -> VerifyReport:
    opts = options or VerifyOptions()
    start = time.monotonic()
    deadline = None if opts.time_limit is None else start + opts.time_limit

    def remaining() -> float | None:
        return None if deadline is None else max(0.0, deadline - time.monotonic())

    nb = NetBits.of(net)
    notes: list[str] = []

    inv: InvariantResult | None = None
    if opts.invariants:
        budget = remaining()
        inv = place_invariants(net, opts.max_invariant_rows,
                               None if budget is None else budget / 3)
        if inv.message:
            notes.append(f"place invariants: {inv.message}")
    safe_mask = to_mask(inv.safe_places) if inv else 0
    safe_by_invariants = inv is not None and inv.proves_safe(nb.nplaces)

    full: SearchResult | None = None
    reduced: SearchResult | None = None
    if opts.reduction in ("auto", "off"):
        limit = (min(opts.max_states, opts.auto_full_states) if opts.reduction == "auto"
                 else opts.max_states)
        full = explore_full(nb, limit, remaining(), keep_graph=opts.check_progress,
                            max_counterexamples=opts.max_counterexamples,
                            progress=opts.on_progress)
        if full.stopped and full.unsafe is None:
            notes.append(f"full exploration: {full.stopped}")
        if (opts.reduction == "auto" and not full.complete and full.unsafe is None
                and not full.deadlocks and "state limit" in (full.stopped or "")):
            reduced = explore_reduced(nb, safe_mask, opts.max_states, remaining(),
                                      opts.max_counterexamples, opts.on_progress,
                                      for_progress=opts.check_progress)
            notes.append(f"stubborn-set exploration took over: {reduced.states} states")
    else:
        reduced = explore_reduced(nb, safe_mask, opts.max_states, remaining(),
                                  opts.max_counterexamples, opts.on_progress,
                                  for_progress=opts.check_progress)
    deciding = reduced if reduced is not None else full
    assert deciding is not None
    if reduced is not None and reduced.stopped and reduced.unsafe is None:
        notes.append(f"stubborn-set exploration: {reduced.stopped}")

    # safeness
    unsafe_trace = deciding.unsafe or (full.unsafe if full else None)
    safe: bool | None
    safe_by: str | None
    if unsafe_trace is not None:
        safe, safe_by = False, ("full exploration" if deciding is full else
                                "stubborn-set exploration")
    elif safe_by_invariants:
        safe, safe_by = True, "place invariants"
    elif deciding.complete:
        safe, safe_by = True, ("full exploration" if deciding is full else
                               "stubborn-set exploration")
    else:
        safe, safe_by = None, None

    # deadlocks
    dead_traces = deciding.deadlocks or (full.deadlocks if full else [])
    dead_count = max(deciding.deadlock_count, full.deadlock_count if full else 0)
    deadlock_free: bool | None
    if dead_count:
        deadlock_free = False
    elif deciding.complete:
        deadlock_free = True
    else:
        deadlock_free = None

    # progress, dead transitions, unreachable behaviours: full graph only
    progress_result: ProgressResult | None = None
    progress_ok: bool | None = None
    dead_transitions = None
    unreachable = None
    if full is not None and full.complete:
        assert full.fired is not None and full.ever_marked is not None
        dead_transitions = tuple(t for t in net.transitions if t.index not in full.fired)
        unreachable = _unreachable_behaviours(net, full.fired, full.ever_marked)
    elif reduced is not None and reduced.complete:
        notes.append("dead transitions and unreachable behaviours need the full state space")
    graph = (full.graph if full is not None and full.complete else
             reduced.graph if reduced is not None and reduced.complete else None)
    if opts.check_progress:
        if graph is not None:
            progress_result = check_progress(nb, graph, subsystems_of(net))
            progress_ok = not progress_result.violations
            if progress_result.skipped:
                notes.append("no ITERATION transition, progress not checked: "
                             + ", ".join(progress_result.skipped))
        else:
            notes.append("progress not decided: the state space was not explored completely")

    progress_cx: list[Counterexample] = []
    if progress_result is not None and graph is not None:
        g = graph
        for v in progress_result.violations:
            progress_cx.append(Counterexample(
                kind="progress", steps=_steps(net, v.prefix),
                marking=marking_labels(net, nb.marking_of(g.marking(v.point))),
                subsystem=v.subsystem, to_cycle=_steps(net, v.to_cycle),
                cycle=_steps(net, v.cycle),
                cycle_marking=marking_labels(net, nb.marking_of(v.cycle_marking))))

    violated = safe is False or deadlock_free is False or progress_ok is False
    if violated:
        verdict = Verdict.VIOLATED
    elif safe and deadlock_free and (progress_ok or not opts.check_progress):
        verdict = Verdict.VERIFIED
    else:
        verdict = Verdict.INCONCLUSIVE

    method = ("full+stubborn" if full is not None and reduced is not None else
              "full" if full is not None else "stubborn")
    return VerifyReport(
        system=net.system,
        verdict=verdict,
        safe=safe,
        safe_by=safe_by,
        invariants=_invariant_lines(net, inv),
        invariants_complete=inv.complete if inv else False,
        invariants_message=inv.message if inv else "not computed",
        uncovered_places=tuple(net.places[p].label or net.places[p].name
                               for p in (inv.uncovered(nb.nplaces) if inv else
                                         range(nb.nplaces))),
        method=method,
        states=deciding.states,
        edges=deciding.edges,
        depth=deciding.depth,
        complete=deciding.complete,
        deadlock_free=deadlock_free,
        deadlock_count=dead_count,
        deadlocks=tuple(_deadlock_cx(net, nb, t) for t in dead_traces),
        unsafe=_unsafe_cx(net, nb, unsafe_trace) if unsafe_trace else None,
        progress_ok=progress_ok,
        progress=tuple(progress_cx),
        progress_checked=progress_result.checked if progress_result else (),
        dead_transitions=dead_transitions,
        unreachable_behaviours=unreachable,
        seconds=time.monotonic() - start,
        notes=tuple(notes),
    )


def _steps(net: FlatNet, steps: tuple[int, ...]) -> tuple:  # type: ignore[type-arg]
    return tuple(net.transitions[t] for t in steps)


def _deadlock_cx(net: FlatNet, nb: NetBits, trace: Trace) -> Counterexample:
    return Counterexample("deadlock", _steps(net, trace.steps),
                          marking_labels(net, nb.marking_of(trace.marking)))


def _unsafe_cx(net: FlatNet, nb: NetBits, trace: Trace) -> Counterexample:
    return Counterexample("unsafe", _steps(net, trace.steps),
                          marking_labels(net, nb.marking_of(trace.marking)),
                          doubled=marking_labels(net, frozenset(bits(trace.places))))


def _invariant_lines(net: FlatNet, inv: InvariantResult | None) -> tuple[InvariantLine, ...]:
    if inv is None:
        return ()
    proves: dict[int, list[str]] = {}
    for p, k in sorted(inv.proof.items()):
        proves.setdefault(k, []).append(net.places[p].label or net.places[p].name)
    return tuple(InvariantLine(i.render(net), i.tokens, tuple(proves.get(k, ())))
                 for k, i in enumerate(inv.invariants))


def _unreachable_behaviours(net: FlatNet, fired: frozenset[int], ever: int) -> tuple[str, ...]:
    seen: dict[tuple[str | None, str], bool] = {}
    where: dict[tuple[str | None, str], str] = {}
    for p in net.places:
        if p.behaviour is not None:
            key = (p.subsystem, p.behaviour)
            seen[key] = seen.get(key, False) or bool(ever >> p.index & 1)
            where.setdefault(key, p.span.location)
    for t in net.transitions:
        if t.behaviour is not None:
            key = (t.subsystem, t.behaviour)
            seen[key] = seen.get(key, False) or t.index in fired
            where.setdefault(key, t.span.location)
    out = []
    for key, reached in seen.items():
        if not reached:
            sub, beh = key
            name = beh if sub is None or beh.startswith(f"{sub}.") else f"{sub}: {beh}"
            out.append(f"{name} ({where[key]})")
    return tuple(out)
