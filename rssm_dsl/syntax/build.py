"""Build the AST while Lark parses: every grammar rule's callback makes an AST node.

The callbacks run on each LALR reduction (no parse tree is built, nothing recurses), and
each node's span runs from its first to its last token (keywords the grammar drops are not
part of it). Nesting deeper than MAX_DEPTH is refused (E008) so that later passes, which
recurse over expressions, never hit Python's recursion limit (the parser reports most of it
earlier, as the tokens come: parser._Nesting). A number literal the compiler cannot read,
too long or too large for its type, is reported at the literal (E013, see problems())."""

from __future__ import annotations

import codecs
import re
import threading
import warnings
from collections.abc import Callable
from dataclasses import fields
from typing import Any, TypeVar

from lark import Token

from rssm_core.modes import Mode
from rssm_core.records import dataclass
from rssm_core.values import INT_MAX, INT_MIN
from rssm_dsl.diagnostics import Diagnostic
from rssm_dsl.source import SourceFile, Span
from rssm_dsl.syntax import ast

MAX_DEPTH = 64
# The longest number literals read (E013): an int has at most the digits of the largest
# int (leading zeros aside); a float literal at most MAX_NUMBER_CHARS characters.
MAX_INT_DIGITS = len(str(INT_MAX))
MAX_NUMBER_CHARS = 400
_INT_RANGE = f"from {INT_MIN} to {INT_MAX}"
N = TypeVar("N")


@dataclass(frozen=True, slots=True)
class _Prefixed:
    """An operand with prefix operators (`-`, `not`), resolved by the enclosing chain."""

    prefixes: tuple[Token, ...]
    operand: Any


# binding power of binary operators; `not` takes comparisons and tighter, `-` only an operand
# (the parser's early E008 check, parser._Nesting, climbs with these too)
BINARY_PRECEDENCE = {"or": 1, "and": 2, "==": 4, "!=": 4, "<": 4, "<=": 4, ">": 4, ">=": 4,
                     "+": 5, "-": 5, "*": 6, "/": 6, "%": 6}
PREFIX_PRECEDENCE = {"not": 4, "-": 7}


# ------------------------------------------------------------- nodes made by the million
# A frozen dataclass's __init__ sets each field through object.__setattr__, which looks the
# name up first; the objects a long chain of arithmetic makes by the million (spans, number
# literals, binary operations) are made here by setting their slots with the slots' own
# descriptors: the same objects, made in half the time. A class whose fields are not the
# ones expected here (or which has a __post_init__) is made by its __init__.

_new = object.__new__


def _slot_setters(cls: type, names: tuple[str, ...]) -> tuple[Callable[[Any, Any], None], ...]:
    if tuple(f.name for f in fields(cls)) != names or hasattr(cls, "__post_init__"):
        return ()
    return tuple(getattr(cls, name).__set__ for name in names)


def _span_makers() -> tuple[Callable[[str, int, int, int, int, int, int], Span],
                            Callable[[Span, Span], Span]]:
    """Span(...), and a.to(b)."""
    setters = _slot_setters(Span, ("file", "line", "column", "end_line", "end_column",
                                   "offset", "end_offset"))
    if not setters:
        return Span, Span.to
    set_file, set_line, set_column, set_end_line, set_end_column, set_offset, set_end = setters

    def make(file: str, line: int, column: int, end_line: int, end_column: int,
             offset: int, end_offset: int) -> Span:
        span = _new(Span)
        set_file(span, file)
        set_line(span, line)
        set_column(span, column)
        set_end_line(span, end_line)
        set_end_column(span, end_column)
        set_offset(span, offset)
        set_end(span, end_offset)
        return span

    def to(a: Span, b: Span) -> Span:
        span = _new(Span)
        set_file(span, a.file)
        set_line(span, a.line)
        set_column(span, a.column)
        set_end_line(span, b.end_line)
        set_end_column(span, b.end_column)
        set_offset(span, a.offset)
        set_end(span, b.end_offset)
        return span

    return make, to


