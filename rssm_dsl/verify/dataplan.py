"""What the flat net's transitions do with finite data, for the verifier (docs/verify.md,
"How values are tracked": conditions over finite data are evaluated with the values tracked
in the state).

:func:`value_plan` reads the compiled specification and says, per transition of the flat net
(by name, so that it also holds in a slice), which tracked values it reads, which it writes and
how (a :class:`Step`). The values are those of the interpreter, computed by the interpreter's
own compiled expressions and statements (:class:`rssm_dsl.interp.compile_expr.ExprCompiler`,
the code the ROS 2 nodes run), so there is one definition of every value rule:

| flat transition                              | reads -> writes                              |
|----------------------------------------------|----------------------------------------------|
| fork of P^f (new(x) known: a combination)    | the subsystem's variables -> the targets of  |
|                                              | every partial function's case for new(x)     |
| a step that marks a send's ``op`` place      | the output buffer -> the channel's slot      |
| a step that marks a receive's ``op`` place   | the slot -> the input buffer                 |
| ``t_4`` / ``t_out`` of a behaviour           | guard: not (f^tau or f^eps) / f^tau or f^eps |
| a switch ``t[j,v,alpha]``                    | guard: f^sigma, no earlier switch's holding  |

Every partial function reads the state before the transition function (the interpreter stages
its writes and commits them at the join of P^f), and nothing changes the subsystem's variables
between that fork and its join, so the whole transition function is applied at the fork.

A value is *tracked* when its type has a finite domain (``finite_domain``: bool, enums, ranges)
and a condition depends on it, directly or through what is computed from it (the cone of
influence); a channel's slot is tracked when its consumer's input is and its producer is a
subsystem. Everything else is *unknown*: an expression that needs an unknown value (a float,
an external operation's result, an untracked variable) gives an unknown result, which makes a
guard a free choice and a written value any value of its domain (an over-approximation).
Run-time failures (E802) of operations are not modelled: the terminal and error conditions
are evaluated on the values (the report says so).
"""

from __future__ import annotations

import itertools
from collections.abc import Callable, Iterable, Mapping, Sequence
from dataclasses import field
from typing import Any

from rssm_core.records import dataclass
from rssm_dsl.hpn.flat import FlatNet
from rssm_dsl.hpn.ir import CondKind, OpKind
from rssm_dsl.interp.compile_expr import ExprCompiler
from rssm_dsl.interp.initial import InitialValues
from rssm_dsl.pipeline import Compilation
from rssm_dsl.semantics import cases as case_rule
from rssm_dsl.semantics.model import Buffer, Condition, Subsystem, System, Variable
from rssm_dsl.semantics.typecheck import Symbol, owner_symbols
from rssm_dsl.semantics.types import BOOL, finite_domain
from rssm_dsl.source import Span
from rssm_dsl.syntax import ast
from rssm_dsl.syntax.walk import names, statement_exprs

MAX_VALUATIONS = 4096      # per transition: beyond, its values are left unknown
MAX_OPEN_INPUTS = 10       # new(x) not known of more split inputs: a fork writes any value


class _UnknownValue(Exception):
    """An expression used a value the verifier does not track."""


def _unknown(*_: Any, **__: Any) -> Any:
    raise _UnknownValue


class Unknown:
    """A value the verifier does not track: any use of it raises :class:`_UnknownValue`."""

    __slots__ = ()
    __bool__ = __eq__ = __ne__ = __lt__ = __le__ = __gt__ = __ge__ = _unknown
    __add__ = __radd__ = __sub__ = __rsub__ = __mul__ = __rmul__ = _unknown
    __truediv__ = __rtruediv__ = __mod__ = __rmod__ = __neg__ = __abs__ = _unknown
    __floordiv__ = __rfloordiv__ = __pow__ = __rpow__ = __pos__ = _unknown
    __getitem__ = __iter__ = __len__ = __float__ = __int__ = __index__ = _unknown
    __contains__ = __array__ = __getattr__ = _unknown
    __hash__ = None  # type: ignore[assignment]


