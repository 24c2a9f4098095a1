"""Run every engine and reduction of ``rssmc verify`` on one spec and compare the verdicts;
replay every counterexample in the interpreter (tests/soundness/, bench/soundness.py).

Engines (:data:`ENGINES`), each one call of ``rssm_dsl.verify.verify(net, VerifyOptions(...))``
built as ``rssmc verify`` builds it (``commands/verify.py``: the flat net, the value plan of
``dataplan.value_plan``, progress checked, strong fairness):

* ``off``: the full exploration, the reference;
* ``on``: stubborn sets; ``compositional``: the page-by-page check;
* ``auto``: the default; ``auto-noslice``: ``VerifyOptions(slicing=False)`` (the option that
  turns slicing off under auto; the CLI has no flag for it);
* ``sliced``: auto with ``slice_after_states=1``, so that a net with several blocking groups
  always takes the sliced path (the specs here are small: plain auto explores them whole).

Compared, whenever two engines both decided them: safeness, deadlock freedom, progress, the
set of subsystems that lose progress (when both say progress is lost), and every property of
the spec. The properties are also checked on the whole net with slicing disabled
(``props-whole``: ``userprops`` always slices by blocking groups, whatever the reduction), so
that the sliced property check has something to be compared with. ``off`` is exhaustive, but
the comparison is symmetric: any two decided answers that differ are a disagreement, so specs
that ``off`` cannot finish still compare the engines that did. An engine that stays undecided
within its limits is counted (``Outcome.undecided``), not a disagreement.

Every counterexample an engine reports is replayed in the interpreter by forcing its
firings, as ``rssmc simulate --replay`` does (``rssm_dsl.interp.replay.judge``): a deadlock
must end with nothing enabled, an unsafe firing must double-mark a place, a lasso's cycle must
come back to its marking without the subsystem iterating. A property's counterexample must end
in a state that violates it, read from the interpreter's marking and variables
(:func:`property_violated`). A replay that fails is a disagreement.

:func:`compare_simulation` is the hook for violations found by simulation (a falsifier): each
contradicts an engine that proved the property it violates.
"""

from __future__ import annotations

import functools
import time
import traceback
from collections.abc import Callable, Iterable, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from rssm_dsl.hpn.flat import FlatNet
from rssm_dsl.hpn.flatten import flatten
from rssm_dsl.pipeline import Compilation, compile_file
from rssm_dsl.verify import VerifyOptions, verify
from rssm_dsl.verify.budget import Budget, LimitReached
from rssm_dsl.verify.dataplan import value_plan
from rssm_dsl.verify.report import Counterexample, PropertyResult, VerifyReport

ENGINES: dict[str, dict[str, Any]] = {
    "off": {"reduction": "off"},
    "on": {"reduction": "on"},
    "compositional": {"reduction": "compositional"},
    "auto": {"reduction": "auto"},
    "auto-noslice": {"reduction": "auto", "slicing": False},
    "sliced": {"reduction": "auto", "slice_after_states": 1},
}
PROPS_WHOLE = "props-whole"
MID_FUNCTION = "inside the transition function"
FIELDS = ("safe", "deadlock_free", "progress_ok")


@dataclass(frozen=True)
class Limits:
    seconds: float = 10.0          # per engine
    max_states: int = 400_000      # per exploration


@dataclass
class Outcome:
    """One engine's answers on one spec (None: not decided)."""

    engine: str
    verdict: str
    safe: bool | None
    deadlock_free: bool | None
    progress_ok: bool | None
    lost: frozenset[str]
    properties: dict[str, bool | None]
    method: str
    seconds: float
    why: str | None
    counterexamples: list[Counterexample] = field(default_factory=list)
    property_cxs: dict[str, Counterexample] = field(default_factory=dict)
    stopped: bool = False          # a limit of the run (time, memory) ended it
    checked: frozenset[str] = frozenset()   # the subsystems whose progress was decided
    escaped: str | None = None     # LimitReached raised out of verify(): where

    @property
    def undecided(self) -> bool:
        return (self.safe is None or self.deadlock_free is None or self.progress_ok is None
                or any(v is None for v in self.properties.values()))


