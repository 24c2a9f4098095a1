"""User-stated properties (`property NAME: always ...`, `... whenever ... eventually ...`):
their checks, their atoms, and their evaluation (docs/language.md, "Properties").

A property's expression is an ordinary expression in which a subsystem is written
`AGENT.SUBSYSTEM` (`arm.c`, `arm.motion`) and:

* `SUB in BEH` is an atom: the subsystem is in its behaviour BEH (:class:`InBehaviour`);
* `SUB.NAME` is an atom when NAME is a memory variable or a buffer of SUB (:class:`Value`);
  fields and elements of it are read as usual (`arm.c.pose.yaw`, `arm.c.q[2]`);
* `SUB.NAME` of a parameter is a constant (its value at the start of the run), as are the
  program's constants, the built-in constants and the enum members.

:func:`check_properties` checks the declarations for the front end (E620-E625, W626, and the
type errors of the expression language). :func:`atoms` lists the atoms of one expression in
the order they appear, resolved. :class:`Formula` compiles an expression once into a function
of the atoms, with the code the interpreter runs (rssm_dsl.pycode), so a property means what
the same expression means in a behaviour; :func:`evaluate` is the one-shot form.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import replace
from typing import Any

import rssm_core.values as rt
from rssm_core.records import dataclass
from rssm_dsl.diagnostics import DiagnosticBag, Related
from rssm_dsl.semantics.model import Agent, Property, Subsystem, System
from rssm_dsl.semantics.typecheck import (
    BUILTIN_CONSTS,
    BUILTIN_FUNCTIONS,
    ExprChecker,
    Scope,
    Symbol,
    did_you_mean,
    enum_symbols,
)
from rssm_dsl.semantics.types import BOOL, ArrayT, RecordT, Type, descriptor, finite_domain
from rssm_dsl.source import Span
from rssm_dsl.syntax import ast
from rssm_dsl.syntax.printer import expr_text

# ---------------------------------------------------------------------- atoms


@dataclass(frozen=True)
class InBehaviour:
    """`SUB in BEH`: subsystem ``subsystem_id`` (Subsystem.id, e.g. "arm.c", "arm.e.motion")
    is in its behaviour ``behaviour``."""

    subsystem_id: str
    behaviour: str
    span: Span


@dataclass(frozen=True)
class Value:
    """`SUB.NAME`: the value of memory variable or buffer ``variable_name`` of subsystem
    ``subsystem_id``, of type ``type``; ``kind`` is "memory", "input" or "output"."""

    subsystem_id: str
    variable_name: str
    type: Type
    span: Span
    kind: str


Atom = InBehaviour | Value


class PropertyError(Exception):
    """An expression that does not resolve against the system (the front end reports it as
    a diagnostic; only code that skips the front end sees this)."""


class UnknownValue(LookupError):
    """The ``value`` callback of an evaluation could not give an atom's value."""


# ---------------------------------------------------------------------- resolution


@dataclass(frozen=True)
class _Param:
    subsystem: Subsystem
    name: str
    type: Type
    span: Span


