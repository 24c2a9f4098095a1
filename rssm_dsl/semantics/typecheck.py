"""Type checking of expressions and statements of the small RSSM expression language."""

from __future__ import annotations

import difflib
from collections.abc import Callable, Iterable, Mapping
from dataclasses import field
from typing import Protocol

from rssm_core.records import dataclass
from rssm_core.values import INT_MAX, INT_MIN
from rssm_dsl.diagnostics import DiagnosticBag
from rssm_dsl.semantics.model import Extern
from rssm_dsl.semantics.types import (
    BOOL,
    FLOAT,
    INT,
    ArrayT,
    EnumT,
    RangeT,
    RecordT,
    Type,
    assignable,
    is_int,
    is_numeric,
    is_numeric_array,
    join,
)
from rssm_dsl.source import Span
from rssm_dsl.syntax import ast

_MATH1 = ("sin", "cos", "tan", "asin", "acos", "atan", "exp", "log", "sqrt", "floor", "ceil",
          "tanh")
BUILTIN_FUNCTIONS = (*_MATH1, "abs", "atan2", "min", "max", "clamp", "norm", "dot", "cross",
                     "new")
BUILTIN_CONSTS: dict[str, tuple[Type, float]] = {"pi": (FLOAT, 3.141592653589793),
                                                 "inf": (FLOAT, float("inf"))}


# "did you mean" costs a pass over every candidate: a file of thousands of undeclared names
# would take minutes (quadratic). After this many suggestions in one analysis, none more: the
# first ones are what a person reads (analyze() starts the count again).
SUGGESTIONS_AT_MOST = 200
_suggested = [0]


def new_suggestions() -> None:
    """A new analysis: the count of suggestions starts again."""
    _suggested[0] = 0


def did_you_mean(name: str, candidates: Iterable[str] | Callable[[], Iterable[str]]
                 ) -> str | None:
    """The declared name closest to a misspelt one (same letters in another case first);
    None after SUGGESTIONS_AT_MOST suggestions in this analysis (``candidates`` may be a
    function giving them: it is then not called)."""
    _suggested[0] += 1
    if _suggested[0] > SUGGESTIONS_AT_MOST:
        return None
    pool = sorted(set(candidates() if callable(candidates) else candidates))
    same = [c for c in pool if c.lower() == name.lower()]
    if same:
        return same[0]
    close = difflib.get_close_matches(name, pool, n=1, cutoff=0.75)
    return close[0] if close else None


def guess_hint(guess: str, scope: Scope, at: Span) -> str:
    """"did you mean" for a name, with where the proposed name is declared: when the
    declaration is the misspelt one (every use says `status`, the input says `stauts`),
    the fix is there, not at the uses."""
    sym = scope.lookup(guess)
    if sym is None or sym.kind in ("const", "extern", "enum", "condition") or not sym.span.line:
        return f"did you mean '{guess}'?"
    where = (f"line {sym.span.line}" if sym.span.file == at.file
             else f"{sym.span.file}:{sym.span.line}")
    return (f"did you mean '{guess}'? ({sym.kind} '{guess}' is declared at {where}: if that "
            f"declaration is the misspelt name, correct it there)")


@dataclass(frozen=True)
class Symbol:
    kind: str   # const | extern | param | memory | input | output | local | condition | enum
    type: Type | None  # None: declared, but its type is unknown (an error was reported)
    span: Span


class Declared(Protocol):
    """A declared variable: a parameter, a memory variable, or (with a direction) a buffer."""

    @property
    def name(self) -> str: ...
    @property
    def type(self) -> Type | None: ...
    @property
    def span(self) -> Span: ...


class DeclaredBuffer(Declared, Protocol):
    @property
    def direction(self) -> ast.Direction: ...


def enum_symbols(types: Iterable[tuple[str, Type]], span: Span) -> dict[str, Symbol]:
    """The enum types among ``types`` (``System.types``) as the symbols that let expressions
    name their members (``Phase.idle``); ``span`` stands for where they are declared."""
    return {n: Symbol("enum", t, span) for n, t in types if isinstance(t, EnumT)}


INT_RANGE_HINT = f"an int is a 64-bit integer, from {INT_MIN} to {INT_MAX}"