def _literal_maker() -> Callable[[Span, bool | int | float], ast.Literal]:
    setters = _slot_setters(ast.Literal, ("span", "value"))
    if not setters:
        return ast.Literal
    set_span, set_value = setters

    def make(span: Span, value: bool | int | float) -> ast.Literal:
        node = _new(ast.Literal)
        set_span(node, span)
        set_value(node, value)
        return node

    return make


def _binary_maker() -> Callable[[Span, str, ast.Expr, ast.Expr], ast.Binary]:
    setters = _slot_setters(ast.Binary, ("span", "op", "left", "right"))
    if not setters:
        return ast.Binary
    set_span, set_op, set_left, set_right = setters

    def make(span: Span, op: str, left: ast.Expr, right: ast.Expr) -> ast.Binary:
        node = _new(ast.Binary)
        set_span(node, span)
        set_op(node, op)
        set_left(node, left)
        set_right(node, right)
        return node

    return make


_make_span, _span_to = _span_makers()
_make_literal = _literal_maker()
_make_binary = _binary_maker()


class NestingTooDeep(Exception):
    def __init__(self, span: Span, limit: int, message: str | None = None) -> None:
        self.message = message or f"nesting deeper than {limit} levels"
        super().__init__(self.message)
        self.span = span
        self.limit = limit


# An escape of a string: those of Python's strings (docs/language.md, "Lexical structure")
_ESCAPE = re.compile(r"\\(x[0-9a-fA-F]{2}|u[0-9a-fA-F]{4}|U[0-9a-fA-F]{8}|N\{[^}]*\}|[0-7]{1,3}"
                     r"|[\\'\"abfnrtv]|.)")


