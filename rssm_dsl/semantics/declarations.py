"""Program-wide declarations: types, constants, external operations, device types."""

from __future__ import annotations

import re
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import field

from rssm_core.records import dataclass
from rssm_dsl.diagnostics import DiagnosticBag, Related
from rssm_dsl.semantics.model import Const, Extern
from rssm_dsl.semantics.typecheck import (
    BUILTIN_CONSTS,
    BUILTIN_FUNCTIONS,
    ExprChecker,
    Scope,
    Symbol,
    did_you_mean,
    mismatch_hint,
)
from rssm_dsl.semantics.types import (
    SCALARS,
    ArrayT,
    EnumT,
    RangeT,
    RecordT,
    Type,
    assignable,
    scalar_count,
)
from rssm_dsl.source import Span
from rssm_dsl.syntax import ast

# the most numbers one value may hold (8 MB of floats: a 640x480 RGB image fits)
MAX_VALUES = 1 << 20

BINDING_RE = re.compile(r"^[A-Za-z_][A-Za-z0-9_]*(\.[A-Za-z_][A-Za-z0-9_]*)*:[A-Za-z_][A-Za-z0-9_]*$")


@dataclass
class Globals:
    types: dict[str, Type] = field(default_factory=dict)
    consts: dict[str, Const] = field(default_factory=dict)
    externs: dict[str, Extern] = field(default_factory=dict)
    devices: dict[str, ast.DeviceDecl] = field(default_factory=dict)
    agent_defs: dict[str, ast.AgentDef] = field(default_factory=dict)
    systems: list[ast.SystemDecl] = field(default_factory=list)
    spans: dict[str, Span] = field(default_factory=dict)
    # consts and externs whose type could not be determined (an error was reported): their
    # uses are not reported again
    broken: dict[str, Symbol] = field(default_factory=dict)

    def symbols(self) -> dict[str, Symbol]:
        out = {n: Symbol("enum", t, self.spans[n]) for n, t in self.types.items()
               if isinstance(t, EnumT) and n in self.spans}
        out.update(self.broken)
        out.update({n: Symbol("const", c.type, c.span) for n, c in self.consts.items()})
        return out


