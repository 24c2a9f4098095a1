"""Compile the DSL's expressions and statements to Python closures, once.

An expression becomes a function ``env -> value`` where ``env`` is the ``dict`` of the
subsystem's variables (parameters, memory, input and output buffers) plus the local values
of ``let``; constants are folded into the closures. Static types come from the front end's
type checker (:class:`ExprChecker`), so every int-to-float widening the language allows is a
conversion compiled in at the place it happens, and array and record operations are chosen
once, not tested at every evaluation.

A statement becomes a function ``env -> None`` that writes ``env``. Writing a field or an
element builds a new value (values are immutable, see :mod:`rssm_dsl.interp.values`).

Run-time failures (division by zero, an index out of range, a math domain error, an external
operation that raises or returns a value of the wrong type) raise :class:`EvalError` with the
span of the expression that failed (E802 / E803).
"""

from __future__ import annotations

import inspect
import math
from collections.abc import Callable, Mapping
from typing import Any

import numpy as np

from rssm_dsl.diagnostics import DiagnosticBag, Related
from rssm_dsl.interp.errors import EvalError
from rssm_dsl.interp.values import (
    ValueTypeError,
    converter,
    equal,
    float_array,
    freeze,
    is_float_array,
)
from rssm_dsl.semantics.model import Extern
from rssm_dsl.semantics.typecheck import BUILTIN_CONSTS, ExprChecker, Scope, Symbol
from rssm_dsl.semantics.types import BOOL, FLOAT, INT, ArrayT, RecordT, Scalar, Type
from rssm_dsl.source import Span
from rssm_dsl.syntax import ast
from rssm_dsl.syntax.printer import expr_text

Env = dict[str, Any]
Fn = Callable[[Env], Any]
Run = Callable[[Env], None]
Resolver = Callable[[Extern, Span], Callable[..., Any] | None]

_MATH1: dict[str, Callable[[float], float]] = {
    "sin": math.sin, "cos": math.cos, "tan": math.tan, "asin": math.asin, "acos": math.acos,
    "atan": math.atan, "exp": math.exp, "log": math.log, "sqrt": math.sqrt, "tanh": math.tanh,
    "floor": lambda x: float(math.floor(x)), "ceil": lambda x: float(math.ceil(x)),
}


def _fail(span: Span, message: str, hint: str | None = None) -> EvalError:
    return EvalError("E802", message, span, hint)


def coerce(fn: Fn, src: Type, dst: Type) -> Fn:
    """``fn`` converted from its static type ``src`` to ``dst`` (int -> float widening)."""
    if src == dst:
        return fn
    if src == INT and dst == FLOAT:
        return lambda env: float(fn(env))
    conv = converter(dst)
    return lambda env: conv(fn(env))


def _as_numpy(fn: Fn, t: Type) -> Fn:
    """A numeric array operand as a float64 array (int arrays are tuples)."""
    if is_float_array(t) or not isinstance(t, ArrayT):
        return fn
    return lambda env: np.array(fn(env), dtype=np.float64)