UNKNOWN = Unknown()
ANY = object()             # an outcome's value: any value of the variable's domain

Outcome = dict[str, Any]   # written variable -> value (or ANY)


@dataclass(frozen=True)
class Var:
    """A value the verifier may track: a memory variable, a buffer or a channel's slot."""

    key: str                       # "arm.c.phase"; a slot: "slot of <channel id>"
    domain: tuple[Any, ...]
    initial: Any
    label: str                     # in the user's words
    span: Span


@dataclass(frozen=True)
class Step:
    """What one flat transition does with values: it reads ``reads`` (keys of :class:`Var`
    or of untracked variables) and ``run`` gives, for their values, the outcomes it may
    have: each a value per written key (or ``ANY``); none when its guard is false."""

    reads: tuple[str, ...]
    writes: tuple[str, ...]
    run: Callable[[Mapping[str, Any]], list[Outcome]]
    # a guarded step: its condition on the values (None: unknown, a free choice)
    holds: Callable[[Mapping[str, Any]], bool | None] | None = None
    # per written key, the keys its new value may depend on (None: every key of ``reads``):
    # the cone of influence follows these, so a transition function that computes a
    # tracked flag beside a counter nobody tests does not drag the counter's inputs in
    deps: Mapping[str, tuple[str, ...]] | None = None


@dataclass(frozen=True)
class ValuePlan:
    """Per flat transition (by name) its :class:`Step`; a fork's steps by the new(x)
    combination of its subsystem's inputs (the fork of a subsystem whose new(x) is not
    known: ``free_forks``, which write any value)."""

    vars: dict[str, Var]
    steps: dict[str, Step]
    forks: dict[str, Callable[[tuple[bool | None, ...]], Step]]
    free_forks: dict[str, Step]
    slot_writers: dict[str, frozenset[str]]  # slot key -> the transitions that mark its full
    subsystem_of: dict[str, str | None]     # var key -> its subsystem (None: a slot)
    channel_of: dict[str, str] = field(default_factory=dict)   # slot key -> channel id
    system: System | None = None            # the model (its properties: userprops.py)


def _guard_outcomes(holds: Callable[[Mapping[str, Any]], bool | None]
                    ) -> Callable[[Mapping[str, Any]], list[Outcome]]:
    def run(values: Mapping[str, Any]) -> list[Outcome]:
        return [] if holds(values) is False else [{}]
    return run


def _truth(fn: Callable[[dict[str, Any]], Any], env: dict[str, Any]) -> bool | None:
    """The value of a condition, None when it is unknown (an untracked value, or a failure)."""
    try:
        v = fn(env)
    except Exception:
        return None
    return v if type(v) is bool else None


def _kleene(compile_expr: Callable[[ast.Expr], Callable[[dict[str, Any]], Any]], e: ast.Expr,
            depth: int = 0) -> Callable[[dict[str, Any]], Any]:
    """``e`` compiled so that `and`, `or` and `not` take what is known of each side (Kleene's
    three values): an unknown side does not hide a false one under `and`, or a true one
    under `or`, whichever side it is on. The interpreter's code evaluates `a and b` from
    the left, so an untracked `a` made `a and false` unknown, a free choice, while `false
    and a` was false (a condition's operands in another order gave another verdict).
    Deeper than ``KLEENE_DEPTH``, the expression is compiled as it is."""
    if depth < KLEENE_DEPTH and isinstance(e, ast.Binary) and e.op in ("and", "or"):
        left = _kleene(compile_expr, e.left, depth + 1)
        right = _kleene(compile_expr, e.right, depth + 1)
        decides = e.op == "or"          # the value of one side that decides the whole

        def both(env: dict[str, Any]) -> bool:
            a = _truth(left, env)
            if a is decides:
                return decides
            b = _truth(right, env)
            if b is decides:
                return decides
            if a is None or b is None:
                raise _UnknownValue
            return not decides
        return both
    if depth < KLEENE_DEPTH and isinstance(e, ast.Unary) and e.op == "not":
        inner = _kleene(compile_expr, e.operand, depth + 1)

        def negated(env: dict[str, Any]) -> bool:
            v = _truth(inner, env)
            if v is None:
                raise _UnknownValue
            return not v
        return negated
    return compile_expr(e)