class DeclarationPass:
    def __init__(self, bag: DiagnosticBag) -> None:
        self.bag = bag
        self.g = Globals()
        self.checker = ExprChecker(bag)
        self._type_decls: dict[str, ast.RecordDecl | ast.AliasDecl | ast.EnumDecl] = {}
        self._resolving: set[str] = set()
        self._const_scope: dict[str, Symbol] = {}

    @contextmanager
    def reporting_to(self, bag: DiagnosticBag) -> Iterator[None]:
        """Report to `bag` meanwhile (what the passes find in one agent, types included,
        is kept with that agent's work: see analyze.AgentMemo)."""
        old = self.bag
        self.bag = bag
        try:
            yield
        finally:
            self.bag = old

    def _declare(self, name: str, span: Span) -> bool:
        if name in self.g.spans:
            self.bag.error("E101", f"'{name}' is declared twice", span,
                           related=(Related(self.g.spans[name], "first declared here"),))
            return False
        if name in SCALARS or name in BUILTIN_FUNCTIONS or name in BUILTIN_CONSTS:
            self.bag.error("E101", f"'{name}' is a built-in name", span, "choose another name")
            return False
        self.g.spans[name] = span
        return True

    def run(self, modules: list[ast.Module], root: ast.Module | None) -> Globals:
        decls = [d for m in modules for d in m.decls]
        for d in decls:
            if isinstance(d, ast.RecordDecl | ast.AliasDecl | ast.EnumDecl) and \
                    self._declare(d.name, d.name_span):
                self._type_decls[d.name] = d
        for name in list(self._type_decls):
            self._resolve_named(name)
        # what a constant's value may name, kept up to date as constants are declared (the
        # types are all resolved by now): building it anew for each constant was quadratic
        self._const_scope = self.g.symbols()
        for d in decls:
            match d:
                case ast.ConstDecl():
                    self._const(d)
                case ast.ExternDecl():
                    self._extern(d)
                case ast.AgentDef():
                    if self._declare(d.name, d.name_span):
                        self.g.agent_defs[d.name] = d
                    self._agent_params(d)
                case ast.DeviceDecl():
                    if self._declare(d.name, d.name_span):
                        self.g.devices[d.name] = d
                    if d.binding is not None:
                        self._binding(d.binding.binding, d.binding.span, "Class")
                case ast.SystemDecl():
                    if root is not None and d in root.decls:
                        self.g.systems.append(d)
                    else:
                        self.bag.error("E104", f"system '{d.name}' is declared in an imported "
                                       "module", d.name_span, "compile that file instead")
        return self.g

    def _agent_params(self, d: ast.AgentDef) -> None:
        """E101 for a parameter of an agent definition declared twice."""
        seen: dict[str, Span] = {}
        for p in d.params:
            if p.name in seen:
                self.bag.error("E101", f"parameter '{p.name}' of agent definition '{d.name}' "
                               "is declared twice", p.name_span, "rename one of them",
                               related=(Related(seen[p.name], "first declared here"),))
            else:
                seen[p.name] = p.name_span

    # ------------------------------------------------------------------ types
    def resolve_type(self, t: ast.TypeExpr) -> Type | None:
        if isinstance(t, ast.ArrayType):
            elem = self.resolve_type(t.element)
            if elem is None:
                return None
            if t.size < 1:
                self.bag.error("E206", "an array needs at least one element", t.span)
                return None
            values = t.size * scalar_count(elem)
            if values > MAX_VALUES:
                self.bag.error("E206", f"an array of {values:,} values is larger than the "
                               f"{MAX_VALUES:,} a value may hold", t.span,
                               "every backend holds each value whole in memory, and copies it "
                               "as it is sent: keep large data in a device or an external "
                               "operation")
                return None
            return ArrayT(elem, t.size)
        if isinstance(t, ast.RangeType):
            if t.lo > t.hi:
                self.bag.error("E213", f"the range {t.lo}..{t.hi} is empty: its low bound is "
                               "above its high bound", t.span,
                               f"write the low bound first: {t.hi}..{t.lo}")
                return None
            return RangeT(t.lo, t.hi)
        if t.name in SCALARS:
            return SCALARS[t.name]
        if t.name in self._type_decls:
            return self._resolve_named(t.name, t.span)
        if t.name in self.g.devices or t.name in self.g.consts or t.name in self.g.externs:
            self.bag.error("E103", f"'{t.name}' is not a type", t.span)
            return None
        guess = did_you_mean(t.name, [*SCALARS, *self._type_decls])
        self.bag.error("E202", f"unknown type '{t.name}'", t.span,
                       f"did you mean '{guess}'?" if guess else
                       "built-in types are bool, int, float and T[N]; import std.types for more")
        return None

    def _resolve_named(self, name: str, use: Span | None = None) -> Type | None:
        if name in self.g.types:
            return self.g.types[name]
        decl = self._type_decls[name]
        if name in self._resolving:
            self.bag.error("E202", f"type '{name}' is defined in terms of itself",
                           use or decl.name_span)
            return None
        self._resolving.add(name)
        try:
            if isinstance(decl, ast.AliasDecl):
                result = self.resolve_type(decl.type)
            elif isinstance(decl, ast.EnumDecl):
                result = self._enum(decl)
            else:
                fields: list[tuple[str, Type]] = []
                seen: set[str] = set()
                ok = True
                for f in decl.fields:
                    if f.name in seen:
                        self.bag.error("E101", f"field '{f.name}' is declared twice", f.span)
                        continue
                    seen.add(f.name)
                    ft = self.resolve_type(f.type)
                    if ft is None:
                        ok = False
                        continue
                    fields.append((f.name, ft))
                result = RecordT(name, tuple(fields)) if ok else None
        finally:
            self._resolving.discard(name)
        if result is not None:
            self.g.types[name] = result
        return result

    def _enum(self, decl: ast.EnumDecl) -> EnumT | None:
        if not decl.members:
            self.bag.error("E210", f"enum '{decl.name}' has no members", decl.name_span,
                           f"list its values: `enum {decl.name} {{ first, second }}`")
            return None
        members: dict[str, Span] = {}
        for m in decl.members:
            if m.name in members:
                self.bag.error("E211", f"member '{m.name}' of enum '{decl.name}' is declared "
                               "twice", m.span,
                               related=(Related(members[m.name], "first declared here"),))
                continue
            members[m.name] = m.span
        return EnumT(decl.name, tuple(members))

    # ------------------------------------------------------------------ values
    def _const(self, d: ast.ConstDecl) -> None:
        if not self._declare(d.name, d.name_span):
            return
        want = self.resolve_type(d.type) if d.type is not None else None
        scope = Scope(self._const_scope, self.g.externs, no_calls="a constant")
        got = self.checker.check(d.value, scope, want)
        if got is None or (d.type is not None and want is None):
            self._broken_const(d)
            return
        if want is not None and not assignable(got, want):
            self.bag.error("E201", f"const '{d.name}' is declared {want} but its value is {got}",
                           d.value.span, hint=mismatch_hint(got, want))
            self._broken_const(d)
            return
        if want is not None:
            self.checker.fits(d.value, want, f"const '{d.name}'")
        self.g.consts[d.name] = Const(d.name, want or got, d.value, d.span)
        self._const_scope[d.name] = Symbol("const", want or got, d.span)

    def _broken_const(self, d: ast.ConstDecl) -> None:
        self.g.broken[d.name] = self._const_scope[d.name] = Symbol("const", None, d.name_span)

    def _binding(self, binding: str, span: Span, what: str) -> None:
        """A Python binding is `package.module:name`."""
        if BINDING_RE.match(binding):
            return
        module, _, name = binding.rpartition(".")
        guess = f"{module}:{name}" if module and BINDING_RE.match(f"{module}:{name}") else None
        self.bag.error("E208", f"binding \"{binding}\" is not of the form module:{what}", span,
                       f'did you mean "{guess}"?' if guess and ":" not in binding else
                       f'write the Python module, a colon and the {what} name, e.g. '
                       f'"rssm_stdlib.lwr4plus.ops:impedance"')

    def _extern(self, d: ast.ExternDecl) -> None:
        if not self._declare(d.name, d.name_span):
            return
        self._binding(d.binding, d.binding_span, "function")
        params: list[tuple[str, Type]] = []
        for p in d.params:
            pt = self.resolve_type(p.type)
            if pt is not None:
                params.append((p.name, pt))
        result = self.resolve_type(d.result)
        if result is None or len(params) != len(d.params):
            self.g.broken[d.name] = Symbol("extern", None, d.name_span)
            return
        self.g.externs[d.name] = Extern(d.name, tuple(params), result, d.binding, d.span)