class _Resolver:
    """Rewrites a property expression into a plain one: every atom and parameter becomes a
    name (``_slot``) the expression checker and the code generator know. Problems go to
    ``bag`` when there is one, else raise PropertyError."""

    def __init__(self, system: System, symbols: Mapping[str, Symbol],
                 bag: DiagnosticBag | None = None,
                 declared: Mapping[str, ast.SubsystemDecl] | None = None) -> None:
        self.system = system
        self.symbols = symbols
        self.bag = bag
        self.declared = declared or {}
        self.agents: dict[str, Agent] = {a.name: a for a in system.agents}
        self.prefix = "_p"
        while any(n.startswith(self.prefix) for n in symbols):
            self.prefix = "_" + self.prefix
        self.atoms: list[Atom] = []
        self.slots: dict[str, Atom | _Param] = {}     # synthetic name -> what it stands for
        self._keys: dict[tuple[str, ...], str] = {}
        self.extra: dict[str, Symbol] = {}            # synthetic name -> its symbol
        self.failed = False

    # -- reporting
    def _error(self, code: str, message: str, span: Span, hint: str | None = None,
               related: tuple[Related, ...] = ()) -> ast.Expr:
        self.failed = True
        if self.bag is None:
            raise PropertyError(f"{span.file}:{span.line}:{span.column}: {message}")
        self.bag.error(code, message, span, hint, related=related)
        return self._unknown(span)

    def _unknown(self, span: Span) -> ast.Expr:
        """A name of unknown type: the checker says nothing more about it."""
        name = f"{self.prefix}x"
        self.extra[name] = Symbol("memory", None, span)
        return ast.Name(span, name)

    def _slot(self, key: tuple[str, ...], target: Atom | _Param, t: Type, span: Span) -> str:
        name = self._keys.get(key)
        if name is None:
            name = self._keys[key] = f"{self.prefix}{len(self._keys)}"
            self.slots[name] = target
            self.extra[name] = Symbol("const" if isinstance(target, _Param) else "memory", t,
                                      span)
        return name

    # -- names
    def _subsystem(self, agent: Agent, name: str, span: Span, whole: Span) -> Subsystem | None:
        if name == "c":
            control = next((s for s in agent.subsystems if s.kind == "control"), None)
            if control is not None:
                return control
        found = next((s for s in agent.subsystems if s.name == name), None)
        if found is not None:
            return found
        if any(d.name == name for d in agent.devices):
            self._error("E620", f"'{agent.name}.{name}' is a device; a property reads the "
                        "designed subsystems", whole,
                        "name the virtual effector or receptor that talks to it, or the "
                        f"control subsystem `{agent.name}.c`")
            return None
        names = ["c", *(s.name for s in agent.subsystems if s.kind != "control")]
        guess = did_you_mean(name, names)
        self._error("E620", f"agent '{agent.name}' has no subsystem '{name}'", span,
                    f"did you mean '{agent.name}.{guess}'?" if guess else
                    "its subsystems: " + ", ".join(f"{agent.name}.{n}" for n in names))
        return None

    def _agent(self, name: str, span: Span) -> Agent | None:
        agent = self.agents.get(name)
        if agent is None:
            guess = did_you_mean(name, self.agents)
            self._error("E620", f"'{name}' is not an agent of system '{self.system.name}'",
                        span, f"did you mean '{guess}'?" if guess else
                        "write a subsystem as AGENT.SUBSYSTEM, e.g. "
                        f"`{next(iter(self.agents), 'a1')}.c`")
        return agent

    def _declared(self, sub: Subsystem, name: str) -> bool:
        """Declared in the text, but left out of the model (its declaration had an error)."""
        decl = self.declared.get(sub.id)
        return decl is not None and (any(x.name == name for x in decl.params)
                                     or any(x.name == name for x in decl.memory)
                                     or any(x.name == name for x in decl.buffers))

    def _variable(self, sub: Subsystem, name: str, span: Span, whole: Span) -> ast.Expr:
        for kind, variables in (("memory", sub.memory), ("input", sub.inputs),
                                ("output", sub.outputs)):
            v = next((x for x in variables if x.name == name), None)
            if v is not None:
                atom = Value(sub.id, name, v.type, whole, kind)
                self.atoms.append(atom)
                return ast.Name(whole, self._slot(("v", sub.id, name), atom, v.type, whole))
        p = next((x for x in sub.params if x.name == name), None)
        if p is not None:
            param = _Param(sub, name, p.type, whole)
            return ast.Name(whole, self._slot(("p", sub.id, name), param, p.type, whole))
        if self._declared(sub, name):
            self.failed = True
            return self._unknown(whole)
        names = _variable_names(sub)
        guess = did_you_mean(name, names)
        return self._error("E622", f"{sub.id} has no variable '{name}'", span,
                           f"did you mean '{guess}'?" if guess else
                           "a property reads memory variables, buffers and parameters"
                           + (": " + ", ".join(names) if names else
                              f"; {sub.id} declares none"))

    # -- the rewrite
    def rewrite(self, e: ast.Expr) -> ast.Expr:
        match e:
            case ast.InBehaviour():
                return self._in(e)
            case ast.Name() | ast.FieldAccess():
                return self._path(e)
            case ast.Index():
                return replace(e, value=self.rewrite(e.value), index=self.rewrite(e.index))
            case ast.Call():
                if e.function not in BUILTIN_FUNCTIONS and e.function not in self.symbols:
                    ext = next((x for x in self.system.externs if x.name == e.function), None)
                    if ext is not None:
                        return self._error("E103", f"'{e.function}' is an external operation; "
                                           "a property cannot call one", e.function_span,
                                           "state the property with the built-in operators "
                                           "and functions only")
                return replace(e, args=tuple(self.rewrite(a) for a in e.args))
            case ast.Unary():
                return replace(e, operand=self.rewrite(e.operand))
            case ast.Binary():
                return replace(e, left=self.rewrite(e.left), right=self.rewrite(e.right))
            case ast.IfExpr():
                return replace(e, condition=self.rewrite(e.condition), then=self.rewrite(e.then),
                               otherwise=self.rewrite(e.otherwise))
            case ast.ArrayLit():
                return replace(e, items=tuple(self.rewrite(x) for x in e.items))
            case ast.RecordLit():
                return replace(e, fields=tuple((n, self.rewrite(v)) for n, v in e.fields))
        return e

    def _in(self, e: ast.InBehaviour) -> ast.Expr:
        subject = e.subject
        if not (isinstance(subject, ast.FieldAccess) and isinstance(subject.value, ast.Name)):
            return self._error("E620", f"'{expr_text(subject)}' is not a subsystem",
                               subject.span, "write the subsystem as AGENT.SUBSYSTEM, "
                               f"e.g. `arm.c in {e.behaviour}`")
        agent = self._agent(subject.value.name, subject.value.span)
        if agent is None:
            return self._unknown(e.span)
        sub = self._subsystem(agent, subject.field, _field_span(subject), subject.span)
        if sub is None:
            return self._unknown(e.span)
        if not any(b.name == e.behaviour for b in sub.behaviours):
            names = [b.name for b in sub.behaviours]
            guess = did_you_mean(e.behaviour, names)
            return self._error("E621", f"{sub.id} has no behaviour '{e.behaviour}'",
                               e.behaviour_span, f"did you mean '{guess}'?" if guess else
                               "its behaviours: " + (", ".join(names) or "none"))
        atom = InBehaviour(sub.id, e.behaviour, e.span)
        self.atoms.append(atom)
        return ast.Name(e.span, self._slot(("b", sub.id, e.behaviour), atom, BOOL, e.span))

    def _path(self, e: ast.Name | ast.FieldAccess) -> ast.Expr:
        """A name followed by fields: AGENT.SUB.VAR(.FIELD)*, or a constant or an enum
        member (and its fields)."""
        chain: list[ast.FieldAccess] = []       # outermost first
        x: ast.Expr = e
        while isinstance(x, ast.FieldAccess):
            chain.append(x)
            x = x.value
        if not isinstance(x, ast.Name):         # (expr).field: the inner expression
            inner = self.rewrite(x)
            for node in reversed(chain):
                inner = replace(node, value=inner)
            return inner
        root = x
        chain.reverse()                         # innermost first: root.f1, root.f1.f2, ...
        if root.name in self.agents and (chain or root.name not in self.symbols):
            if not chain:
                agent = self.agents[root.name]
                return self._error("E622", f"'{root.name}' is an agent, not a value", root.span,
                                   "a property reads AGENT.SUBSYSTEM.VARIABLE, e.g. "
                                   f"`{root.name}.c.NAME`, or tests `{root.name}.c in "
                                   f"{_first_behaviour(agent)}`")
            return self._in_system(root, chain)
        if root.name in self.symbols or root.name in BUILTIN_CONSTS:
            return e
        if chain:
            self._agent(root.name, root.span)
            return self._unknown(e.span)
        holders = [s.id for s in self.system.subsystems()
                   if root.name in _variable_names(s)]
        if holders:
            return self._error("E622", f"'{root.name}' is not a constant; a property reads a "
                               "subsystem's variable as SUBSYSTEM.NAME", root.span,
                               f"write `{written(self.system, holders[0])}.{root.name}`")
        guess = did_you_mean(root.name, [*self.symbols, *BUILTIN_CONSTS])
        return self._error("E622", f"'{root.name}' is not declared", root.span,
                           f"did you mean '{guess}'?" if guess else
                           "a property reads SUBSYSTEM.NAME (e.g. `arm.c.count`), constants "
                           "and literals")

    def _in_system(self, root: ast.Name, chain: list[ast.FieldAccess]) -> ast.Expr:
        agent = self.agents[root.name]
        first = chain[0]
        sub = self._subsystem(agent, first.field, _field_span(first), first.span)
        if sub is None:
            return self._unknown(chain[-1].span)
        if len(chain) == 1:
            return self._error("E622", f"'{root.name}.{first.field}' is a subsystem, not a "
                               "value", first.span,
                               f"read one of its variables (`{root.name}.{first.field}.NAME`) "
                               f"or test its behaviour (`{root.name}.{first.field} in "
                               f"{sub.behaviours[0].name if sub.behaviours else 'BEHAVIOUR'}`)")
        second = chain[1]
        value = self._variable(sub, second.field, _field_span(second), second.span)
        for node in chain[2:]:
            value = replace(node, value=value)
        return value