class ExprCompiler:
    """Compiles the expressions of one subsystem (or of the global constants)."""

    def __init__(self, symbols: Mapping[str, Symbol], externs: Mapping[str, Extern],
                 consts: Mapping[str, Any], resolve: Resolver | None = None,
                 special: Mapping[str, Callable[[], Any]] | None = None) -> None:
        self.symbols = dict(symbols)
        self.externs = dict(externs)
        self.consts = dict(consts)
        self.resolve = resolve
        self.special = dict(special or {})   # names read through a getter (switch conditions)
        self.locals: dict[str, Symbol] = {}
        self.extra_symbols: dict[str, Symbol] = {}

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

    # ------------------------------------------------------------------ expressions
    def expr(self, e: ast.Expr, expected: Type | None = None) -> Fn:
        """The closure of ``e``; with ``expected``, its value converted to that type."""
        fn, t = self._expr(e, expected)
        return coerce(fn, t, expected) if expected is not None else fn

    def _expr(self, e: ast.Expr, expected: Type | None = None) -> tuple[Fn, Type]:
        t = self.type_of(e, expected)
        match e:
            case ast.Literal():
                value = e.value
                return (lambda env: value), t
            case ast.Name():
                return self._name(e), t
            case ast.FieldAccess():
                inner = self.expr(e.value)
                name = e.field
                return (lambda env: inner(env)[name]), t
            case ast.Index():
                return self._index(e), t
            case ast.Unary():
                return self._unary(e, t), t
            case ast.Binary():
                return self._binary(e, t), t
            case ast.IfExpr():
                cond = self.expr(e.condition, BOOL)
                then = self.expr(e.then, t)
                other = self.expr(e.otherwise, t)
                return (lambda env: then(env) if cond(env) else other(env)), t
            case ast.ArrayLit():
                if isinstance(expected, ArrayT) and expected.element == FLOAT:
                    t = expected
                return self._array(e, t), t
            case ast.RecordLit():
                assert isinstance(t, RecordT)
                fields = [(n, self.expr(v, t.field(n))) for n, v in e.fields]
                return (lambda env: {n: f(env) for n, f in fields}), t
            case ast.Call():
                return self._call(e, t), t
        raise AssertionError(e)

    def _name(self, e: ast.Name) -> Fn:
        name = e.name
        if name in self.special and name not in self.locals:
            getter = self.special[name]
            return lambda env: getter()
        sym = self.locals.get(name) or self.symbols.get(name)
        if sym is not None and sym.kind != "const":
            return lambda env: env[name]
        if name in self.consts:
            value = self.consts[name]
            return lambda env: value
        if name in BUILTIN_CONSTS:
            c = BUILTIN_CONSTS[name][1]
            return lambda env: c
        raise AssertionError(f"unresolved name {name} at {e.span}")

    def _index(self, e: ast.Index) -> Fn:
        at = self.type_of(e.value)
        assert isinstance(at, ArrayT)
        arr = self.expr(e.value)
        idx = self.expr(e.index, INT)
        size, span = at.size, e.span
        floats = at.element == FLOAT

        def index(env: Env) -> Any:
            a, i = arr(env), idx(env)
            if 0 <= i < size:
                return a.item(i) if floats else a[i]
            raise _fail(span, f"index {i} is out of range for {at}",
                        f"indices run from 0 to {size - 1}")
        return index

    def _unary(self, e: ast.Unary, t: Type) -> Fn:
        x = self.expr(e.operand)
        if e.op == "not":
            return lambda env: not x(env)
        if isinstance(t, ArrayT):
            xt = self.type_of(e.operand)
            xn = _as_numpy(x, xt)
            return lambda env: freeze(np.negative(xn(env)))
        return lambda env: -x(env)

    def _binary(self, e: ast.Binary, t: Type) -> Fn:
        op, span = e.op, e.span
        if op in ("and", "or"):
            a, b = self.expr(e.left, BOOL), self.expr(e.right, BOOL)
            if op == "and":
                return lambda env: a(env) and b(env)
            return lambda env: a(env) or b(env)
        lt, rt = self.type_of(e.left), self.type_of(e.right)
        a, b = self.expr(e.left), self.expr(e.right)
        if op in ("==", "!="):
            if isinstance(lt, Scalar) and isinstance(rt, Scalar):
                return (lambda env: a(env) == b(env)) if op == "==" else (
                    lambda env: a(env) != b(env))
            if op == "==":
                return lambda env: equal(a(env), b(env))
            return lambda env: not equal(a(env), b(env))
        if op in ("<", "<=", ">", ">="):
            return {
                "<": lambda env: a(env) < b(env), "<=": lambda env: a(env) <= b(env),
                ">": lambda env: a(env) > b(env), ">=": lambda env: a(env) >= b(env),
            }[op]
        if isinstance(t, ArrayT):
            return self._array_arith(op, _as_numpy(a, lt), _as_numpy(b, rt),
                                     isinstance(rt, ArrayT), span)
        if op == "+":
            return lambda env: a(env) + b(env)
        if op == "-":
            return lambda env: a(env) - b(env)
        if op == "*":
            return lambda env: a(env) * b(env)
        word = "division" if op == "/" else "remainder"

        def divide(env: Env) -> Any:
            x, y = a(env), b(env)
            if y == 0:
                raise _fail(span, f"{word} by zero in {expr_text(e)}")
            return x / y if op == "/" else x % y
        return divide

    @staticmethod
    def _array_arith(op: str, a: Fn, b: Fn, b_array: bool, span: Span) -> Fn:
        if op == "+":
            return lambda env: freeze(np.add(a(env), b(env)))
        if op == "-":
            return lambda env: freeze(np.subtract(a(env), b(env)))
        if op == "*":
            return lambda env: freeze(np.multiply(a(env), b(env)))

        def divide(env: Env) -> Any:
            x, y = a(env), b(env)
            if (not np.all(y)) if b_array else y == 0:
                raise _fail(span, "division by zero")
            return freeze(np.divide(x, y))
        return divide

    def _array(self, e: ast.ArrayLit, t: Type) -> Fn:
        assert isinstance(t, ArrayT)
        items = [self.expr(x, t.element) for x in e.items]
        if t.element == FLOAT:
            if len(items) == 3:
                i0, i1, i2 = items
                return lambda env: float_array((i0(env), i1(env), i2(env)))
            return lambda env: float_array([f(env) for f in items])
        return lambda env: tuple(f(env) for f in items)

    # ------------------------------------------------------------------ calls
    def _call(self, e: ast.Call, t: Type) -> Fn:
        ext = self.externs.get(e.function)
        if ext is not None:
            return self._extern(e, ext)
        f, span = e.function, e.span
        if f in _MATH1:
            g = _MATH1[f]
            x = self.expr(e.args[0], FLOAT)

            def math1(env: Env) -> float:
                v = x(env)
                try:
                    return g(v)
                except (ValueError, OverflowError) as ex:
                    raise _fail(span, f"{f}({v!r}): {ex}") from None
            return math1
        if f == "atan2":
            y, x = self.expr(e.args[0], FLOAT), self.expr(e.args[1], FLOAT)
            return lambda env: math.atan2(y(env), x(env))
        if f in ("abs", "min", "max", "clamp"):
            args = [self.expr(a, t) for a in e.args]
            if f == "abs":
                return lambda env: abs(args[0](env))
            if f == "min":
                return lambda env: min(args[0](env), args[1](env))
            if f == "max":
                return lambda env: max(args[0](env), args[1](env))
            return lambda env: min(max(args[0](env), args[1](env)), args[2](env))
        vecs = [_as_numpy(self.expr(a), self.type_of(a)) for a in e.args]
        if f == "norm":
            v0 = vecs[0]
            return lambda env: float(np.linalg.norm(v0(env)))
        if f == "dot":
            v0, v1 = vecs

            def dot(env: Env) -> float:
                x, y = v0(env), v1(env)
                if len(x) != len(y):
                    raise _fail(span, f"dot() of arrays of sizes {len(x)} and {len(y)}")
                return float(np.dot(x, y))
            return dot
        if f == "cross":
            v0, v1 = vecs
            return lambda env: freeze(np.cross(v0(env), v1(env)))
        raise AssertionError(f"unknown built-in {f} at {span}")

    def _extern(self, e: ast.Call, ext: Extern) -> Fn:
        args = [self.expr(a, pt) for a, (_, pt) in zip(e.args, ext.params, strict=True)]
        target = self.resolve(ext, e.span) if self.resolve is not None else None
        span, name = e.span, ext.name
        related = (Related(ext.span, f"extern {name} is bound to \"{ext.binding}\""),)
        if target is None:
            def unbound(env: Env) -> Any:
                raise EvalError("E801", f"extern {name} has no binding", span, None, related)
            return unbound
        fn = target
        conv = converter(ext.result)

        def failed(ex: Exception) -> EvalError:
            return EvalError("E802", f"{name}() raised {type(ex).__name__}: {ex}", span,
                             "the Python function of the extern failed; see its message",
                             related)

        def wrong(ex: ValueTypeError) -> EvalError:
            return EvalError("E803", f"{name}() returned {ex} (declared -> {ext.result})", span,
                             "make the function return the declared type", related)

        if len(args) == 4:
            a0, a1, a2, a3 = args

            def call4(env: Env) -> Any:
                x0, x1, x2, x3 = a0(env), a1(env), a2(env), a3(env)
                try:
                    r = fn(x0, x1, x2, x3)
                except Exception as ex:
                    raise failed(ex) from ex
                try:
                    return conv(r)
                except ValueTypeError as ex:
                    raise wrong(ex) from None
            return call4

        def call(env: Env) -> Any:
            values = [a(env) for a in args]
            try:
                r = fn(*values)
            except Exception as ex:
                raise failed(ex) from ex
            try:
                return conv(r)
            except ValueTypeError as ex:
                raise wrong(ex) from None
        return call

    # ------------------------------------------------------------------ statements
    def body(self, stmts: tuple[ast.Stmt, ...]) -> tuple[Run, tuple[str, ...]]:
        """The runner of a statement list and the names it assigns (roots of the targets).

        Locals declared by ``let`` are visible to the statements after them only."""
        saved = dict(self.locals)
        runs: list[Run] = []
        written: list[str] = []
        try:
            for s in stmts:
                match s:
                    case ast.Skip():
                        continue
                    case ast.Let():
                        t = self.type_of(s.value)
                        runs.append(self._let(s.name, self.expr(s.value)))
                        self.locals[s.name] = Symbol("local", t, s.span)
                    case ast.Assign():
                        run, root = self._assign(s)
                        runs.append(run)
                        if root not in written:
                            written.append(root)
        finally:
            self.locals = saved
        if not runs:
            return (lambda env: None), ()
        if len(runs) == 1:
            return runs[0], tuple(written)
        seq = tuple(runs)

        def run_all(env: Env) -> None:
            for r in seq:
                r(env)
        return run_all, tuple(written)

    @staticmethod
    def _let(name: str, value: Fn) -> Run:
        def let(env: Env) -> None:
            env[name] = value(env)
        return let

    def _assign(self, s: ast.Assign) -> tuple[Run, str]:
        tt = self.type_of(s.target)
        value = self.expr(s.value, tt)
        steps: list[tuple[str, Any]] = []
        node: ast.Expr = s.target
        while isinstance(node, ast.FieldAccess | ast.Index):
            if isinstance(node, ast.FieldAccess):
                steps.append(("field", node.field))
            else:
                at = self.type_of(node.value)
                assert isinstance(at, ArrayT)
                steps.append(("index", (self.expr(node.index, INT), at, node.span)))
            node = node.value
        assert isinstance(node, ast.Name)
        root = node.name
        steps.reverse()
        if not steps:
            def assign(env: Env) -> None:
                env[root] = value(env)
            return assign, root
        update = _updater(steps)

        def assign_part(env: Env) -> None:
            v = value(env)
            env[root] = update(env[root], env, v)
        return assign_part, root


