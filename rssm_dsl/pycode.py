"""Python source for the DSL's expressions and statements: the one expression compiler.

Both executions of a specification run what this module writes: the interpreter
(rssm_dsl.interp.compile_expr compiles the source once per subsystem and calls it on its
variables) and the generated ROS 2 nodes (rssm_dsl.ros2.nodecode writes it into the node
modules). The code calls the semantics core, rssm_core.values (imported as ``_rt``), for
every operation whose meaning is not plain Python: int arithmetic (64-bit, overflow fails),
division and remainder (checked for zero), float min/max/clamp (NaN propagates), indexing,
array arithmetic, external operations (their results checked against the declared type),
the check of a value stored into a range type (``_rt.in_range``: an int assigned to a
memory variable of type ``0..3`` fails there when it lies outside). An enum member
``Phase.grasp`` is the string literal ``'grasp'``.
Static types come from the front end's ExprChecker, so every int-to-float widening the
language allows is a conversion written at the place it happens.

User text never becomes Python syntax: every name of the specification is emitted mangled
(``v_`` variables, parameters and locals, ``k_`` constants, ``x_`` external operations,
``c_`` terminal/error conditions in switch conditions), field names, behaviour names and
source locations only inside string literals written by ``repr``, numbers by ``repr`` (an
infinite float as ``math.inf``). Generated helper names start with ``_`` or an upper-case
letter and so never collide with a mangled name. Where an operation can fail, the code
passes a *site*: by default the ``file:line:column`` string literal of the expression; the
interpreter passes its own reference to the span instead (``PyGen(site=...)``).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping
from dataclasses import field

from rssm_core.records import dataclass
from rssm_dsl.diagnostics import DiagnosticBag
from rssm_dsl.semantics.model import Extern
from rssm_dsl.semantics.typecheck import BUILTIN_CONSTS, ExprChecker, Scope, Symbol
from rssm_dsl.semantics.types import (
    BOOL,
    FLOAT,
    INT,
    ArrayT,
    EnumT,
    RangeT,
    RecordT,
    Scalar,
    Type,
    descriptor,
    is_int,
)
from rssm_dsl.source import Span
from rssm_dsl.syntax import ast
from rssm_dsl.syntax.printer import expr_text

MATH1 = {"sin": "math.sin", "cos": "math.cos", "tan": "math.tan", "asin": "math.asin",
         "acos": "math.acos", "atan": "math.atan", "exp": "math.exp", "log": "math.log",
         "sqrt": "math.sqrt", "tanh": "math.tanh", "floor": "_rt.floor", "ceil": "_rt.ceil"}


def var(name: str) -> str:
    return "v_" + name


def const(name: str) -> str:
    return "k_" + name


def extern(name: str) -> str:
    return "x_" + name


def cond(name: str) -> str:
    return "c_" + name


def number(value: bool | int | float) -> str:
    if isinstance(value, bool):
        return "True" if value else "False"
    if isinstance(value, float) and not math.isfinite(value):
        if math.isnan(value):
            return "math.nan"
        return "math.inf" if value > 0 else "(-math.inf)"
    return repr(value)


def where(span: Span) -> str:
    """A source location as a Python string literal."""
    return repr(f"{span.file}:{span.line}:{span.column}")


def comment(text: str) -> str:
    """Text safe inside a one-line ``#`` comment (no line breaks, printable ASCII)."""
    return "".join(c if " " <= c <= "~" else "?" for c in text)


def tuple_source(items: list[str] | tuple[str, ...]) -> str:
    """A tuple display of items given as Python source: (), (a,), (a, b)."""
    return "(" + ", ".join(items) + ("," if len(items) == 1 else "") + ")"


def narrows(src: Type, dst: Type) -> bool:
    """Must a value of type ``src`` be checked when stored as a ``dst``? (An int, or a wider
    range, stored into a range; arrays of them element-wise.)"""
    if isinstance(dst, RangeT):
        return not (isinstance(src, RangeT) and dst.lo <= src.lo and src.hi <= dst.hi)
    if isinstance(dst, ArrayT) and isinstance(src, ArrayT):
        return narrows(src.element, dst.element)
    return False


def descriptor_source(t: Type) -> str:
    """The value descriptor of a type (rssm_core.values) as Python source."""
    return repr(descriptor(t))