def _variable_names(sub: Subsystem) -> list[str]:
    """The parameters, memory variables and buffers of a subsystem, in that order."""
    return ([p.name for p in sub.params] + [m.name for m in sub.memory]
            + [b.name for b in (*sub.inputs, *sub.outputs)])


def _field_span(e: ast.FieldAccess) -> Span:
    """The span of the field name of `x.field` (its last token)."""
    s = e.span
    n = len(e.field)
    return Span(s.file, s.end_line, max(1, s.end_column - n), s.end_line, s.end_column,
                max(s.offset, s.end_offset - n), s.end_offset)


def _first_behaviour(agent: Agent) -> str:
    control = next((s for s in agent.subsystems if s.kind == "control"), None)
    return control.behaviours[0].name if control is not None and control.behaviours \
        else "BEHAVIOUR"


def written(system: System, sid: str) -> str:
    """How a property writes the subsystem with id ``sid``: `arm.c`, `arm.motion`."""
    sub = next(s for s in system.subsystems() if s.id == sid)
    return f"{sub.agent}.c" if sub.kind == "control" else f"{sub.agent}.{sub.name}"


def _symbols(system: System) -> dict[str, Symbol]:
    out = enum_symbols(system.types, system.span)
    out.update({c.name: Symbol("const", c.type, c.span) for c in system.consts})
    return out