def _updater(steps: list[tuple[str, Any]]) -> Callable[[Any, Env, Any], Any]:
    """A function rebuilding a value with the part at ``steps`` replaced (no mutation)."""
    kind, arg = steps[0]
    inner = _updater(steps[1:]) if len(steps) > 1 else None
    if kind == "field":
        name = arg

        def set_field(container: Any, env: Env, v: Any) -> Any:
            new = dict(container)
            new[name] = inner(container[name], env, v) if inner is not None else v
            return new
        return set_field
    idx, at, span = arg
    size = at.size

    def set_item(container: Any, env: Env, v: Any) -> Any:
        i = idx(env)
        if not 0 <= i < size:
            raise _fail(span, f"index {i} is out of range for {at}",
                        f"indices run from 0 to {size - 1}")
        item = inner(container[i], env, v) if inner is not None else v
        if isinstance(container, np.ndarray):
            c = container.copy()
            c[i] = item
            return freeze(c)
        items = list(container)
        items[i] = item
        return tuple(items)
    return set_item


def check_signature(fn: Callable[..., Any], arity: int) -> str | None:
    """Why ``fn`` cannot be called with ``arity`` positional arguments, or None."""
    try:
        sig = inspect.signature(fn)
    except (TypeError, ValueError):
        return None
    try:
        sig.bind(*range(arity))
    except TypeError as e:
        return str(e)
    return None