@dataclass(frozen=True)
class Disagreement:
    what: str                      # "safe", "progress lost", "property p0", "replay", ...
    detail: str

    def __str__(self) -> str:
        return f"{self.what}: {self.detail}"


@dataclass
class SpecResult:
    name: str
    outcomes: dict[str, Outcome]
    disagreements: list[Disagreement]
    replays: int = 0
    error: str | None = None       # the spec did not compile (a generator bug) or a crash
    seconds: float = 0.0
    ending: frozenset[str] = frozenset()   # subsystems with a switch to `end`

    def known(self, d: Disagreement) -> str | None:
        """The known bug (``KNOWN_BUGS``) that explains ``d``, if any. When a property's
        verdict is disputed, its counterexample's failed replay is explained (or not) with
        that dispute."""
        if d.what.startswith("replay property "):
            name = d.what.removeprefix("replay property ")
            for x in self.disagreements:
                if x.what == f"property {name}":
                    return known_bug(x, self.outcomes, self.ending)
        return known_bug(d, self.outcomes, self.ending)

    @property
    def unexplained(self) -> list[Disagreement]:
        return [d for d in self.disagreements if self.known(d) is None]


# Engine bugs found by this harness and not fixed yet, each pinned by a strict xfail
# regression in tests/soundness/regressions/ (its header says the right verdict and why).
# ``known_bug`` recognises their signature so that a batch can tell them from new
# disagreements; remove an entry once its regression passes.
KNOWN_BUGS: dict[str, str] = {}


def known_error(error: str | None) -> str | None:
    """The known bug that explains a crash of the harness (``SpecResult.error``): none
    (a LimitReached out of verify() was one, fixed: limit_in_property_lasso.rssm)."""
    return None


def known_bug(d: Disagreement, outcomes: Mapping[str, Outcome],
              ending: frozenset[str]) -> str | None:
    """The entry of ``KNOWN_BUGS`` whose signature ``d`` has. The four bugs found so far
    are fixed (regressions/*.rssm); a new one gets its entry and its test here."""
    return None


@dataclass(frozen=True)
class SimulationFinding:
    """A violation found by simulation (the converse check): ``kind`` is "deadlock",
    "unsafe", "progress" (with ``subsystem``) or "property" (with ``name``)."""

    kind: str
    subsystem: str | None = None
    name: str | None = None
    detail: str = ""


# ------------------------------------------------------------------------ compile, verify


def compile_text(text: str, path: Path) -> Compilation:
    """Compile ``text`` as if it were the file ``path`` (not written)."""
    return compile_file(path, overrides={path: text})


def check_errors(comp: Compilation) -> list[str]:
    return [f"{d.code} {d.span.location}: {d.message}" for d in comp.diagnostics if d.is_error]


def _outcome(engine: str, report: VerifyReport, seconds: float) -> Outcome:
    lost = frozenset({c.subsystem for c in report.progress if c.subsystem is not None}
                     | set(report.progress_lost))
    cxs = [*report.deadlocks, *([report.unsafe] if report.unsafe else []), *report.progress]
    props = {p.name: p.holds for p in report.user_properties}
    pcx = {p.name: p.counterexample for p in report.user_properties
           if p.counterexample is not None}
    return Outcome(engine, report.verdict.value, report.safe, report.deadlock_free,
                   report.progress_ok, lost, props, report.method, seconds,
                   report.why_undecided, cxs, pcx, report.stop is not None,
                   frozenset(report.progress_checked) | lost)