def atoms(system: System, expr: ast.Expr) -> list[Atom]:
    """The atoms of a property expression of ``system``, resolved, in the order they appear
    (every occurrence). Raises PropertyError when the expression does not resolve."""
    r = _Resolver(system, _symbols(system))
    r.rewrite(expr)
    return r.atoms


# ---------------------------------------------------------------------- front end


_PART = {"always": ("condition",), "response": ("trigger", "goal")}


def check_properties(bag: DiagnosticBag, system: System, decls: tuple[ast.PropertyDecl, ...],
                     symbols: Mapping[str, Symbol],
                     declared: Mapping[str, ast.SubsystemDecl],
                     reads: dict[str, set[str]] | None = None) -> tuple[Property, ...]:
    """Check the property declarations of a system; the model's properties (those that
    resolve and type-check). ``symbols``: the constants and enum types; ``declared``: the
    subsystems' declarations by id (names whose declaration failed are not reported again);
    ``reads``, when given, receives the variables and parameters the properties read, by
    subsystem id (they count as used)."""
    out: list[Property] = []
    seen: dict[str, Span] = {}
    for d in decls:
        if d.name in seen:
            bag.error("E624", f"property '{d.name}' is declared twice", d.name_span,
                      "rename one of them", related=(Related(seen[d.name], "first declared "
                                                                            "here"),))
            continue
        seen[d.name] = d.name_span
        ok = True
        for part in _PART[d.kind]:
            e: ast.Expr | None = getattr(d, part)
            if e is None:  # debris of syntax error recovery
                ok = False
                continue
            ok = _check_expr(bag, system, d, part, e, symbols, declared, reads) and ok
        if ok:
            out.append(Property(d.name, "response" if d.kind == "response" else "always",
                                d.span, d.name_span, d.condition, d.trigger, d.goal))
    return tuple(out)


def _check_expr(bag: DiagnosticBag, system: System, d: ast.PropertyDecl, part: str,
                e: ast.Expr, symbols: Mapping[str, Symbol],
                declared: Mapping[str, ast.SubsystemDecl],
                reads: dict[str, set[str]] | None) -> bool:
    before = len(bag.items)
    r = _Resolver(system, symbols, bag, declared)
    plain = r.rewrite(e)
    if reads is not None:
        for target in r.slots.values():
            if isinstance(target, Value):
                reads.setdefault(target.subsystem_id, set()).add(target.variable_name)
            elif isinstance(target, _Param):
                reads.setdefault(target.subsystem.id, set()).add(target.name)
    scope = Scope(dict(symbols), {}, extra=dict(r.extra))
    t = ExprChecker(bag).check(plain, scope, BOOL)
    if t is not None and t != BOOL:
        what = "the condition" if part == "condition" else f"the {part}"
        bag.error("E623", f"{what} of property '{d.name}' is {t}, not bool", e.span,
                  "compare it (`==`, `<`, ...), or test a behaviour: "
                  "`AGENT.SUBSYSTEM in BEHAVIOUR`")
    if any(x.is_error for x in bag.items[before:]) or r.failed:
        return False
    warned: set[tuple[str, str]] = set()
    for atom in r.atoms:
        if not isinstance(atom, Value) or finite_domain(atom.type) is not None:
            continue
        key = (atom.subsystem_id, atom.variable_name)
        if key in warned:
            continue
        warned.add(key)
        bag.warn("W626", f"property '{d.name}' reads {expr_text(_path_of(atom, system))} "
                    f"({atom.type}): the verifier cannot track it, it tracks bool, enum and "
                    "small range values only; the property is checked with that value "
                    "abstracted", atom.span,
                    "give the variable a range or enum type (`memory n: 0..10`), or state "
                    "the property without it")
    return True