class AstBuilder:
    def __init__(self, source: SourceFile) -> None:
        self.source = source
        # id of a node -> (the node, kept alive so that its id is not reused; its depth)
        self._depth: dict[int, tuple[object, int]] = {}
        self._problems: dict[int, Diagnostic] = {}   # by offset (trial parses repeat)

    def problems(self) -> list[Diagnostic]:
        """The literals that could not be read (E013, E005), in the order of the text."""
        return [self._problems[k] for k in sorted(self._problems)]

    # ------------------------------------------------------------- helpers
    def _span(self, t: list[Any]) -> Span:
        """The span of a rule: from its first child's to its last's (those with a span)."""
        return self.children_span(t)

    def _tok(self, tok: Token) -> Span:
        if tok.line is None or tok.start_pos is None:
            start = tok.start_pos or 0
            return self.source.span(start, tok.end_pos if tok.end_pos is not None else start)
        column = tok.column or 1
        return _make_span(self.source.path, tok.line, column, tok.end_line or tok.line,
                          tok.end_column or column, tok.start_pos, tok.end_pos or tok.start_pos)

    def _span_of(self, c: Any) -> Span | None:
        if isinstance(c, Token):
            return self._tok(c)
        if isinstance(c, Span):
            return c
        if isinstance(c, tuple):  # what a rule returns as several values: span them all
            spans = [s for s in map(self._span_of, c) if s is not None]
            return spans[0].to(spans[-1]) if spans else None
        span = getattr(c, "span", None)
        return span if isinstance(span, Span) else None

    def children_span(self, children: list[Any]) -> Span:
        first: Span | None = None
        last: Span | None = None
        for c in children:
            sp = self._span_of(c)
            if sp is None:
                continue
            if first is None:
                first = sp
            last = sp
        if first is None or last is None:
            return self.source.span(0, 0)
        return first.to(last)

    def _deep(self, node: N, children: list[Any], span: Span) -> N:
        depths = self._depth
        depth = 1
        for c in children:
            known = depths.get(id(c))
            if known is not None and known[1] >= depth:
                depth = known[1] + 1
        if depth > MAX_DEPTH:
            raise NestingTooDeep(span, MAX_DEPTH)
        depths[id(node)] = (node, depth)
        return node

    # ------------------------------------------------------------- literals
    def _problem(self, code: str, message: str, span: Span, hint: str) -> None:
        self._problems[span.offset] = Diagnostic(code, message, span, hint)

    def _too_large(self, tok: Token, message: str, hint: str) -> None:
        self._problem("E013", message, self._tok(tok), hint)

    def _string(self, tok: Token) -> str:
        """The text of a STRING token, its escapes replaced (an unknown or malformed one is
        E005 at the escape, and stands for itself)."""
        body = str(tok)[1:-1]
        if "\\" not in body:
            return body

        def escape(m: re.Match[str]) -> str:
            try:
                with warnings.catch_warnings():
                    warnings.simplefilter("error")     # an unknown escape only warns
                    return codecs.decode(m.group(), "unicode_escape")
            except (UnicodeDecodeError, DeprecationWarning):
                pass
            if tok.start_pos is not None:
                at = tok.start_pos + 1 + m.start()
                self._problem("E005", f"unknown escape '{m.group()[:12]}' in a string",
                              self.source.span(at, at + len(m.group())),
                              'a string\'s escapes are those of Python: \\", \\\\, \\n, '
                              "\\t, \\x41, \\u00e9, ...")
            return m.group(1)

        return _ESCAPE.sub(escape, body)

    def _int(self, tok: Token) -> int:
        """The value of an INT token; 0 (and E013) when it has more digits than an int."""
        digits = str(tok).lstrip("0")
        if len(digits) > MAX_INT_DIGITS:
            self._too_large(tok, f"integer literal of {len(digits)} digits is too large for "
                            "int, a 64-bit integer",
                            f"an int is {_INT_RANGE} ({MAX_INT_DIGITS} digits); write a "
                            "float (e.g. 1e30) for a larger number")
            return 0
        return int(digits or "0")

    def _float(self, tok: Token) -> float:
        """The value of a FLOAT token; 0.0 (and E013) when it is too long to be read or
        too large for a float."""
        text = str(tok)
        if len(text) > MAX_NUMBER_CHARS:
            self._too_large(tok, f"number literal of {len(text)} characters: the compiler "
                            f"reads at most {MAX_NUMBER_CHARS}",
                            "a float has 17 significant digits: write it with fewer")
            return 0.0
        value = float(text)
        if value == float("inf"):
            shown = text if len(text) <= 40 else text[:39] + "…"
            self._too_large(tok, f"number {shown} is too large for a float (a 64-bit IEEE 754 "
                            "number)", "the largest float is about 1.8e308")
            return 0.0
        return value

    # ------------------------------------------------------------- module level
    def r_start(self, t: list[Any], k: list[Any]) -> ast.Module:
        imports = tuple(x for x in k if isinstance(x, ast.Import))
        decls = tuple(x for x in k if not isinstance(x, ast.Import))
        return ast.Module(self._span(t), self.source.path, imports, decls)

    def r_import_decl(self, t: list[Any], k: list[Any]) -> ast.Import:
        path, quoted, _ = k[0]
        return ast.Import(self._span(t), path, quoted)

    def r_dotted_path(self, t: list[Any], k: list[Any]) -> tuple[str, bool, Span]:
        return ".".join(str(x) for x in k), False, self._span(t)

    def r_string_path(self, t: list[Any], k: list[Any]) -> tuple[str, bool, Span]:
        return self._string(k[0]), True, self._span(t)

    def r_record_decl(self, t: list[Any], k: list[Any]) -> ast.RecordDecl:
        return ast.RecordDecl(self._span(t), str(k[0]), self._tok(k[0]), tuple(k[1:]))

    def r_field_decl(self, t: list[Any], k: list[Any]) -> ast.FieldDecl:
        return ast.FieldDecl(self._span(t), str(k[0]), k[1])

    def r_alias_decl(self, t: list[Any], k: list[Any]) -> ast.AliasDecl:
        return ast.AliasDecl(self._span(t), str(k[0]), self._tok(k[0]), k[1])

    def r_enum_decl(self, t: list[Any], k: list[Any]) -> ast.EnumDecl:
        members = tuple(x for x in k[1:] if isinstance(x, ast.EnumMember))
        return ast.EnumDecl(self._span(t), str(k[0]), self._tok(k[0]), members)

    def r_enum_member(self, t: list[Any], k: list[Any]) -> ast.EnumMember:
        return ast.EnumMember(self._tok(k[0]), str(k[0]))

    def r_named_type(self, t: list[Any], k: list[Any]) -> ast.NamedType:
        return ast.NamedType(self._span(t), str(k[0]))

    def r_range_bound(self, t: list[Any], k: list[Any]) -> tuple[int, Span]:
        value = self._int(k[-1])
        return (-value if len(k) > 1 else value), self._span(t)

    def r_range_type(self, t: list[Any], k: list[Any]) -> ast.RangeType:
        return ast.RangeType(self._span(t), k[0][0], k[1][0])

    def r_array_type(self, t: list[Any], k: list[Any]) -> ast.ArrayType:
        return self._deep(ast.ArrayType(self._span(t), k[0], self._int(k[1])), k, self._span(t))

    def r_const_decl(self, t: list[Any], k: list[Any]) -> ast.ConstDecl:
        return ast.ConstDecl(self._span(t), str(k[0]), self._tok(k[0]), k[1], k[2])

    def r_extern_decl(self, t: list[Any], k: list[Any]) -> ast.ExternDecl:
        params = tuple(x for x in k[1:-2] if isinstance(x, ast.Param))
        return ast.ExternDecl(self._span(t), str(k[0]), self._tok(k[0]), params, k[-2],
                              self._string(k[-1]), self._tok(k[-1]))

    def r_param(self, t: list[Any], k: list[Any]) -> ast.Param:
        return ast.Param(self._span(t), str(k[0]), k[1])

    # ------------------------------------------------------------- devices
    def r_device_kind(self, t: list[Any], k: list[Any]) -> ast.DeviceKind:
        return ast.DeviceKind(str(k[0]))

    def r_device_decl(self, t: list[Any], k: list[Any]) -> ast.DeviceDecl:
        items = k[3:]
        bindings = [x for x in items if isinstance(x, ast.BindingDecl)]
        return ast.DeviceDecl(
            self._span(t), k[0], str(k[1]), self._tok(k[1]), k[2],
            tuple(x for x in items if isinstance(x, ast.BufferDecl)),
            tuple(x for x in items if isinstance(x, ast.ParamDecl)),
            bindings[0] if bindings else None,
        )

    def r_binding_decl(self, t: list[Any], k: list[Any]) -> ast.BindingDecl:
        return ast.BindingDecl(self._span(t), self._string(k[0]))

    # ------------------------------------------------------------- structure
    def r_system_decl(self, t: list[Any], k: list[Any]) -> ast.SystemDecl:
        items = k[1:]
        return ast.SystemDecl(self._span(t), str(k[0]), self._tok(k[0]),
                              tuple(x for x in items if isinstance(x, ast.AgentDecl)),
                              tuple(x for x in items if isinstance(x, ast.PropertyDecl)),
                              tuple(x for x in items if isinstance(x, ast.AgentInstance)))

    def r_property_always(self, t: list[Any], k: list[Any]) -> ast.PropertyDecl:
        return ast.PropertyDecl(self._span(t), str(k[0]), self._tok(k[0]), "always", k[1],
                                None, None)

    def r_property_response(self, t: list[Any], k: list[Any]) -> ast.PropertyDecl:
        return ast.PropertyDecl(self._span(t), str(k[0]), self._tok(k[0]), "response", None,
                                k[1], k[2])

    def r_agent_decl(self, t: list[Any], k: list[Any]) -> ast.AgentDecl:
        items = k[1:]
        return ast.AgentDecl(
            self._span(t), str(k[0]), self._tok(k[0]),
            tuple(x for x in items if isinstance(x, ast.SubsystemDecl)),
            tuple(x for x in items if isinstance(x, ast.DeviceInstance)),
        )

    def r_agent_def(self, t: list[Any], k: list[Any]) -> ast.AgentDef:
        items = k[2:]
        return ast.AgentDef(
            self._span(t), str(k[0]), self._tok(k[0]), k[1] or (),
            tuple(x for x in items if isinstance(x, ast.SubsystemDecl)),
            tuple(x for x in items if isinstance(x, ast.DeviceInstance)),
        )

    def r_agent_params(self, t: list[Any], k: list[Any]) -> tuple[ast.AgentParam, ...]:
        return tuple(a for a in k if a is not None)

    def r_agent_param_agent(self, t: list[Any], k: list[Any]) -> ast.AgentParam:
        return ast.AgentParam(self._span(t), str(k[0]), self._tok(k[0]), None, None)

    def r_agent_param_value(self, t: list[Any], k: list[Any]) -> ast.AgentParam:
        return ast.AgentParam(self._span(t), str(k[0]), self._tok(k[0]), k[1], k[2])

    def r_agent_instance(self, t: list[Any], k: list[Any]) -> ast.AgentInstance:
        bounds = k[1]
        return ast.AgentInstance(
            self._span(t), str(k[0]), self._tok(k[0]), str(k[2]), self._tok(k[2]), k[3] or (),
            bounds[0] if bounds is not None else None,
            bounds[1] if bounds is not None else None)

    def r_instance_range(self, t: list[Any], k: list[Any]) -> tuple[int, int]:
        return k[0][0], k[1][0]

    def r_subsystem_kind(self, t: list[Any], k: list[Any]) -> tuple[ast.SubsystemKind, Span]:
        return ast.SubsystemKind(str(k[0])), self._tok(k[0])

    def r_subsystem_decl(self, t: list[Any], k: list[Any]) -> ast.SubsystemDecl:
        (kind, kind_span), name, freq = k[0], k[1], k[2]
        items = k[3:]

        def of(cls: type[Any]) -> tuple[Any, ...]:
            return tuple(x for x in items if isinstance(x, cls))

        return ast.SubsystemDecl(
            self._span(t), kind,
            str(name) if name is not None else "c",
            self._tok(name) if name is not None else kind_span,
            freq, of(ast.MemoryDecl), of(ast.BufferDecl), of(ast.ParamDecl),
            of(ast.BehaviourDecl), of(ast.InitialDecl), of(ast.SwitchDecl),
        )

    def r_device_instance(self, t: list[Any], k: list[Any]) -> ast.DeviceInstance:
        return ast.DeviceInstance(self._span(t), k[0], str(k[1]), self._tok(k[1]), str(k[2]),
                                  self._tok(k[2]), k[4], k[3] or ())

    def r_device_args(self, t: list[Any], k: list[Any]) -> tuple[ast.DeviceArg, ...]:
        return tuple(a for a in k if a is not None)

    def r_device_arg(self, t: list[Any], k: list[Any]) -> ast.DeviceArg:
        return ast.DeviceArg(self._span(t), str(k[0]), self._tok(k[0]), k[1])

    def r_frequency(self, t: list[Any], k: list[Any]) -> ast.Frequency:
        value = k[0].value
        unit = str(k[1])
        return ast.Frequency(self._span(t), float(value) * (1000.0 if unit == "kHz" else 1.0))

    def r_freq_unit(self, t: list[Any], k: list[Any]) -> Token:
        unit: Token = k[0]  # the token (a str) keeps its position for the frequency's span
        return unit

    def r_memory_decl(self, t: list[Any], k: list[Any]) -> ast.MemoryDecl:
        return ast.MemoryDecl(self._span(t), str(k[0]), self._tok(k[0]), k[1], k[2])

    def r_param_decl(self, t: list[Any], k: list[Any]) -> ast.ParamDecl:
        return ast.ParamDecl(self._span(t), str(k[0]), self._tok(k[0]), k[1], k[2])

    def r_direction(self, t: list[Any], k: list[Any]) -> ast.Direction:
        return ast.Direction(str(k[0]))

    def r_peer_arrow(self, t: list[Any], k: list[Any]) -> tuple[str, Span]:
        return str(k[0]), self._tok(k[0])

    def r_mode(self, t: list[Any], k: list[Any]) -> tuple[Mode, Span]:
        return Mode(str(k[0])), self._tok(k[0])

    def r_peer(self, t: list[Any], k: list[Any]) -> ast.PeerRef:
        return ast.PeerRef(self._span(t), tuple(str(x) for x in k))

    def r_buffer_decl(self, t: list[Any], k: list[Any]) -> ast.BufferDecl:
        direction, name, type_, arrow, peer, mode, init = k
        return ast.BufferDecl(
            self._span(t), direction, str(name), self._tok(name), type_,
            peer, mode[0] if mode else None, mode[1] if mode else None, init, arrow,
        )

    # ------------------------------------------------------------- behaviours
    def r_behaviour_decl(self, t: list[Any], k: list[Any]) -> ast.BehaviourDecl:
        items = k[1:]
        sends = tuple(x[1] for x in items if isinstance(x, tuple) and x[0] == "send")
        receives = tuple(x[1] for x in items if isinstance(x, tuple) and x[0] == "receive")
        return ast.BehaviourDecl(
            self._span(t), str(k[0]), self._tok(k[0]),
            tuple(x for x in items if isinstance(x, ast.UpdateDecl)),
            tuple(x for x in items if isinstance(x, ast.ConditionDecl)),
            sends, receives,
        )

    def r_update_target(self, t: list[Any], k: list[Any]) -> Token:
        tok: Token = k[0]
        return tok

    def r_update_plain(self, t: list[Any], k: list[Any]) -> ast.UpdateDecl:
        span = self._span(t)
        return ast.UpdateDecl(span, str(k[0]), self._tok(k[0]),
                              (ast.Case(span, None, tuple(k[1:])),), True)

    def r_update_cases(self, t: list[Any], k: list[Any]) -> ast.UpdateDecl:
        return ast.UpdateDecl(self._span(t), str(k[0]), self._tok(k[0]), tuple(k[1:]), False)

    def r_case(self, t: list[Any], k: list[Any]) -> ast.Case:
        return ast.Case(self._span(t), k[0], tuple(k[1:]))

    def r_otherwise(self, t: list[Any], k: list[Any]) -> ast.Case:
        return ast.Case(self._span(t), None, tuple(k))

    def r_condition_kind(self, t: list[Any], k: list[Any]) -> str:
        return str(k[0])

    def r_condition_decl(self, t: list[Any], k: list[Any]) -> ast.ConditionDecl:
        return ast.ConditionDecl(self._span(t), k[0], str(k[1]), self._tok(k[1]), k[2])

    def r_send_decl(self, t: list[Any], k: list[Any]) -> tuple[str, ast.Arrangement]:
        return "send", k[0]

    def r_receive_decl(self, t: list[Any], k: list[Any]) -> tuple[str, ast.Arrangement]:
        return "receive", k[0]

    def r_arr_seq(self, t: list[Any], k: list[Any]) -> ast.ArrSeq:
        span = self._span(t)
        return self._deep(ast.ArrSeq(span, tuple(k)), k, span)

    def r_arr_par(self, t: list[Any], k: list[Any]) -> ast.ArrPar:
        span = self._span(t)
        return self._deep(ast.ArrPar(span, tuple(k)), k, span)

    def r_arr_buffer(self, t: list[Any], k: list[Any]) -> ast.ArrBuffer:
        return ast.ArrBuffer(self._span(t), str(k[0]))

    def r_initial_decl(self, t: list[Any], k: list[Any]) -> ast.InitialDecl:
        return ast.InitialDecl(self._span(t), str(k[0]), self._tok(k[0]))

    def r_switch_when(self, t: list[Any], k: list[Any]) -> ast.SwitchDecl:
        return ast.SwitchDecl(self._span(t), str(k[0]), self._tok(k[0]), str(k[1]),
                              self._tok(k[1]), k[2])

    def r_switch_otherwise(self, t: list[Any], k: list[Any]) -> ast.SwitchDecl:
        return ast.SwitchDecl(self._span(t), str(k[0]), self._tok(k[0]), str(k[1]),
                              self._tok(k[1]), None)

    # ------------------------------------------------------------- statements
    def r_assign(self, t: list[Any], k: list[Any]) -> ast.Assign:
        return ast.Assign(self._span(t), k[0], k[1])

    def r_let(self, t: list[Any], k: list[Any]) -> ast.Let:
        return ast.Let(self._span(t), str(k[0]), k[1])

    def r_skip(self, t: list[Any], k: list[Any]) -> ast.Skip:
        return ast.Skip(self._span(t))

    def r_lvalue(self, t: list[Any], k: list[Any]) -> ast.Expr:
        node: ast.Expr = ast.Name(self._tok(k[0]), str(k[0]))
        for kind, value, span in k[1:]:
            whole = node.span.to(span)
            prev = node
            if kind == "field":
                node = ast.FieldAccess(whole, prev, value)
            else:
                node = ast.Index(whole, prev, value)
            node = self._deep(node, [prev, value], whole)
        return node

    def r_lv_field(self, t: list[Any], k: list[Any]) -> tuple[str, Any, Span]:
        return "field", str(k[0]), self._span(t)

    def r_lv_index(self, t: list[Any], k: list[Any]) -> tuple[str, Any, Span]:
        return "index", k[0], self._span(t)

    # ------------------------------------------------------------- expressions
    def _expr(self, node: ast.Expr, children: list[Any]) -> ast.Expr:
        return self._deep(node, children, node.span)  # type: ignore[no-any-return]

    def r_if_expr(self, t: list[Any], k: list[Any]) -> ast.Expr:
        return self._expr(ast.IfExpr(self._span(t), k[0], k[1], k[2]), k)

    def r_chain(self, t: list[Any], k: list[Any]) -> ast.Expr:
        if len(k) == 1 and not isinstance(k[0], _Prefixed):
            return k[0]  # type: ignore[no-any-return]
        precedences = set()
        prefixed = False
        for i, item in enumerate(k):
            if i % 2:
                if not (isinstance(item, Token) and item.value in BINARY_PRECEDENCE):
                    return k[0]  # type: ignore[no-any-return]  # debris of error recovery
                precedences.add(BINARY_PRECEDENCE[item.value])
            elif isinstance(item, _Prefixed):
                if len(item.prefixes) > MAX_DEPTH:
                    raise NestingTooDeep(self._tok(item.prefixes[0]), MAX_DEPTH)
                prefixed = True
        if len(precedences) == 1 and not prefixed:
            return self._fold(k)
        return self._climb(k)

    def _fold(self, k: list[Any]) -> ast.Expr:
        """A chain of binary operators of one precedence, without prefixes (`1 + 2 - 3`):
        folded from the left, as _climb would (the same nodes, made in the same order)."""
        depths = self._depth
        binary, span_to = _make_binary, _span_to
        node = k[0]
        known = depths.get(id(node))
        depth = known[1] if known is not None else 0
        for i in range(1, len(k), 2):
            right = k[i + 1]
            known = depths.get(id(right))
            if known is not None and known[1] > depth:
                depth = known[1]
            depth += 1
            span = span_to(node.span, right.span)
            if depth > MAX_DEPTH:
                raise NestingTooDeep(span, MAX_DEPTH)
            node = binary(span, k[i].value, node, right)
        depths[id(node)] = (node, depth)
        return node  # type: ignore[no-any-return]

    def _climb(self, k: list[Any]) -> ast.Expr:
        """Precedence climbing over a chain `prefix* operand (op prefix* operand)*`, with an
        explicit stack of the operators not yet combined: the nodes are made in the order of
        the recursive algorithm (an operator is combined as soon as the next one binds less
        tightly than it, or as tightly and it is binary), so a too-deep chain is refused
        (E008) at the same node. Each node's depth is carried along; only the chain's
        result is recorded for the nodes around it (_deep)."""
        depths = self._depth
        binary, span_to = _make_binary, _span_to
        # (precedence, is prefix, operator, left operand or prefix token, its depth)
        pending: list[tuple[int, bool, str, Any, int]] = []
        node: Any = None
        depth = 0
        operand = True
        for item in k:
            if operand:
                operand = False
                if isinstance(item, _Prefixed):
                    for tok in item.prefixes:
                        pending.append((PREFIX_PRECEDENCE[tok.value], True, tok.value, tok, 0))
                    item = item.operand
                node = item
                known = depths.get(id(item))
                depth = known[1] if known is not None else 0
                continue
            operand = True
            op: str = item.value
            prec = BINARY_PRECEDENCE[op]
            while pending:
                p, is_prefix, pop, left, left_depth = pending[-1]
                if p < prec or (p == prec and is_prefix):
                    break
                del pending[-1]
                if is_prefix:
                    node, depth = self._unary(pop, left, node, depth)
                else:
                    span = span_to(left.span, node.span)
                    depth = 1 + (left_depth if left_depth > depth else depth)
                    if depth > MAX_DEPTH:
                        raise NestingTooDeep(span, MAX_DEPTH)
                    node = binary(span, pop, left, node)
            pending.append((prec, False, op, node, depth))
        while pending:
            _, is_prefix, pop, left, left_depth = pending.pop()
            if is_prefix:
                node, depth = self._unary(pop, left, node, depth)
            else:
                span = span_to(left.span, node.span)
                depth = 1 + (left_depth if left_depth > depth else depth)
                if depth > MAX_DEPTH:
                    raise NestingTooDeep(span, MAX_DEPTH)
                node = binary(span, pop, left, node)
        depths[id(node)] = (node, depth)
        return node  # type: ignore[no-any-return]

    def _unary(self, op: str, tok: Token, operand: Any, depth: int) -> tuple[ast.Unary, int]:
        span = self._tok(tok).to(operand.span)
        if depth + 1 > MAX_DEPTH:
            raise NestingTooDeep(span, MAX_DEPTH)
        return ast.Unary(span, op, operand), depth + 1

    def r_prefixed(self, t: list[Any], k: list[Any]) -> _Prefixed:
        # only operator tokens precede the operand (error recovery may leave other debris)
        prefixes = tuple(x for x in k[:-1] if isinstance(x, Token) and str(x) in PREFIX_PRECEDENCE)
        return _Prefixed(prefixes, k[-1])

    def r_field(self, t: list[Any], k: list[Any]) -> ast.Expr:
        return self._expr(ast.FieldAccess(self._span(t), k[0], str(k[1])), k)

    def r_index(self, t: list[Any], k: list[Any]) -> ast.Expr:
        return self._expr(ast.Index(self._span(t), k[0], k[1]), k)

    def r_in_behaviour(self, t: list[Any], k: list[Any]) -> ast.Expr:
        return self._expr(ast.InBehaviour(self._span(t), k[0], str(k[1]), self._tok(k[1])), k)

    def r_call(self, t: list[Any], k: list[Any]) -> ast.Expr:
        args = [a for a in k[1:] if a is not None]
        return self._expr(ast.Call(self._span(t), str(k[0]), self._tok(k[0]), tuple(args)), args)

    def r_number(self, t: list[Any], k: list[Any]) -> ast.Expr:
        tok: Token = k[0]
        value: int | float
        if tok.type != "INT":
            value = self._float(tok)
        elif len(tok.value) <= MAX_INT_DIGITS:   # (what _int reads, without its checks)
            value = int(tok.value)
        else:
            value = self._int(tok)
        return _make_literal(self._tok(tok), value)

    def r_true(self, t: list[Any], k: list[Any]) -> ast.Expr:
        return ast.Literal(self._span(t), True)

    def r_false(self, t: list[Any], k: list[Any]) -> ast.Expr:
        return ast.Literal(self._span(t), False)

    def r_name(self, t: list[Any], k: list[Any]) -> ast.Expr:
        return ast.Name(self._tok(k[0]), str(k[0]))

    def r_array_lit(self, t: list[Any], k: list[Any]) -> ast.Expr:
        items = [x for x in k if x is not None]
        return self._expr(ast.ArrayLit(self._span(t), tuple(items)), items)

    def r_record_lit(self, t: list[Any], k: list[Any]) -> ast.Expr:
        return self._expr(ast.RecordLit(self._span(t), tuple(k)), [v for _, v in k])

    def r_field_init(self, t: list[Any], k: list[Any]) -> tuple[str, ast.Expr]:
        return str(k[0]), k[1]


_current = threading.local()


class Callbacks:
    """The object Lark calls on each reduction; it forwards to the AstBuilder of the parse
    running in this thread (the Lark instance is built once and shared)."""

    def __getattr__(self, rule: str) -> Any:
        method = getattr(AstBuilder, "r_" + rule, None)
        if method is None:
            raise AttributeError(rule)

        def callback(children: list[Any]) -> Any:
            # (the children are given twice: as the rule, for its span, and as its values)
            return method(_current.builder, children, children)

        return callback


def building(builder: AstBuilder | None) -> None:
    """Make `builder` receive the callbacks of the parses this thread runs next."""
    _current.builder = builder