def int_literal(e: ast.Expr) -> int | None:
    """The value of an int literal (None for anything else)."""
    match e:
        case ast.Literal(value=int() as v) if not isinstance(v, bool):
            return v
    return None


def constant_int(e: ast.Expr) -> int | None:
    """The value of an int expression made of literals, unary minus, ``+``, ``-`` and ``*``
    (None for anything else), computed exactly (in Python's unbounded ints)."""
    match e:
        case ast.Literal(value=int() as v) if not isinstance(v, bool):
            return v
        case ast.Unary(op="-", operand=operand):
            inner = constant_int(operand)
            return -inner if inner is not None else None
        case ast.Binary(op="+" | "-" | "*", left=left, right=right):
            a, b = constant_int(left), constant_int(right)
            if a is None or b is None:
                return None
            return a + b if e.op == "+" else a - b if e.op == "-" else a * b
    return None


def owner_symbols(base: Mapping[str, Symbol], params: Iterable[Declared],
                  memory: Iterable[Declared], buffers: Iterable[DeclaredBuffer]
                  ) -> dict[str, Symbol]:
    """The names the expressions of one subsystem (or device) see: ``base`` (the constants),
    then its parameters, memory variables and buffers, each shadowing what came before."""
    symbols = dict(base)
    for v in params:
        symbols[v.name] = Symbol("param", v.type, v.span)
    for v in memory:
        symbols[v.name] = Symbol("memory", v.type, v.span)
    for b in buffers:
        symbols[b.name] = Symbol(b.direction.value, b.type, b.span)
    return symbols


@dataclass
class Scope:
    """Names visible in one expression context."""

    symbols: dict[str, Symbol]
    externs: dict[str, Extern]
    new_allowed: bool = False          # inside a data-availability case condition
    inputs: tuple[str, ...] = ()
    reads: set[str] = field(default_factory=set)
    extra: dict[str, Symbol] = field(default_factory=dict)  # locals (let), conditions
    # where external operations cannot be called (initial values and constants are computed
    # before the run, by every backend alike), e.g. "the initial value of param 'k'"
    no_calls: str | None = None
    # there, the constant ints met so far (as the backends compute them, in 64 bits), for the
    # operations that use them: id of the expression -> (the expression, its value)
    constants: dict[int, tuple[ast.Expr, int]] = field(default_factory=dict)

    def lookup(self, name: str) -> Symbol | None:
        return self.extra.get(name) or self.symbols.get(name)

    def names(self) -> set[str]:
        return set(self.symbols) | set(self.extra) | set(BUILTIN_CONSTS)


_INT_ARITH = frozenset(("+", "-", "*", "/", "%"))