def run_engine(comp: Compilation, net: FlatNet, engine: str, limits: Limits) -> Outcome:
    options = VerifyOptions(max_states=limits.max_states, check_progress=True,
                            values=value_plan(comp, net),
                            budget=Budget(limits.seconds, None), **ENGINES[engine])
    start = time.monotonic()
    try:
        report = verify(net, options)
    except LimitReached as e:
        # verify() is meant to return what it decided when a limit is reached; record the
        # escape (a known bug, KNOWN_BUGS["limit-escapes-verify"]) and carry on
        where = _innermost_rssm_frame(e)
        return Outcome(engine, "escaped", None, None, None, frozenset(), {}, "-",
                       time.monotonic() - start, f"LimitReached escaped verify() from "
                       f"{where}: {e.stop.message}", escaped=where)
    return _outcome(engine, report, time.monotonic() - start)


def _innermost_rssm_frame(e: BaseException) -> str:
    """``file:line in function`` of the deepest frame of rssm_dsl outside budget.py."""
    tb = e.__traceback__
    where = "?"
    while tb is not None:
        code = tb.tb_frame.f_code
        path = code.co_filename
        if "rssm_dsl" in path and not path.endswith("budget.py"):
            where = f"{path[path.index('rssm_dsl'):]}:{tb.tb_lineno} in {code.co_name}"
        tb = tb.tb_next
    return where


def whole_net_properties(comp: Compilation, net: FlatNet,
                         limits: Limits) -> dict[str, PropertyResult]:
    """The spec's properties checked on the whole net (``userprops`` slicing nothing)."""
    from rssm_dsl.verify import userprops

    assert comp.system is not None
    results = userprops.check_properties(net, comp.system, value_plan(comp, net),
                                         Budget(limits.seconds, None), limits.max_states,
                                         sliced=False)
    return {r.name: r for r in results}


# ------------------------------------------------------------------------------ replays


def _replay_cx(cx: Counterexample) -> Any:
    from rssm_dsl.interp.replay import Counterexample as ReplayCx

    return ReplayCx(cx.kind, tuple(t.name for t in cx.steps), cx.marking, cx.subsystem,
                    tuple(t.name for t in cx.to_cycle), tuple(t.name for t in cx.cycle),
                    cx.cycle_marking, cx.values)


def _simulate(comp: Compilation, names: list[str],
              cx: Any = None) -> tuple[Any, Any, list[int], Any, Any]:
    """The interpreter forced through ``names``, with the values ``cx`` (a replay
    counterexample) chose set as ``rssmc simulate --replay`` sets them: (simulator, result,
    steps, runtime, the ValueChoices or None)."""
    from rssm_dsl.interp import SimOptions, Simulator, build_runtime
    from rssm_dsl.interp.replay import ValueChoices, resolve_steps

    rt = build_runtime(comp)
    steps, bad = resolve_steps(rt.net, names, "counterexample")
    if bad:
        raise ValueError(bad[0].message)
    values = ValueChoices(rt, cx) if cx is not None and cx.values else None
    sim = Simulator(rt, SimOptions(forced=steps, record_markings=True,
                                   observe=values.observe if values is not None else None))
    return sim, sim.run(), steps, rt, values


def replay(comp: Compilation, cx: Counterexample) -> tuple[bool, str]:
    """Does the interpreter, forced through ``cx``, reach the deadlock, unsafe firing or
    lasso it claims? (``rssmc simulate --replay``'s judgement.)"""
    from rssm_dsl.interp.replay import judge

    rcx = _replay_cx(cx)
    sim, result, steps, _, values = _simulate(comp, rcx.sequence(), rcx)
    verdict = judge(rcx, steps, result, sim, values=values)
    return verdict.reproduced, verdict.message


