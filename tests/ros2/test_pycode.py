"""The Python the generator writes for partial functions, conditions and switches computes
what the interpreter computes: both run on the same random states (values, and failures
with their codes) for every data case of every behaviour of the example specifications
and of specs/tricky.rssm, which uses every kind of expression and statement. The generated
code runs here with the workspace's runtime values module (it needs numpy only)."""

from __future__ import annotations

import math
import random
from collections.abc import Callable, Mapping
from pathlib import Path
from typing import Any

import numpy as np
import pytest

import rssm_core.values as rt_values
from rssm_dsl.bindings import resolve
from rssm_dsl.hpn.ir import HPN
from rssm_dsl.interp.compile_expr import ExprCompiler
from rssm_dsl.interp.errors import EvalError
from rssm_dsl.interp.initial import InitialValues as SpecValues
from rssm_dsl.interp.values import equal, float_array
from rssm_dsl.pipeline import compile_file
from rssm_dsl.pycode import var
from rssm_dsl.ros2.msgtypes import MessageTypes
from rssm_dsl.ros2.nodecode import Context, SubsystemCode, row_source
from rssm_dsl.semantics import cases as case_rule
from rssm_dsl.semantics.model import Subsystem, System
from rssm_dsl.semantics.typecheck import Symbol, enum_symbols
from rssm_dsl.semantics.types import BOOL, FLOAT, INT, ArrayT, EnumT, RangeT, RecordT, Type
from tests.conftest import ROOT, example_specs
from tests.ros2.conftest import SPECS

SAMPLES = 60


class _NoSwitch(Exception):
    pass


def random_value(t: Type, rnd: random.Random) -> Any:
    if t == FLOAT:
        return rnd.choice([0.0, 1.0, -1.0, rnd.uniform(-4, 4), rnd.uniform(-4, 4)])
    if t == INT:
        return rnd.randint(-5, 5)
    if t == BOOL:
        return rnd.random() < 0.5
    if isinstance(t, EnumT):
        return rnd.choice(t.members)
    if isinstance(t, RangeT):
        return rnd.choice([t.lo, t.hi, rnd.randint(t.lo, t.hi)])
    if isinstance(t, ArrayT):
        items = [random_value(t.element, rnd) for _ in range(t.size)]
        return float_array(items) if t.element == FLOAT else tuple(items)
    assert isinstance(t, RecordT)
    return {n: random_value(ft, rnd) for n, ft in t.fields}


def generated_module(system: System, hpn: HPN, sub: Subsystem, agent: str, j: str,
                     values: SpecValues, base: Path) -> tuple[dict[str, Any], Any]:
    """Execute the generated pieces of one node (everything but the ROS parts)."""
    ctx = Context(system, hpn, MessageTypes(), values.param)
    view = SubsystemCode(ctx, sub, agent, j).build("pkg")
    lines = [*view.types, *view.converters, *view.consts,
             "class State:", f"    __slots__ = {tuple(view.slots)!r}"]
    for fn in view.functions:
        lines += fn
    for b in view.behaviours:
        lines += [*b.tables, *b.switch]
    ns: dict[str, Any] = {"_rt": rt_values, "math": math, "Any": Any, "Mapping": Mapping,
                          "_NoSwitch": _NoSwitch}
    for x in view.externs:
        ns[x.var] = resolve(f"{x.module}:{x.attribute}", [base])
    exec(compile("\n".join(lines), f"<node {sub.id}>", "exec"), ns)
    return ns, view


def interpreter(system: System, sub: Subsystem, values: SpecValues,
                base: Path) -> ExprCompiler:
    symbols = enum_symbols(system.types, system.span)
    symbols.update({c.name: Symbol("const", c.type, c.span) for c in system.consts})
    for v in sub.params:
        symbols[v.name] = Symbol("param", v.type, v.span)
    for v in sub.memory:
        symbols[v.name] = Symbol("memory", v.type, v.span)
    for b in (*sub.inputs, *sub.outputs):
        symbols[b.name] = Symbol(b.direction.value, b.type, b.span)
    externs = {e.name: e for e in system.externs}
    return ExprCompiler(symbols, externs, values.consts,
                        lambda ext, span: resolve(ext.binding, [base]))  # type: ignore[arg-type]