class ExprChecker:
    def __init__(self, bag: DiagnosticBag) -> None:
        self.bag = bag

    # ------------------------------------------------------------ constant ints
    def _constant(self, e: ast.Expr, value: int, scope: Scope, literal: bool = False) -> None:
        """A constant int met while checking. An int literal outside 64 bits is E214
        wherever it is written. Where the value is computed before the run (a constant, an
        initial value) it is recorded for the operation that uses it, and an operation whose
        value lies outside 64 bits is E214; in a statement, that operation fails when it
        runs (E802), as every backend computes it."""
        in_range = INT_MIN <= value <= INT_MAX
        if literal and not in_range:
            self.bag.error("E214", f"value {value} is outside the 64-bit range of int", e.span,
                           INT_RANGE_HINT + " (write a float, such as 1e19, for a larger number)")
        if scope.no_calls is None or literal:
            return
        if in_range:
            scope.constants[id(e)] = (e, value)
        else:
            self.bag.error("E214", f"value {value} is outside the 64-bit range of int, in "
                           f"{scope.no_calls}", e.span, INT_RANGE_HINT)

    @staticmethod
    def _value(e: ast.Expr, scope: Scope) -> int | None:
        """The value of a checked constant int of a context computed before the run (None
        for anything else, and for one outside 64 bits)."""
        if type(e) is ast.Literal:        # the common cases first, as below
            v = e.value
            if isinstance(v, int) and not isinstance(v, bool):
                return v if INT_MIN <= v <= INT_MAX else None
            return None                   # a literal is never recorded in scope.constants
        if type(e) is ast.Binary:
            found = scope.constants.get(id(e))
            return found[1] if found is not None and found[0] is e else None
        literal = int_literal(e)
        if literal is None and isinstance(e, ast.Unary) and e.op == "-":
            negated = int_literal(e.operand)
            literal = -negated if negated is not None else None
        if literal is not None:
            return literal if INT_MIN <= literal <= INT_MAX else None
        found = scope.constants.get(id(e))
        return found[1] if found is not None and found[0] is e else None

    # ------------------------------------------------------------ expressions
    def check(self, e: ast.Expr, scope: Scope, expected: Type | None = None) -> Type | None:
        method: Callable[[ast.Expr, Scope, Type | None], Type | None] = getattr(
            self, "_" + type(e).__name__
        )
        return method(e, scope, expected)

    def expect(self, e: ast.Expr, scope: Scope, want: Type, what: str) -> None:
        got = self.check(e, scope, want)
        if got is not None and not assignable(got, want):
            self.bag.error("E201", f"{what} must be {want}, not {got}", e.span,
                           hint=mismatch_hint(got, want))
        elif got is not None:
            self.fits(e, want, what)

    def fits(self, e: ast.Expr, want: Type, what: str) -> None:
        """Report a constant int stored into a range it lies outside (E214): a literal, or
        literals combined by ``- + *``, also as an item of an array literal or a branch of
        ``if``. Other values are checked when they are stored, at run time. (An int literal
        outside 64 bits, and an operation overflowing them in a constant or an initial value,
        are reported when they are checked: _constant.)"""
        match e:
            case ast.IfExpr():
                self.fits(e.then, want, what)
                self.fits(e.otherwise, want, what)
                return
            case ast.ArrayLit() if isinstance(want, ArrayT):
                for item in e.items:
                    self.fits(item, want.element, what)
                return
        if not isinstance(want, RangeT):
            return
        value = constant_int(e)
        if value is not None and INT_MIN <= value <= INT_MAX and value not in want:
            self.bag.error("E214", f"value {value} is outside {want} of {what}", e.span,
                           f"{what} holds the integers from {want.lo} to {want.hi}")

    def _Literal(self, e: ast.Literal, scope: Scope, expected: Type | None) -> Type | None:
        value = e.value
        if isinstance(value, bool):
            return BOOL
        if isinstance(value, int):
            if not INT_MIN <= value <= INT_MAX:  # (a literal in range is not recorded)
                self._constant(e, value, scope, literal=True)
            return INT
        return FLOAT

    def _Name(self, e: ast.Name, scope: Scope, expected: Type | None) -> Type | None:
        sym = scope.lookup(e.name)
        if sym is not None and sym.kind == "enum":
            first = sym.type.members[0] if isinstance(sym.type, EnumT) else "member"
            self.bag.error("E103", f"'{e.name}' is an enum type, not a value", e.span,
                           f"name one of its members, e.g. {e.name}.{first}")
            return None
        if sym is None:
            if e.name in BUILTIN_CONSTS:
                return BUILTIN_CONSTS[e.name][0]
            guess = did_you_mean(e.name, scope.names)
            self.bag.error("E102", f"'{e.name}' is not declared here", e.span,
                           guess_hint(guess, scope, e.span) if guess
                           else "declare it as memory, param, a buffer or a const")
            return None
        scope.reads.add(e.name)
        return sym.type

    def _FieldAccess(self, e: ast.FieldAccess, scope: Scope, expected: Type | None) -> Type | None:
        if isinstance(e.value, ast.Name):
            sym = scope.lookup(e.value.name)
            if sym is not None and sym.kind == "enum":
                return self._member(e, sym.type)
        t = self.check(e.value, scope)
        if t is None:
            return None
        if not isinstance(t, RecordT):
            self.bag.error("E207", f"'{e.field}': a value of type {t} has no fields", e.span)
            return None
        ft = t.field(e.field)
        if ft is None:
            names = ", ".join(n for n, _ in t.fields)
            self.bag.error("E207", f"record {t.name} has no field '{e.field}'", e.span,
                           f"its fields are: {names}")
        return ft

    def _member(self, e: ast.FieldAccess, t: Type | None) -> Type | None:
        """``Phase.grasp``: a member of an enum type."""
        if not isinstance(t, EnumT):
            return None    # the enum's declaration failed (reported)
        if e.field in t.members:
            return t
        guess = did_you_mean(e.field, t.members)
        self.bag.error("E212", f"enum {t.name} has no member '{e.field}'", e.span,
                       f"did you mean '{t.name}.{guess}'?" if guess else
                       "its members are: " + ", ".join(t.members))
        return None

    def _Index(self, e: ast.Index, scope: Scope, expected: Type | None) -> Type | None:
        t = self.check(e.value, scope)
        self.expect(e.index, scope, INT, "an array index")
        if t is None:
            return None
        if not isinstance(t, ArrayT):
            self.bag.error("E206", f"cannot index a value of type {t}", e.span)
            return None
        if isinstance(e.index, ast.Literal) and isinstance(e.index.value, int) and not (
            0 <= e.index.value < t.size
        ):
            self.bag.error("E206", f"index {e.index.value} is out of range for {t}", e.index.span,
                           f"indices run from 0 to {t.size - 1}")
        return t.element

    def _Unary(self, e: ast.Unary, scope: Scope, expected: Type | None) -> Type | None:
        literal = int_literal(e.operand) if e.op == "-" else None
        if literal is not None:   # a negative int literal (-9223372036854775808 is one)
            self._constant(e, -literal, scope, literal=True)
            return INT
        t = self.check(e.operand, scope, expected)
        if t is None:
            return None
        value = self._value(e.operand, scope) if e.op == "-" and scope.no_calls else None
        if value is not None:
            self._constant(e, -value, scope)
        if e.op == "not":
            if t != BOOL:
                self.bag.error("E203", f"'not' needs a bool, not {t}", e.span)
            return BOOL
        if not (is_numeric(t) or is_numeric_array(t)):
            self.bag.error("E203", f"cannot negate a value of type {t}", e.span)
            return None
        return INT if isinstance(t, RangeT) else t

    def _Binary(self, e: ast.Binary, scope: Scope, expected: Type | None) -> Type | None:
        op = e.op
        if op == "and" or op == "or":
            self.expect(e.left, scope, BOOL, f"the left operand of '{op}'")
            self.expect(e.right, scope, BOOL, f"the right operand of '{op}'")
            return BOOL
        lt = self.check(e.left, scope)
        rt = self.check(e.right, scope)
        if lt is INT and rt is INT and op in _INT_ARITH:
            # the common case (long chains of int arithmetic), as _arith has it
            if op == "/":
                return FLOAT
            if op != "%" and scope.no_calls is not None:
                a, b = self._value(e.left, scope), self._value(e.right, scope)
                if a is not None and b is not None:
                    self._constant(e, a + b if op == "+" else a - b if op == "-" else a * b,
                                   scope)
            return INT
        if lt is None or rt is None:
            return BOOL if e.op in ("==", "!=", "<", "<=", ">", ">=") else None
        if e.op in ("==", "!="):
            if not (assignable(lt, rt) or assignable(rt, lt)):
                self.bag.error("E203", f"cannot compare {lt} with {rt}", e.span)
            return BOOL
        if e.op in ("<", "<=", ">", ">="):
            if not (is_numeric(lt) and is_numeric(rt)):
                self.bag.error("E203", f"'{e.op}' compares numbers, not {lt} and {rt}", e.span)
            return BOOL
        return self._arith(e, lt, rt, scope)

    def _arith(self, e: ast.Binary, lt: Type, rt: Type, scope: Scope) -> Type | None:
        if is_numeric(lt) and is_numeric(rt):
            if e.op == "/" or FLOAT in (lt, rt):
                return FLOAT
            if e.op in ("+", "-", "*") and scope.no_calls is not None:
                a, b = self._value(e.left, scope), self._value(e.right, scope)
                if a is not None and b is not None:
                    self._constant(e, a + b if e.op == "+" else a - b if e.op == "-" else a * b,
                                   scope)
            return INT
        if is_numeric_array(lt) and is_numeric_array(rt) and e.op in "+-*/":
            assert isinstance(lt, ArrayT) and isinstance(rt, ArrayT)
            if lt.size != rt.size:
                self.bag.error("E203", f"'{e.op}' of arrays of different sizes ({lt}, {rt})", e.span)
                return None
            return ArrayT(FLOAT, lt.size)
        if is_numeric_array(lt) and is_numeric(rt) and e.op in "*/":
            assert isinstance(lt, ArrayT)
            return ArrayT(FLOAT, lt.size)
        if is_numeric(lt) and is_numeric_array(rt) and e.op == "*":
            assert isinstance(rt, ArrayT)
            return ArrayT(FLOAT, rt.size)
        self.bag.error("E203", f"'{e.op}' does not apply to {lt} and {rt}", e.span)
        return None

    def _IfExpr(self, e: ast.IfExpr, scope: Scope, expected: Type | None) -> Type | None:
        self.expect(e.condition, scope, BOOL, "the condition of 'if'")
        a = self.check(e.then, scope, expected)
        b = self.check(e.otherwise, scope, expected)
        if a is None or b is None:
            return a or b
        joined = join(a, b)
        if joined is None:
            self.bag.error("E201", f"the branches of 'if' have different types ({a}, {b})",
                           e.span)
        return joined

    def _ArrayLit(self, e: ast.ArrayLit, scope: Scope, expected: Type | None) -> Type | None:
        want = expected.element if isinstance(expected, ArrayT) else None
        types = [self.check(x, scope, want) for x in e.items]
        if not e.items:
            self.bag.error("E201", "an empty array has no type", e.span)
            return None
        if any(t is None for t in types):
            return None
        elem = types[0]
        assert elem is not None
        for t, x in zip(types[1:], e.items[1:], strict=True):
            assert t is not None
            joined = join(elem, t)
            if joined is None:
                self.bag.error("E201", f"array items of different types ({elem}, {t})", x.span)
                return None
            elem = joined
        return ArrayT(elem, len(e.items))

    def _InBehaviour(self, e: ast.InBehaviour, scope: Scope, expected: Type | None
                     ) -> Type | None:
        # a property's tests are resolved before its expression is checked (properties.py)
        from rssm_dsl.syntax.printer import expr_text
        self.bag.error("E625", f"'{expr_text(e)}' tests which behaviour a subsystem is in; "
                       "that is only meaningful in a property", e.span,
                       "write it in `property NAME: always ...` inside the system, or test "
                       "this subsystem's own state here")
        return BOOL

    def _RecordLit(self, e: ast.RecordLit, scope: Scope, expected: Type | None) -> Type | None:
        if not isinstance(expected, RecordT):
            self.bag.error("E201", "a record literal needs a record type from its context", e.span,
                           "assign it to a record buffer, memory variable or parameter")
            for _, v in e.fields:
                self.check(v, scope)
            return None
        given = {n for n, _ in e.fields}
        missing = [n for n, _ in expected.fields if n not in given]
        seen: set[str] = set()
        for n, v in e.fields:
            ft = expected.field(n)
            if n in seen:
                self.bag.error("E207", f"field '{n}' is given twice", v.span)
            seen.add(n)
            if ft is None:
                guess = did_you_mean(n, missing)
                if guess is not None:
                    missing.remove(guess)  # a misspelling: one report, not two
                self.bag.error("E207", f"record {expected.name} has no field '{n}'", v.span,
                               f"did you mean '{guess}'?" if guess else
                               "its fields are: " + ", ".join(f for f, _ in expected.fields))
                self.check(v, scope)
                continue
            self.expect(v, scope, ft, f"field '{n}'")
        if missing:
            self.bag.error("E207", f"record {expected.name} literal misses " + ", ".join(missing),
                           e.span)
        return expected

    def _Call(self, e: ast.Call, scope: Scope, expected: Type | None) -> Type | None:
        if e.function == "new":
            return self._new(e, scope)
        ext = scope.externs.get(e.function)
        if ext is not None:
            if scope.no_calls is not None:
                self.bag.error("E215", f"external operation {e.function}() cannot be called "
                               f"in {scope.no_calls}", e.span,
                               "initial values and constants are computed before the run, "
                               "without Python: compute it in the first iteration (`update "
                               "memory`), or write the value")
            if len(e.args) != len(ext.params):
                self.bag.error("E204", f"{e.function}() takes {len(ext.params)} argument(s), "
                               f"{len(e.args)} given", e.span, related=())
            for arg, (pname, ptype) in zip(e.args, ext.params, strict=False):
                self.expect(arg, scope, ptype, f"argument '{pname}' of {e.function}()")
            return ext.result
        if e.function in BUILTIN_FUNCTIONS:
            return self._builtin(e, scope)
        sym = scope.lookup(e.function)
        if sym is not None and sym.kind == "extern":  # declared, but its signature is broken
            for a in e.args:
                self.check(a, scope)
            return None
        guess = did_you_mean(e.function, [*scope.externs, *BUILTIN_FUNCTIONS])
        self.bag.error("E102", f"function '{e.function}' is not declared", e.function_span,
                       f"did you mean '{guess}'?" if guess else
                       "declare it with `extern NAME(...) -> TYPE = \"module:function\"`")
        for a in e.args:
            self.check(a, scope)
        return None

    def _new(self, e: ast.Call, scope: Scope) -> Type | None:
        if not scope.new_allowed:
            self.bag.error("E505", "new() is only meaningful in the condition of a `case`",
                           e.span, "data availability is chosen by `case new(x): ...`")
            return BOOL
        if len(e.args) != 1 or not isinstance(e.args[0], ast.Name):
            self.bag.error("E503", "new() takes the name of one input buffer", e.span)
            return BOOL
        name = e.args[0].name
        sym = scope.lookup(name)
        if sym is not None and sym.kind == "input" and sym.type is None:
            return BOOL  # an input whose type is unknown (already reported)
        if name not in scope.inputs:
            self.bag.error("E503", f"new({name}): '{name}' is not an input buffer of this "
                           "subsystem", e.args[0].span,
                           "inputs: " + (", ".join(scope.inputs) or "none"))
        scope.reads.add(name)
        return BOOL

    def _builtin(self, e: ast.Call, scope: Scope) -> Type | None:
        f, args = e.function, e.args
        arity = {"atan2": 2, "min": 2, "max": 2, "clamp": 3, "dot": 2, "cross": 2}.get(f, 1)
        if len(args) != arity:
            self.bag.error("E204", f"{f}() takes {arity} argument(s), {len(args)} given", e.span)
            return None
        types = [self.check(a, scope) for a in args]
        if any(t is None for t in types):
            return None
        if f in ("norm", "dot", "cross"):
            for a, t in zip(args, types, strict=True):
                if not is_numeric_array(t):  # type: ignore[arg-type]
                    self.bag.error("E201", f"{f}() needs numeric arrays, not {t}", a.span)
                    return None
            if f == "cross" and any(t.size != 3 for t in types):  # type: ignore[union-attr]
                self.bag.error("E201", "cross() needs two float[3]", e.span)
            return ArrayT(FLOAT, 3) if f == "cross" else FLOAT
        for a, t in zip(args, types, strict=True):
            if not is_numeric(t):  # type: ignore[arg-type]
                self.bag.error("E201", f"{f}() needs numbers, not {t}", a.span)
                return None
        if f in ("abs", "min", "max", "clamp") and all(is_int(t) for t in types):  # type: ignore[arg-type]
            return INT
        return FLOAT

    # ------------------------------------------------------------ statements
    def root_name(self, target: ast.Expr) -> ast.Name | None:
        while isinstance(target, ast.FieldAccess | ast.Index):
            target = target.value
        return target if isinstance(target, ast.Name) else None


def mismatch_hint(got: Type, want: Type) -> str:
    """What to do about a value of type ``got`` where ``want`` is needed (E201)."""
    if want == BOOL:
        return ("write a condition: a comparison (`x > 0`, `mode == Mode.ready`), or "
                f"`and`/`or`/`not` of conditions; a {got} is not a bool")
    if got == BOOL:
        return f"a bool is not a number: write `if COND then A else B` to get a {want}"
    if got == FLOAT and (want == INT or isinstance(want, RangeT)):
        return ("there is no conversion from float to int (`floor` and `ceil` return floats): "
                "compute the value in ints, or declare the target float")
    if isinstance(want, EnumT) or isinstance(got, EnumT):
        return (f"write a value of the declared type ({want}), e.g. a member `Type.member` of "
                "an enum, or change the declaration")
    return f"write a value of type {want}, or change the declaration"