def property_violated(comp: Compilation, name: str, cx: Counterexample) -> tuple[bool, str]:
    """Does the interpreter, forced through ``cx``, end in a state that violates property
    ``name``? ``always P``: P is false there; ``whenever P eventually Q``: P holds and Q does
    not (a state from which Q is never reached is one where Q is false). ``SUB in BEH`` is
    read from the marking (a place of BEH's page of SUB marked, as the verifier reads it), the
    values from the subsystems' variables."""
    from rssm_dsl.semantics.properties import Formula

    assert comp.system is not None
    prop = next(p for p in comp.system.properties if p.name == name)
    rcx = _replay_cx(cx)
    sim, result, _, rt, _ = _simulate(comp, list(rcx.steps), rcx)
    if result.reason not in ("replayed", "finished", "deadlock"):
        return False, f"the replay stopped ({result.reason}): {result.message}"
    marked = sim.game.marking()
    inside = {(p.subsystem, p.behaviour) for p in rt.net.places
              if p.index in marked and p.behaviour is not None}

    def in_behaviour(sub: str, beh: str) -> bool:
        return (sub, beh) in inside

    def value(sub: str, var: str) -> Any:
        return rt.subsystems[sub].vars[var]

    formulas = [Formula(comp.system, e) for e in prop.expressions]
    truth = [f(in_behaviour, value) for f in formulas]
    bad = (not truth[0]) if prop.kind == "always" else (truth[0] and not truth[1])
    # subsystems the property reads that stand between the fork and the join of their
    # transition function (its partial functions' places marked), where the verifier's
    # values are already the transition function's results (dataplan.py)
    read = {a.subsystem_id for f in formulas for a in f.atoms}
    mid = sorted({p.subsystem for p in rt.net.places if p.index in marked
                  and p.subsystem in read and "partial function" in p.label})
    where = f"; {MID_FUNCTION}: {', '.join(mid)}" if mid else ""
    return bad, f"after {len(cx.steps)} firings the property reads {truth}{where}"


# ---------------------------------------------------------------------------- compare


def compare(outcomes: Mapping[str, Outcome],
            whole_props: Mapping[str, bool | None] | None = None) -> list[Disagreement]:
    """Every answer two engines both decided differently."""
    out: list[Disagreement] = []

    def same(what: str, answers: Iterable[tuple[str, object]]) -> None:
        decided = [(e, v) for e, v in answers if v is not None]
        if len({repr(v) for _, v in decided}) > 1:
            out.append(Disagreement(what, ", ".join(f"{e}={_show(v)}" for e, v in decided)))

    for f in FIELDS:
        same(f, ((e, getattr(o, f)) for e, o in outcomes.items()))
    # the subsystems that lose progress, compared on those both engines checked (a limit,
    # or a capped first try, may stop the check once a first loss is found: the report's
    # list is then of the subsystems checked, each loss real)
    losing = [(e, o) for e, o in outcomes.items() if o.progress_ok is False]
    for i, (e1, o1) in enumerate(losing):
        for e2, o2 in losing[i + 1:]:
            both = o1.checked & o2.checked
            if o1.lost & both != o2.lost & both:
                out.append(Disagreement("progress lost", ", ".join(
                    f"{e}={_show(sorted(o.lost))} (of {len(o.checked)} checked)"
                    for e, o in ((e1, o1), (e2, o2)))))
                break
        else:
            continue
        break
    names = sorted({n for o in outcomes.values() for n in o.properties})
    for n in names:
        answers = [(e, o.properties.get(n)) for e, o in outcomes.items()]
        if whole_props is not None:
            answers.append((PROPS_WHOLE, whole_props.get(n)))
        same(f"property {n}", answers)
    return out


def _show(v: object) -> str:
    if isinstance(v, list):
        return "{" + ", ".join(map(str, v)) + "}"
    return str(v)


def compare_simulation(outcomes: Mapping[str, Outcome],
                       findings: Iterable[SimulationFinding]) -> list[Disagreement]:
    """The converse check: a violation the simulation found (and replayed) contradicts every
    engine that proved the property it violates."""
    out: list[Disagreement] = []
    for f in findings:
        for e, o in outcomes.items():
            proved = {
                "deadlock": o.deadlock_free is True,
                "unsafe": o.safe is True,
                "progress": o.progress_ok is True,
                "property": f.name is not None and o.properties.get(f.name) is True,
            }.get(f.kind, False)
            if proved:
                what = f.kind if f.kind != "property" else f"property {f.name}"
                out.append(Disagreement(f"simulation: {what}",
                                        f"{e} proved it, the simulation found {f.detail}"))
    return out