def _path_of(atom: Value, system: System) -> ast.Expr:
    agent, _, rest = written(system, atom.subsystem_id).partition(".")
    s = atom.span
    return ast.FieldAccess(s, ast.FieldAccess(s, ast.Name(s, agent), rest), atom.variable_name)


# ---------------------------------------------------------------------- evaluation


class Formula:
    """A property expression compiled once: ``formula(in_behaviour, value) -> bool``.

    ``in_behaviour(subsystem_id, behaviour)`` says whether a subsystem is in a behaviour;
    ``value(subsystem_id, variable_name)`` gives a memory variable's or buffer's value in the
    interpreter's representation (rssm_core.values: bool, int, float, an enum member's name;
    arrays and records are converted as the values of external operations are, so lists,
    tuples or numpy arrays and dicts will do, and a value that does not fit raises
    PropertyError); it raises LookupError (or returns None) for a value it does not know,
    and the evaluation raises UnknownValue. Each distinct atom is asked for
    once per evaluation, all of them before the expression runs (no short circuit).
    Parameters and constants take their values at the start of the run
    (rssm_dsl.interp.initial). Run-time failures of the expression (a division by zero)
    raise rssm_dsl.interp.errors.EvalError, as in the interpreter."""

    def __init__(self, system: System, expr: ast.Expr) -> None:
        from rssm_dsl.interp.compile_expr import ExprCompiler
        from rssm_dsl.interp.initial import InitialValues

        initial = InitialValues(system)
        if initial.diagnostics:
            raise PropertyError("the system's initial values cannot be computed: "
                                + initial.diagnostics[0].message)
        r = _Resolver(system, initial.const_symbols)
        plain = r.rewrite(expr)
        self.expr = expr
        self.atoms: tuple[Atom, ...] = tuple(r.atoms)
        consts = dict(initial.consts)
        self._slots: list[tuple[str, Atom, Callable[[Any], Any] | None]] = []
        for name, target in r.slots.items():
            if isinstance(target, _Param):
                p = next(x for x in target.subsystem.params if x.name == target.name)
                consts[name] = initial.param(target.subsystem.id, p)
            elif isinstance(target, Value) and isinstance(target.type, ArrayT | RecordT):
                self._slots.append((name, target, rt.converter(descriptor(target.type))))
            else:
                self._slots.append((name, target, None))
        symbols = {**initial.const_symbols, **r.extra}
        self._fn = ExprCompiler(symbols, {}, consts).expr(plain, BOOL)

    def __call__(self, in_behaviour: Callable[[str, str], bool],
                 value: Callable[[str, str], Any]) -> bool:
        env: dict[str, Any] = {}
        for name, atom, convert in self._slots:
            if isinstance(atom, InBehaviour):
                env[name] = bool(in_behaviour(atom.subsystem_id, atom.behaviour))
                continue
            where = f"{atom.subsystem_id}.{atom.variable_name}"
            try:
                v = value(atom.subsystem_id, atom.variable_name)
            except LookupError as e:
                raise UnknownValue(f"the value of {where} is unknown ({e})") from e
            if v is None:
                raise UnknownValue(f"the value of {where} is unknown")
            if convert is not None:
                try:
                    v = convert(v)
                except rt.ValueTypeError as e:
                    raise PropertyError(f"the value given for {where} is not a {atom.type}: "
                                        f"{e}") from e
            env[name] = v
        return bool(self._fn(env))


def evaluate(system: System, expr: ast.Expr, in_behaviour: Callable[[str, str], bool],
             value: Callable[[str, str], Any]) -> bool:
    """Evaluate a property expression once (compiles it: use :class:`Formula` in a loop)."""
    return Formula(system, expr)(in_behaviour, value)