KLEENE_DEPTH = 64


def _stmt_names(stmts: Iterable[ast.Stmt]) -> set[str]:
    """The names statements read, and the variables they assign (a partial write keeps the
    rest of the value)."""
    out: set[str] = set()
    for st in stmts:
        for e, target in statement_exprs(st):
            out |= {n.name for n in names(e)}
            if target is not None:
                out.add(target)
    return out


class _Sub:
    """One subsystem's variables and compiled expressions."""

    def __init__(self, sub: Subsystem, initial: InitialValues, system: System) -> None:
        self.model = sub
        self.env0 = initial.env(sub)
        symbols = owner_symbols(initial.const_symbols, sub.params, sub.memory,
                                (*sub.inputs, *sub.outputs))
        externs = {e.name: e for e in system.externs}
        self.symbols = symbols
        self.compiler = ExprCompiler(symbols, externs, initial.consts, None)
        self.params = {p.name for p in sub.params}
        self.variables: dict[str, Variable | Buffer] = {v.name: v for v in sub.memory}
        self.variables.update((b.name, b) for b in (*sub.inputs, *sub.outputs))
        self.memory = {v.name for v in sub.memory}
        self._conds: dict[str, Callable[[dict[str, Any]], Any]] = {}

    def key(self, name: str) -> str:
        return f"{self.model.id}.{name}"

    def env(self, values: Mapping[str, Any]) -> dict[str, Any]:
        """The subsystem's variables: parameters as declared, tracked values as given,
        everything else unknown."""
        env = {n: self.env0.get(n, UNKNOWN) for n in self.params}
        for n in self.variables:
            env[n] = values.get(self.key(n), UNKNOWN)
        return env

    def reads(self, used: Iterable[str]) -> tuple[str, ...]:
        return tuple(sorted(self.key(n) for n in set(used) if n in self.variables))

    def condition(self, c: Condition) -> Callable[[dict[str, Any]], Any]:
        fn = self._conds.get(c.name)
        if fn is None:
            fn = self._conds[c.name] = _kleene(self.compiler.expr, c.expr)
        return fn