def _replays(comp: Compilation, outcomes: Mapping[str, Outcome],
             ) -> tuple[int, list[Disagreement]]:
    """Every counterexample replayed once (engines often give the same one)."""
    seen: dict[tuple[Any, ...], tuple[bool, str]] = {}
    out: list[Disagreement] = []
    for e, o in outcomes.items():
        jobs: list[tuple[str, Counterexample, Callable[[], tuple[bool, str]]]] = []
        for cx in o.counterexamples:
            jobs.append((cx.kind, cx, functools.partial(replay, comp, cx)))
        for n, cx in o.property_cxs.items():
            jobs.append((f"property {n}", cx, functools.partial(property_violated, comp, n, cx)))
        for what, cx, run in jobs:
            key = (what, cx.subsystem, tuple(t.name for t in cx.steps),
                   tuple(t.name for t in cx.to_cycle), tuple(t.name for t in cx.cycle))
            if key not in seen:
                try:
                    seen[key] = run()
                except Exception as ex:            # a crash of the replay is a failed replay
                    seen[key] = (False, f"the replay raised {type(ex).__name__}: {ex}")
            ok, message = seen[key]
            if not ok:
                sub = f" of {cx.subsystem}" if cx.subsystem and cx.kind == "progress" else ""
                out.append(Disagreement(f"replay {what}{sub}",
                                        f"{e}'s counterexample ({len(cx.steps)} steps) does "
                                        f"not replay: {message}"))
    return len(seen), out


def check_spec(text: str, name: str = "spec", limits: Limits | None = None,
               engines: Iterable[str] = ENGINES, path: Path | None = None) -> SpecResult:
    """Compile ``text``, run every engine, compare, replay."""
    lim = limits or Limits()
    start = time.monotonic()
    where = path or Path(f"/nonexistent/soundness/{name}.rssm")
    comp = compile_text(text, where) if path is None else compile_file(path)
    errors = check_errors(comp)
    if errors or comp.hpn is None:
        return SpecResult(name, {}, [], error="does not check: " + "; ".join(errors[:3]),
                          seconds=time.monotonic() - start)
    assert comp.system is not None
    ending = frozenset(s.id for a in comp.system.agents for s in a.subsystems
                       if any(w.target is None for w in s.switches))
    try:
        net = flatten(comp.hpn)
        outcomes = {e: run_engine(comp, net, e, lim) for e in engines}
        whole = None
        if comp.system is not None and comp.system.properties:
            whole = {n: r.holds for n, r in whole_net_properties(comp, net, lim).items()}
        disagreements = compare(outcomes, whole)
        disagreements += [Disagreement("limit escaped verify()", f"{e}: {o.why}")
                          for e, o in outcomes.items() if o.escaped]
        count, bad = _replays(comp, outcomes)
    except Exception:
        return SpecResult(name, {}, [], error="crash: " + traceback.format_exc(limit=8),
                          seconds=time.monotonic() - start)
    return SpecResult(name, outcomes, [*disagreements, *bad], count,
                      seconds=time.monotonic() - start, ending=ending)


def summary_line(r: SpecResult) -> str:
    if r.error:
        return f"{r.name}: ERROR {r.error.splitlines()[0]}"
    verdicts = ", ".join(f"{e}={o.verdict}" for e, o in r.outcomes.items())
    return f"{r.name}: {verdicts}; {len(r.disagreements)} disagreement(s), {r.replays} replays"


__all__ = ["ENGINES", "KNOWN_BUGS", "Disagreement", "Limits", "Outcome", "SimulationFinding",
           "SpecResult", "check_spec", "compare", "compare_simulation", "known_bug"]
