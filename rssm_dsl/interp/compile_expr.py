"""The interpreter's expressions and statements: the Python that rssm_dsl.pycode writes (the
same code the generated ROS 2 nodes run), compiled once into functions of the subsystem's
variables.

An expression becomes a function ``env -> value`` where ``env`` is the ``dict`` of the
subsystem's variables (parameters, memory, input and output buffers) plus the local values of
``let``. A statement list becomes a function ``env -> None`` that writes ``env``; a data case
becomes a function ``(env, stage) -> None`` that writes only the values it assigns into
``stage``. Values are immutable (rssm_core.values).

Run-time failures (division by zero, an index out of range, integer overflow, a math domain
error, an external operation that raises or returns a value of the wrong type) raise
:class:`EvalError` with the span of the expression that failed (E802 / E803).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping
from typing import Any

import rssm_core.values as rt
from rssm_dsl.diagnostics import DiagnosticBag
from rssm_dsl.interp.errors import EvalError
from rssm_dsl.pycode import PyGen, TypeTable, cond, const, extern, var
from rssm_dsl.semantics.model import Extern
from rssm_dsl.semantics.typecheck import ExprChecker, Scope, Symbol
from rssm_dsl.semantics.types import Type
from rssm_dsl.source import Span
from rssm_dsl.syntax import ast
from rssm_dsl.syntax.printer import expr_text

Env = dict[str, Any]
Fn = Callable[[Env], Any]
Run = Callable[[Env], None]
Case = Callable[[Env, dict[str, Any]], None]
Resolver = Callable[[Extern, Span], Callable[..., Any] | None]

HINTS = {
    "E802": None,
    "E803": "make the Python function return the declared type",
    "E801": "bind the extern to a Python function (extern NAME(...) -> T = \"module:function\")",
}


def _lift(e: rt.OperationError) -> EvalError:
    """The interpreter's error for a failure of the core's operations (``where`` is a Span)."""
    span = e.where
    assert isinstance(span, Span)
    return EvalError(e.code, e.message, span, HINTS.get(e.code))


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
        self.extra_symbols: dict[str, Symbol] = {}
        self.types = TypeTable()
        self.sites: list[Span] = []
        self.ns: dict[str, Any] = {"_rt": rt, "math": math, "_S": self.sites,
                                   "_OpError": rt.OperationError, "_lift": _lift,
                                   "_special": self.special}
        for name, value in self.consts.items():
            self.ns[const(name)] = value
        self._types_done = 0
        self._converters_done = 0
        self._count = 0

    # ------------------------------------------------------------------ pieces
    def _site(self, span: Span) -> str:
        self.sites.append(span)
        return f"_S[{len(self.sites) - 1}]"

    def _gen(self) -> PyGen:
        gen = PyGen(self.symbols, self.externs, self.types, frozenset(self.special), self._site)
        gen.extra_symbols = dict(self.extra_symbols)
        return gen

    def type_of(self, e: ast.Expr, expected: Type | None = None) -> Type:
        bag = DiagnosticBag()
        scope = Scope(self.symbols, self.externs, extra=dict(self.extra_symbols))
        t = ExprChecker(bag).check(e, scope, expected)
        if t is None or bag.has_errors:
            raise AssertionError(f"the front end accepted an ill-typed expression at {e.span}: "
                                 f"{expr_text(e)}")
        return t

    def _bind_externs(self, gen: PyGen) -> None:
        for name in gen.externs_used:
            key = extern(name)
            if key in self.ns:
                continue
            ext = self.externs[name]
            self.ns[key] = self.resolve(ext, ext.span) if self.resolve is not None else None

    def _compile(self, gen: PyGen, params: str, body: list[str]) -> Any:
        """Define a function of ``params`` running ``body`` (after loading what it reads) in
        the namespace, and return it."""
        self._bind_externs(gen)
        prelude = [*self.types.desc_lines()[self._types_done:],
                   *self.types.converter_lines()[self._converters_done:]]
        self._types_done = len(self.types.descs)
        self._converters_done = len(self.types.converters)
        self._count += 1
        name = f"_f{self._count}"
        loads = [f"{var(n)} = env[{n!r}]" for n in sorted(gen.reads)]
        loads += [f"{cond(n)} = _special[{n!r}]()" for n in sorted(gen.specials_read)]
        lines = [*prelude, f"def {name}({params}):", "    try:",
                 *(f"        {x}" for x in [*loads, *body] or ["pass"]),
                 "    except _OpError as e:",
                 "        raise _lift(e) from e.__cause__"]
        exec(compile("\n".join(lines), f"<rssm {name}>", "exec"), self.ns)
        return self.ns.pop(name)

    # ------------------------------------------------------------------ expressions
    def expr(self, e: ast.Expr, expected: Type | None = None, what: str | None = None) -> Fn:
        """The function of ``e``; with ``expected``, its value converted to that type (and
        checked when that is a range; ``what`` names the variable in the failure)."""
        gen = self._gen()
        code = gen.expr(e, expected, what)
        fn: Fn = self._compile(gen, "env", [f"return {code}"])
        return fn

    # ------------------------------------------------------------------ statements
    def body(self, stmts: tuple[ast.Stmt, ...]) -> tuple[Run, tuple[str, ...]]:
        """The runner of a statement list (it writes ``env``) and the names it assigns."""
        gen = self._gen()
        lines, written = gen.body(stmts)
        lines += [f"env[{n!r}] = {var(n)}" for n in written]
        run: Run = self._compile(gen, "env", lines)
        return run, written

    def case(self, stmts: tuple[ast.Stmt, ...]) -> tuple[Case, tuple[str, ...]]:
        """A data case: reads ``env``, writes what it assigns into ``stage`` only."""
        gen = self._gen()
        lines, written = gen.body(stmts)
        lines += [f"stage[{n!r}] = {var(n)}" for n in written]
        fn: Case = self._compile(gen, "env, stage", lines)
        return fn, written