class _Planner:
    def __init__(self, comp: Compilation, net: FlatNet) -> None:
        assert comp.system is not None and comp.hpn is not None
        self.system, self.hpn, self.net = comp.system, comp.hpn, net
        initial = InitialValues(comp.system)
        self.subs = {s.id: _Sub(s, initial, comp.system) for s in comp.system.subsystems()}
        self.vars: dict[str, Var] = {}
        self.subsystem_of: dict[str, str | None] = {}
        self.channel_of: dict[str, str] = {}
        self.steps: dict[str, Step] = {}
        self.forks: dict[str, Callable[[tuple[bool | None, ...]], Step]] = {}
        self.free_forks: dict[str, Step] = {}
        self.slot_writers: dict[str, set[str]] = {}
        for s in self.subs.values():
            for name, v in s.variables.items():
                dom = finite_domain(v.type)
                init = s.env0.get(name)
                if dom is not None and any(type(d) is type(init) and d == init for d in dom):
                    key = s.key(name)
                    self.vars[key] = Var(key, dom, init, f"{s.model.id}.{name}", v.span)
                    self.subsystem_of[key] = s.model.id
        for ch in comp.system.channels:
            prod, cons = self.subs.get(ch.producer.owner), self.subs.get(ch.consumer.owner)
            if prod is None or cons is None:
                continue
            src = prod.key(ch.producer.name)
            if src in self.vars and cons.key(ch.consumer.name) in self.vars:
                key = f"slot of {ch.id}"
                out = self.vars[src]
                self.vars[key] = Var(key, out.domain, out.initial, f"channel {ch.id}",
                                     ch.producer.span)
                self.subsystem_of[key] = None
                self.channel_of[key] = ch.id

    # ------------------------------------------------------------------ steps
    def plan(self) -> ValuePlan:
        self._copies()
        for t, sub in self.net.new_sites.forks:
            self._fork(self.net.transitions[t].name, sub, self.net.transitions[t].behaviour)
        self._guards()
        return ValuePlan(self.vars, self.steps, self.forks, self.free_forks,
                         {k: frozenset(v) for k, v in self.slot_writers.items()},
                         self.subsystem_of, self.channel_of, self.system)

    def _copies(self) -> None:
        """Sends copy an output into the channel's slot, receives the slot into an input."""
        net, hpn = self.net, self.hpn
        for fp in net.places:
            if fp.operation is None:
                continue
            op = hpn.places[fp.operation].operation
            if op is None or op.kind not in (OpKind.SEND, OpKind.RECEIVE):
                continue
            assert op.channel is not None and op.target is not None
            slot = f"slot of {op.channel}"
            s = self.subs.get(op.subsystem)
            if s is None:
                continue
            buffer = s.key(op.target)
            if slot not in self.vars:
                if op.kind is OpKind.RECEIVE and buffer in self.vars:   # from a device
                    fill = Step((), (buffer,), _any((buffer,)))
                    for t in net.rule.producers[fp.index]:
                        self.steps[net.transitions[t].name] = fill
                continue
            reads, writes = ((buffer,), (slot,)) if op.kind is OpKind.SEND else ((slot,),
                                                                                (buffer,))
            step = Step(reads, writes, _copy(reads[0], writes[0]))
            for t in net.rule.producers[fp.index]:
                self.steps[net.transitions[t].name] = step
            if op.kind is OpKind.SEND:
                ends = self.slot_writers.setdefault(slot, set())
                for t in net.rule.consumers[fp.index]:
                    ends.add(net.transitions[t].name)

    def _guards(self) -> None:
        """t_4 / t_out of behaviours and the switches: guarded by conditions on values."""
        net, hpn = self.net, self.hpn
        for c in net.conditions:
            ft = net.transitions[c.transition]
            s = self.subs.get(ft.subsystem or "")
            if s is None or c.kind == "case":
                continue
            cond = hpn.transitions[ft.name].condition
            if c.kind in ("continue", "stop") and ft.behaviour is not None:
                self.steps[ft.name] = self._ends(s, ft.behaviour, c.kind == "stop")
            elif c.kind == "switch" and cond is not None and cond.kind is CondKind.SWITCH:
                assert cond.switch is not None
                self.steps[ft.name] = self._switch(s, cond.switch)

    def _fork(self, name: str, sub: str, behaviour: str | None) -> None:
        s = self.subs.get(sub)
        if s is None or behaviour is None:
            return
        beh = s.model.behaviour(behaviour)
        # per case, its runs: each computes some of its targets (the names it answers for)
        compiled: dict[int, list[tuple[Any, tuple[str, ...]]]] = {}
        written: set[str] = set()
        used: set[str] = set()
        deps: dict[str, set[str]] = {}
        for pf in beh.functions:
            for case in pf.cases:
                if case.void:
                    continue
                run, names_ = s.compiler.case(case.body)
                written |= set(names_)
                used |= _stmt_names(case.body)
                # a target at a time, with the statements it depends on: one that needs an
                # unknown value (`x := x + 0.5`, x a float) leaves only its own target
                # unknown, not `n := n + 1` beside it
                parts = per_target(case.body)
                if parts is None:
                    compiled[id(case)] = [(run, names_)]
                    parts = [(case.body, n) for n in names_]
                else:
                    compiled[id(case)] = [(s.compiler.case(body)[0], (n,)) for body, n in parts]
                # a case reads the state before the transition function (env, never
                # another case's stage), so what it writes depends on what it reads
                for body, n in parts:
                    for target in s.reads((n,)):
                        deps.setdefault(target, set()).update(s.reads(_stmt_names(body)))
        writes = s.reads(written)
        reads = s.reads(used)
        # a target no case of a combination writes keeps its value (its own key)
        dep_of = {w: tuple(sorted(deps.get(w, set()) | {w})) for w in writes}
        self.free_forks[name] = Step((), writes, _any(writes))
        inputs = len(s.model.inputs)
        # the inputs the behaviour's cases split (rssm_dsl/semantics/cases.py)
        split = sorted({k for pf in beh.functions for c in pf.cases
                        for k in case_rule.split_of(c.new)})

        def for_combination(new: tuple[bool | None, ...]) -> Step:
            """The cases taken with new(x) ``new`` (None: not tracked, any value: the cases
            of each combination of the split inputs it leaves open)."""
            new = (*new[:inputs], *(None,) * (inputs - len(new)))
            unknown_inputs = [k for k in split if new[k] is None]
            if len(unknown_inputs) > MAX_OPEN_INPUTS:
                return self.free_forks[name]        # too many to try: any value written
            choices: list[list[tuple[Any, tuple[str, ...]]]] = []
            for bits in itertools.product((True, False), repeat=len(unknown_inputs)):
                fill = dict(zip(unknown_inputs, bits, strict=True))
                full = tuple(fill.get(k, v) for k, v in enumerate(new))
                choices.append([r for pf in beh.functions for c in pf.cases
                                if not c.void and case_rule.covers(c.new, full)
                                for r in compiled[id(c)]])

            def one(runs: list[tuple[Any, tuple[str, ...]]], values: Mapping[str, Any]
                    ) -> Outcome:
                # each partial function reads the state before the transition function, so
                # one that needs an unknown value (a float, an operation's result) leaves
                # only its own targets unknown
                env, stage = s.env(values), dict[str, Any]()
                unknown: set[str] = set()
                for r, names_ in runs:
                    mine: dict[str, Any] = {}
                    try:
                        r(env, mine)
                    except Exception:
                        unknown.update(s.reads(names_))
                        continue
                    stage.update((n, mine[n]) for n in names_ if n in mine)
                return {k: ANY if k in unknown else
                        _known(stage[n]) if n in stage else values.get(k, ANY)
                        for k in writes for n in [k.rpartition(".")[2]]}

            def run(values: Mapping[str, Any]) -> list[Outcome]:
                return [one(runs, values) for runs in choices]
            return Step(reads, writes, run, deps=dep_of)
        self.forks[name] = for_combination

    def _ends(self, s: _Sub, behaviour: str, stop: bool) -> Step:
        beh = s.model.behaviour(behaviour)
        fns = [s.condition(c) for c in beh.conditions]
        used = {n.name for c in beh.conditions for n in names(c.expr)}

        def holds(values: Mapping[str, Any]) -> bool | None:
            v = _stops(fns, s.env(values))
            return None if v is None else v == stop
        return Step(s.reads(used), (), _guard_outcomes(holds), holds)

    def _switch(self, s: _Sub, alpha: int) -> Step:
        sub = s.model
        sw = next(x for x in sub.switches if x.index == alpha)
        assert sw.source is not None
        source = sub.behaviour(sw.source)
        order = sub.switches_from(sw.source)
        earlier = [x.condition for x in order[:order.index(sw)] if x.condition is not None]
        cond_fns = {c.name: s.condition(c) for c in source.conditions}
        box: dict[str, Any] = {}

        def special(n: str) -> Callable[[], Any]:
            def get() -> Any:
                v = _truth(cond_fns[n], box["env"])
                if v is None:
                    raise _UnknownValue
                return v
            return get
        sc = ExprCompiler(s.symbols, s.compiler.externs, s.compiler.consts, None,
                          {c.name: special(c.name) for c in source.conditions})
        sc.extra_symbols = {c.name: Symbol("condition", BOOL, c.span)
                            for c in source.conditions}
        own = _kleene(sc.expr, sw.condition) if sw.condition is not None else None
        others = [_kleene(sc.expr, x) for x in earlier]
        exprs = [*earlier, *([sw.condition] if sw.condition is not None else [])]
        used = {n.name for e in exprs for n in names(e)}
        if used & cond_fns.keys():
            used |= {n.name for c in source.conditions for n in names(c.expr)}

        def holds(values: Mapping[str, Any]) -> bool | None:
            box["env"] = s.env(values)
            unknown = False
            for fn in others:
                v = _truth(fn, box["env"])
                if v is True:
                    return False
                unknown = unknown or v is None
            v = _truth(own, box["env"]) if own is not None else True
            if v is False:
                return False
            return None if unknown or v is None else True
        return Step(s.reads(used), (), _guard_outcomes(holds), holds)