def outcome(run: Callable[[], Any]) -> tuple[str, Any]:
    try:
        return "ok", run()
    except EvalError as e:
        return "error", e.code
    except rt_values.OperationError as e:
        return "error", e.code


def same(a: tuple[str, Any], b: tuple[str, Any]) -> bool:
    if a[0] != b[0]:
        return False
    if a[0] == "error":
        return bool(a[1] == b[1])
    if isinstance(a[1], dict) and isinstance(b[1], dict):
        return a[1].keys() == b[1].keys() and all(_eq(a[1][k], b[1][k]) for k in a[1])
    return _eq(a[1], b[1])


def _eq(x: Any, y: Any) -> bool:
    if isinstance(x, float) and isinstance(y, float) and math.isnan(x) and math.isnan(y):
        return True
    if isinstance(x, np.ndarray) and isinstance(y, np.ndarray):
        return bool(np.array_equal(x, y, equal_nan=True))
    return equal(x, y)


SPECS_UNDER_TEST = [*example_specs(), SPECS / "relay.rssm", SPECS / "wire.rssm",
                    SPECS / "tricky.rssm", SPECS / "finite.rssm"]


@pytest.mark.parametrize("spec", SPECS_UNDER_TEST, ids=lambda p: p.stem)
def test_generated_code_computes_what_the_interpreter_computes(
        spec: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.chdir(ROOT)
    comp = compile_file(spec.relative_to(ROOT))
    assert comp.ok and comp.system is not None
    system = comp.system
    values = SpecValues(system)
    rnd = random.Random(spec.stem)
    checked = 0
    for agent in system.agents:
        for sub in agent.subsystems:
            assert comp.hpn is not None
            ns, _ = generated_module(system, comp.hpn, sub, agent.name, agent.designator, values,
                                        spec.parent)
            comp_i = interpreter(system, sub, values, spec.parent)
            variables = [(v.name, v.type) for v in (*sub.params, *sub.memory)] + [
                (b.name, b.type) for b in (*sub.inputs, *sub.outputs)]
            for _ in range(SAMPLES):
                env = {n: random_value(t, rnd) for n, t in variables}
                st = ns["State"]()
                for n, v in env.items():
                    setattr(st, var(n), v)
                for b, beh in enumerate(sub.behaviours, start=1):
                    for pf in beh.functions:
                        table = ns[f"CASES_{b}_{pf.index}"]
                        split = case_rule.split_of(pf.cases[0].new)
                        for case in pf.cases:
                            # a run-time mask the case stands for: the row the node's
                            # code computes from it selects the case
                            mask = sum(1 << k for k, v in enumerate(case.new) if v)
                            row = eval(row_source(split, len(sub.inputs)), {"mask": mask})
                            varpi, fn = table[row]
                            assert varpi == case.index
                            assert (fn is None) == case.void
                            if fn is None:
                                continue
                            run, written = comp_i.body(case.body)

                            def interp(run: Any = run, written: Any = written,
                                       env: Any = env) -> Any:
                                work = dict(env)
                                run(work)
                                return {n: work[n] for n in written}

                            def generated(fn: Any = fn, st: Any = st) -> Any:
                                stage: dict[str, Any] = {}
                                fn(st, stage)
                                return {k[2:]: v for k, v in stage.items()}

                            a, g = outcome(interp), outcome(generated)
                            assert same(a, g), (sub.id, beh.name, pf.target, case.index, a, g)
                            checked += 1
                    conds = {}
                    for k, c in enumerate(beh.conditions, start=1):
                        cond_i = comp_i.expr(c.expr)
                        cond_g = ns[f"cond_{b}_{k}"]
                        a = outcome(lambda cond_i=cond_i, env=env: bool(cond_i(env)))
                        g = outcome(lambda cond_g=cond_g, st=st: bool(cond_g(st)))
                        assert same(a, g), (sub.id, beh.name, c.name, a, g)
                        conds[c.name] = rnd.random() < 0.5
                    _check_switch(ns[f"switch_{b}"], st, env, conds, sub, beh.name, comp_i)
    assert checked > 0


def _check_switch(fn: Any, st: Any, env: dict[str, Any], conds: dict[str, bool],
                  sub: Subsystem, behaviour: str, comp: ExprCompiler) -> None:
    """The generated switch takes the first switch (declaration order, otherwise last) whose
    condition the interpreter's compiled guard finds true."""
    switches = sorted((s for s in sub.switches if s.source == behaviour),
                      key=lambda s: (s.condition is None, s.index))
    special = {n: (lambda n=n: conds[n]) for n in conds}
    want: tuple[str, Any] = ("error", "none")
    for sw in switches:
        if sw.condition is None:
            want = ("ok", sw.target)
            break
        sc = ExprCompiler(comp.symbols, comp.externs, comp.consts, comp.resolve, special)
        sc.extra_symbols = {n: Symbol("condition", BOOL, sub.span) for n in conds}
        got = outcome(lambda sc=sc, sw=sw: bool(sc.expr(sw.condition)(env)))
        if got[0] == "error":
            want = got
            break
        if got[1]:
            want = ("ok", sw.target)
            break
    try:
        have: tuple[str, Any] = ("ok", fn(st, conds))
    except _NoSwitch:
        have = ("error", "none")
    except rt_values.OperationError as e:
        have = ("error", e.code)
    assert have == want, (sub.id, behaviour, conds, have, want)


@pytest.mark.parametrize("split,n", [((), 0), ((), 3), ((0, 1), 2), ((1,), 3), ((0, 2), 3),
                                     ((2, 0, 5), 6)])
def test_the_row_a_node_computes_is_the_rule_of_rssm_core(split: tuple[int, ...], n: int
                                                          ) -> None:
    """The generated row expression is rssm_dsl.semantics.cases.bits for every new(x) mask, and the
    case in that row covers the mask (the table is ordered as nodecode.mask_of orders it)."""
    combos = case_rule.combinations(sorted(split), n)
    for mask in range(1 << n):
        row = eval(row_source(tuple(sorted(split)), n), {"mask": mask})
        assert row == case_rule.bits(mask, sorted(split))
        values = [bool(mask >> k & 1) for k in range(n)]
        covering = [c for c in combos if case_rule.covers(c, values)]
        assert len(covering) == 1
        assert sum(1 << i for i, v in enumerate(x for x in covering[0] if x is not None)
                   if v) == row


def test_a_node_picks_the_case_the_interpreter_picks_beyond_the_table_form(
        tmp_path: Path) -> None:
    """Clauses over 20 inputs: the cases are cubes (rssm_dsl/semantics/cases.py), the node picks
    the first whose fixed inputs match new(x), which is the one case covering the mask."""
    from tests.interp.test_case_rule import BIG, BIG_BODY, _spec, big_masks

    spec = tmp_path / "big.rssm"
    spec.write_text(_spec(BIG_BODY, BIG), encoding="utf-8")
    comp = compile_file(spec)
    assert comp.ok and comp.system is not None and comp.hpn is not None
    system = comp.system
    agent = next(a for a in system.agents if a.name == "hub")
    sub = agent.subsystems[0]
    ns, view = generated_module(system, comp.hpn, sub, agent.name, agent.designator,
                                SpecValues(system), tmp_path)
    picks = [line.split("r.partial(", 1)[1].rsplit(", st, stage)", 1)[0]
             for line in view.behaviours[0].iterate if "r.partial(" in line]
    functions = sub.behaviours[0].functions
    assert len(picks) == len(functions)
    for pf, pick in zip(functions, picks, strict=True):
        assert not case_rule.uniform([c.new for c in pf.cases])
        for mask in big_masks(BIG, 200):
            values = [bool(mask >> k & 1) for k in range(BIG)]
            varpi, _ = eval(pick, {**ns, "mask": mask})
            covering = [c.index for c in pf.cases if case_rule.covers(c.new, values)]
            assert covering == [varpi], (pf.target, mask)