@dataclass
class TypeTable:
    """Module-level names for the descriptors and converters a node uses (T0, CV0, ...)."""

    descs: dict[str, str] = field(default_factory=dict)        # source -> name
    converters: dict[str, str] = field(default_factory=dict)   # descriptor name -> name

    def desc(self, t: Type) -> str:
        src = descriptor_source(t)
        if src not in self.descs:
            self.descs[src] = f"T{len(self.descs)}"
        return self.descs[src]

    def converter(self, t: Type) -> str:
        d = self.desc(t)
        if d not in self.converters:
            self.converters[d] = f"CV{d[1:]}"
        return self.converters[d]

    def desc_lines(self) -> list[str]:
        return [f"{name} = {src}" for src, name in self.descs.items()]

    def converter_lines(self) -> list[str]:
        return [f"{name} = _rt.converter({d})" for d, name in self.converters.items()]


class PyGen:
    """Generates the Python of one scope's expressions (one subsystem, or the constants)."""

    def __init__(self, symbols: Mapping[str, Symbol], externs: Mapping[str, Extern],
                 types: TypeTable, special: frozenset[str] = frozenset(),
                 site: Callable[[Span], str] = where) -> None:
        self.symbols = dict(symbols)
        self.site = site
        self.externs = dict(externs)
        self.types = types
        self.special = special
        self.locals: dict[str, Symbol] = {}
        self.extra_symbols: dict[str, Symbol] = {}
        self.reads: set[str] = set()             # variables read from the state
        self.specials_read: set[str] = set()
        self.externs_used: set[str] = set()
        self.temps = 0

    # ------------------------------------------------------------------ types
    def _scope(self) -> Scope:
        return Scope(self.symbols, self.externs, extra={**self.extra_symbols, **self.locals})

    def type_of(self, e: ast.Expr, expected: Type | None = None) -> Type:
        bag = DiagnosticBag()
        t = ExprChecker(bag).check(e, self._scope(), expected)
        if t is None or bag.has_errors:
            raise AssertionError(f"the front end accepted an ill-typed expression at {e.span}: "
                                 f"{expr_text(e)}")
        return t

    def coerce(self, code: str, src: Type, dst: Type, span: Span | None = None,
               what: str | None = None) -> str:
        """``code`` (of type ``src``) as a ``dst``; a value stored into a range is checked
        (``what`` names the place in the failure's message, ``span`` is where it fails)."""
        if src == dst:
            return code
        if narrows(src, dst):
            assert span is not None, f"a range check without a site: {src} -> {dst}"
            site = self.site(span)
            if isinstance(dst, RangeT):
                return f"_rt.in_range({code}, {dst.lo}, {dst.hi}, {what!r}, {site})"
            return f"_rt.check_ranges({code}, {self.types.desc(dst)}, {what!r}, {site})"
        if is_int(src) and is_int(dst):
            return code           # a range read as an int: the same value
        if is_int(src) and dst == FLOAT:
            return f"float({code})"
        if isinstance(src, ArrayT) and isinstance(dst, ArrayT) and dst.element != FLOAT \
                and is_int(src.element) and is_int(dst.element):
            return code           # tuples of ints either way
        return f"{self.types.converter(dst)}({code})"

    # ------------------------------------------------------------------ expressions
    def expr(self, e: ast.Expr, expected: Type | None = None, what: str | None = None) -> str:
        """The code of ``e``; with ``expected``, converted to that type (and checked when it
        is stored into a range: ``what`` names the place for the failure's message)."""
        code, t = self._expr(e, expected)
        return self.coerce(code, t, expected, e.span, what) if expected is not None else code

    def _expr(self, e: ast.Expr, expected: Type | None = None) -> tuple[str, Type]:
        t = self.type_of(e, expected)
        match e:
            case ast.Literal():
                return number(e.value), t
            case ast.Name():
                return self._name(e), t
            case ast.FieldAccess():
                if isinstance(t, EnumT) and self._enum_name(e.value):
                    return repr(e.field), t          # a member: Phase.grasp
                return f"{self.expr(e.value)}[{e.field!r}]", t
            case ast.Index():
                return self._index(e), t
            case ast.Unary():
                return self._unary(e, t), t
            case ast.Binary():
                return self._binary(e, t), t
            case ast.IfExpr():
                c = self.expr(e.condition, BOOL)
                a = self.expr(e.then, t)
                b = self.expr(e.otherwise, t)
                return f"({a} if {c} else {b})", t
            case ast.ArrayLit():
                if isinstance(expected, ArrayT) and expected.element == FLOAT:
                    t = expected
                return self._array(e, t), t
            case ast.RecordLit():
                assert isinstance(t, RecordT)
                ft = {n: self.expr(v, t.field(n), f"{t.name}.{n}") for n, v in e.fields}
                return "{" + ", ".join(f"{n!r}: {c}" for n, c in ft.items()) + "}", t
            case ast.Call():
                return self._call(e, t), t
        raise AssertionError(e)

    def _enum_name(self, e: ast.Expr) -> bool:
        """Is ``e`` the name of an enum type (the base of a member, ``Phase`` in
        ``Phase.grasp``)?"""
        if not isinstance(e, ast.Name) or e.name in self.locals:
            return False
        sym = self.extra_symbols.get(e.name) or self.symbols.get(e.name)
        return sym is not None and sym.kind == "enum"

    def _name(self, e: ast.Name) -> str:
        name = e.name
        if name in self.special and name not in self.locals:
            self.specials_read.add(name)
            return cond(name)
        local = self.locals.get(name)
        if local is not None:
            return var(name)
        sym = self.symbols.get(name)
        if sym is not None and sym.kind != "const":
            self.reads.add(name)
            return var(name)
        if sym is not None:
            return const(name)
        if name in BUILTIN_CONSTS:
            return number(BUILTIN_CONSTS[name][1])
        raise AssertionError(f"unresolved name {name} at {e.span}")

    def _as_np(self, code: str, t: Type) -> str:
        if isinstance(t, ArrayT) and t.element != FLOAT:
            return f"_rt.as_np({code})"
        return code

    def _index(self, e: ast.Index) -> str:
        at = self.type_of(e.value)
        assert isinstance(at, ArrayT)
        arr = self.expr(e.value)
        idx = self.expr(e.index, INT)
        return f"_rt.index({arr}, {idx}, {at.size}, {at.element == FLOAT}, {self.site(e.span)})"

    def _unary(self, e: ast.Unary, t: Type) -> str:
        x = self.expr(e.operand)
        if e.op == "not":
            return f"(not {x})"
        if isinstance(t, ArrayT):
            return f"_rt.aneg({self._as_np(x, self.type_of(e.operand))})"
        if t == INT:
            if isinstance(e.operand, ast.Literal) and isinstance(e.operand.value, int):
                return f"({-e.operand.value})"    # a negative literal: nothing can overflow
            return f"_rt.ineg({x}, {self.site(e.span)})"
        return f"(-{x})"

    def _binary(self, e: ast.Binary, t: Type) -> str:
        op = e.op
        if op in ("and", "or"):
            return f"({self.expr(e.left, BOOL)} {op} {self.expr(e.right, BOOL)})"
        lt, rt = self.type_of(e.left), self.type_of(e.right)
        a, b = self.expr(e.left), self.expr(e.right)
        if op in ("==", "!="):
            if isinstance(lt, Scalar | EnumT | RangeT) and isinstance(rt, Scalar | EnumT | RangeT):
                return f"({a} {op} {b})"
            return f"_rt.equal({a}, {b})" if op == "==" else f"(not _rt.equal({a}, {b}))"
        if op in ("<", "<=", ">", ">="):
            return f"({a} {op} {b})"
        if isinstance(t, ArrayT):
            na, nb = self._as_np(a, lt), self._as_np(b, rt)
            if op == "/":
                return f"_rt.adiv({na}, {nb}, {isinstance(rt, ArrayT)}, {self.site(e.span)})"
            fn = {"+": "aadd", "-": "asub", "*": "amul"}[op]
            return f"_rt.{fn}({na}, {nb})"
        if op in ("+", "-", "*"):
            if t == INT:
                fn = {"+": "iadd", "-": "isub", "*": "imul"}[op]
                return f"_rt.{fn}({a}, {b}, {self.site(e.span)})"
            return f"({a} {op} {b})"
        fn = "div" if op == "/" else "mod"
        return f"_rt.{fn}({a}, {b}, {self.site(e.span)})"

    def _array(self, e: ast.ArrayLit, t: Type) -> str:
        assert isinstance(t, ArrayT)
        items = tuple_source([self.expr(x, t.element) for x in e.items])
        if t.element == FLOAT:
            return f"_rt.float_array({items})"
        return items

    def _call(self, e: ast.Call, t: Type) -> str:
        ext = self.externs.get(e.function)
        if ext is not None:
            self.externs_used.add(ext.name)
            args = [self.expr(a, pt, f"argument '{pn}' of {ext.name}()")
                    for a, (pn, pt) in zip(e.args, ext.params, strict=True)]
            conv = self.types.converter(ext.result)
            rest = "".join(", " + a for a in args)
            return (f"_rt.call({extern(ext.name)}, {conv}, {ext.name!r}, {self.site(e.span)}"
                    f"{rest})")
        f = e.function
        if f in MATH1:
            x = self.expr(e.args[0], FLOAT)
            return f"_rt.math1({MATH1[f]}, {f!r}, {x}, {self.site(e.span)})"
        if f == "atan2":
            return f"math.atan2({self.expr(e.args[0], FLOAT)}, {self.expr(e.args[1], FLOAT)})"
        if f in ("abs", "min", "max", "clamp"):
            args = [self.expr(a, t) for a in e.args]
            if f == "abs":
                return f"_rt.iabs({args[0]}, {self.site(e.span)})" if t == INT else f"abs({args[0]})"
            if t == INT:
                if f == "clamp":
                    return f"min(max({args[0]}, {args[1]}), {args[2]})"
                return f"{f}({', '.join(args)})"
            return f"_rt.f{f}({', '.join(args)})"
        vecs = [self._as_np(self.expr(a), self.type_of(a)) for a in e.args]
        if f == "norm":
            return f"_rt.norm({vecs[0]})"
        if f == "dot":
            return f"_rt.dot({vecs[0]}, {vecs[1]}, {self.site(e.span)})"
        if f == "cross":
            return f"_rt.cross({vecs[0]}, {vecs[1]})"
        raise AssertionError(f"unknown built-in {f} at {e.span}")

    # ------------------------------------------------------------------ statements
    def body(self, stmts: tuple[ast.Stmt, ...]) -> tuple[list[str], tuple[str, ...]]:
        """The lines of a statement list and the variables it assigns (roots of targets).
        Locals declared by ``let`` are visible to the statements after them only."""
        saved = dict(self.locals)
        lines: list[str] = []
        written: list[str] = []
        try:
            for s in stmts:
                match s:
                    case ast.Skip():
                        continue
                    case ast.Let():
                        t = self.type_of(s.value)
                        lines.append(f"{var(s.name)} = {self.expr(s.value)}")
                        self.locals[s.name] = Symbol("local", t, s.span)
                    case ast.Assign():
                        root = self._assign(s, lines)
                        if root not in written:
                            written.append(root)
        finally:
            self.locals = saved
        return lines, tuple(written)

    def _temp(self, prefix: str) -> str:
        self.temps += 1
        return f"_{prefix}{self.temps}"

    def _assign(self, s: ast.Assign, lines: list[str]) -> str:
        tt = self.type_of(s.target)
        value = self.expr(s.value, tt, expr_text(s.target))
        steps: list[tuple[str, str, int, str]] = []      # (kind, field/index, size, where)
        node: ast.Expr = s.target
        while isinstance(node, ast.FieldAccess | ast.Index):
            if isinstance(node, ast.FieldAccess):
                steps.append(("field", repr(node.field), 0, ""))
            else:
                at = self.type_of(node.value)
                assert isinstance(at, ArrayT)
                steps.append(("index", self.expr(node.index, INT), at.size, self.site(node.span)))
            node = node.value
        assert isinstance(node, ast.Name)
        root = node.name
        target = var(root)
        if not steps:
            lines.append(f"{target} = {value}")
            return root
        steps.reverse()
        if self.locals.get(root) is None:
            self.reads.add(root)      # a part of it is replaced: its old value is needed
        v = self._temp("v")
        lines.append(f"{v} = {value}")
        # descend: the container of every step but the last, indices evaluated once each
        containers = [target]
        keys: list[str] = []
        for k, (kind, key, size, loc) in enumerate(steps):
            if kind == "index":
                i = self._temp("i")
                lines.append(f"{i} = {key}")
                key = i
            keys.append(key)
            if k < len(steps) - 1:
                c = self._temp("c")
                parent = containers[-1]
                if kind == "field":
                    lines.append(f"{c} = {parent}[{key}]")
                else:
                    lines.append(f"{c} = _rt.index({parent}, {key}, {size}, False, {loc})")
                containers.append(c)
        # rebuild from the innermost part outwards
        new = v
        for k in range(len(steps) - 1, -1, -1):
            kind, _, size, loc = steps[k]
            parent = containers[k]
            if kind == "field":
                new = f"_rt.set_field({parent}, {keys[k]}, {new})"
            else:
                new = f"_rt.set_item({parent}, {keys[k]}, {size}, {new}, {loc})"
        lines.append(f"{target} = {new}")
        return root