def per_target(stmts: Sequence[ast.Stmt]
               ) -> list[tuple[tuple[ast.Stmt, ...], str]] | None:
    """A partial function's statements split by the variable they compute: for each
    variable assigned, its assignments up to the last and, before them, every statement
    assigning what those read (a `let`, another target), in their order. Run alone, each
    gives the value the whole body gives that variable (a later statement sees what an
    earlier one assigned; nothing else changes it). None when the body assigns one
    variable."""
    info: list[tuple[ast.Stmt, str | None, set[str]]] = []
    for st in stmts:
        reads: set[str] = set()
        assigned = st.name if isinstance(st, ast.Let) else None
        for e, target in statement_exprs(st):
            reads |= {n.name for n in names(e)}
            if target is not None:
                assigned = target
        info.append((st, assigned, reads))
    roots = list(dict.fromkeys(a for st, a, _ in info
                               if isinstance(st, ast.Assign) and a is not None))
    if len(roots) < 2:
        return None
    out: list[tuple[tuple[ast.Stmt, ...], str]] = []
    for root in roots:
        mine = [i for i, (st, a, _) in enumerate(info) if a == root and isinstance(st, ast.Assign)]
        need = set(mine)
        todo = list(mine)
        while todo:                 # what a needed statement reads, assigned before it
            j = todo.pop()
            for i in range(j):
                if i not in need and info[i][1] is not None and info[i][1] in info[j][2]:
                    need.add(i)
                    todo.append(i)
        out.append((tuple(info[i][0] for i in sorted(need)), root))
    return out


def _stops(fns: Sequence[Callable[[dict[str, Any]], Any]], env: dict[str, Any]) -> bool | None:
    """f^tau or f^eps: True when one condition holds, False when all are known false."""
    unknown = False
    for fn in fns:
        v = _truth(fn, env)
        if v is True:
            return True
        unknown = unknown or v is None
    return None if unknown else False


def _known(v: Any) -> Any:
    return ANY if isinstance(v, Unknown) else v


def _any(writes: tuple[str, ...]) -> Callable[[Mapping[str, Any]], list[Outcome]]:
    def run(_: Mapping[str, Any]) -> list[Outcome]:
        return [dict.fromkeys(writes, ANY)]
    return run


def _copy(src: str, dst: str) -> Callable[[Mapping[str, Any]], list[Outcome]]:
    def run(values: Mapping[str, Any]) -> list[Outcome]:
        return [{dst: values.get(src, ANY)}]
    return run


def value_plan(comp: Compilation, net: FlatNet) -> ValuePlan:
    """The values the flat net ``net`` of ``comp`` works with (the module docstring)."""
    return _Planner(comp, net).plan()


def valuations(keys: Sequence[str], domains: Mapping[str, tuple[Any, ...]]
               ) -> Iterable[dict[str, Any]]:
    """Every assignment of a value of its domain to each key."""
    for combo in itertools.product(*(domains[k] for k in keys)):
        yield dict(zip(keys, combo, strict=True))
