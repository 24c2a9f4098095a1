"""Build the AST while Lark parses: every grammar rule's callback makes an AST node.

The callbacks run on each LALR reduction (no parse tree is built, nothing recurses), and
each node's span runs from its first to its last token (keywords the grammar drops are not
part of it). Nesting deeper than MAX_DEPTH is refused (E008) so that later passes, which
recurse over expressions, never hit Python's recursion limit."""

from __future__ import annotations

import threading
from dataclasses import dataclass
from typing import Any, TypeVar

from lark import Token

from rssm_core.modes import Mode
from rssm_dsl.source import SourceFile, Span
from rssm_dsl.syntax import ast

MAX_DEPTH = 64
N = TypeVar("N")


@dataclass(frozen=True, slots=True)
class _Node:
    """What a rule callback knows about its rule besides the children: the span."""

    span: Span


@dataclass(frozen=True, slots=True)
class _Prefixed:
    """An operand with prefix operators (`-`, `not`), resolved by the enclosing chain."""

    prefixes: tuple[Token, ...]
    operand: Any


@dataclass(frozen=True, slots=True)
class _Operand:
    expr: Any


# binding power of binary operators; `not` takes comparisons and tighter, `-` only an operand
_BINARY = {"or": 1, "and": 2, "==": 4, "!=": 4, "<": 4, "<=": 4, ">": 4, ">=": 4,
           "+": 5, "-": 5, "*": 6, "/": 6, "%": 6}
_PREFIX = {"not": 4, "-": 7}


class _Climber:
    """Precedence climbing over a chain `prefix* operand (op prefix* operand)*`."""

    def __init__(self, builder: AstBuilder, stream: list[Any]) -> None:
        self.b = builder
        self.stream = stream
        self.i = 0

    def parse(self, min_prec: int) -> Any:
        item = self.stream[self.i]
        self.i += 1
        if isinstance(item, _Operand):
            left = item.expr
        else:
            op = str(item)
            operand = self.parse(_PREFIX[op])
            span = self.b._tok(item).to(operand.span)
            left = self.b._deep(ast.Unary(span, op, operand), [operand], span)
        while self.i < len(self.stream):
            tok = self.stream[self.i]
            prec = _BINARY[str(tok)]
            if prec < min_prec:
                break
            self.i += 1
            right = self.parse(prec + 1)
            span = left.span.to(right.span)
            left = self.b._deep(ast.Binary(span, str(tok), left, right), [left, right], span)
        return left


class NestingTooDeep(Exception):
    def __init__(self, span: Span, limit: int) -> None:
        super().__init__(f"nesting deeper than {limit}")
        self.span = span
        self.limit = limit


def _unquote(s: str) -> str:
    body = s[1:-1]
    return body.encode("utf-8").decode("unicode_escape") if "\\" in body else body


class AstBuilder:
    def __init__(self, source: SourceFile) -> None:
        self.source = source
        self._depth: dict[int, int] = {}

    # ------------------------------------------------------------- helpers
    @staticmethod
    def _span(t: _Node) -> Span:
        return t.span

    def _tok(self, tok: Token) -> Span:
        if tok.line is None or tok.start_pos is None:
            start = tok.start_pos or 0
            return self.source.span(start, tok.end_pos if tok.end_pos is not None else start)
        column = tok.column or 1
        return Span(self.source.path, tok.line, column, tok.end_line or tok.line,
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
        depth = 1 + max((self._depth.get(id(c), 0) for c in children), default=0)
        if depth > MAX_DEPTH:
            raise NestingTooDeep(span, MAX_DEPTH)
        self._depth[id(node)] = depth
        return node

    # ------------------------------------------------------------- module level
    def r_start(self, t: _Node, k: list[Any]) -> ast.Module:
        imports = tuple(x for x in k if isinstance(x, ast.Import))
        decls = tuple(x for x in k if not isinstance(x, ast.Import))
        return ast.Module(self._span(t), self.source.path, imports, decls)

    def r_import_decl(self, t: _Node, k: list[Any]) -> ast.Import:
        path, quoted, _ = k[0]
        return ast.Import(self._span(t), path, quoted)

    def r_dotted_path(self, t: _Node, k: list[Any]) -> tuple[str, bool, Span]:
        return ".".join(str(x) for x in k), False, self._span(t)

    def r_string_path(self, t: _Node, k: list[Any]) -> tuple[str, bool, Span]:
        return _unquote(str(k[0])), True, self._span(t)

    def r_record_decl(self, t: _Node, k: list[Any]) -> ast.RecordDecl:
        return ast.RecordDecl(self._span(t), str(k[0]), self._tok(k[0]), tuple(k[1:]))

    def r_field_decl(self, t: _Node, k: list[Any]) -> ast.FieldDecl:
        return ast.FieldDecl(self._span(t), str(k[0]), k[1])

    def r_alias_decl(self, t: _Node, k: list[Any]) -> ast.AliasDecl:
        return ast.AliasDecl(self._span(t), str(k[0]), self._tok(k[0]), k[1])

    def r_enum_decl(self, t: _Node, k: list[Any]) -> ast.EnumDecl:
        members = tuple(x for x in k[1:] if isinstance(x, ast.EnumMember))
        return ast.EnumDecl(self._span(t), str(k[0]), self._tok(k[0]), members)

    def r_enum_member(self, t: _Node, k: list[Any]) -> ast.EnumMember:
        return ast.EnumMember(self._tok(k[0]), str(k[0]))

    def r_named_type(self, t: _Node, k: list[Any]) -> ast.NamedType:
        return ast.NamedType(self._span(t), str(k[0]))

    def r_range_bound(self, t: _Node, k: list[Any]) -> tuple[int, Span]:
        value = int(k[-1])
        return (-value if len(k) > 1 else value), self._span(t)

    def r_range_type(self, t: _Node, k: list[Any]) -> ast.RangeType:
        return ast.RangeType(self._span(t), k[0][0], k[1][0])

    def r_array_type(self, t: _Node, k: list[Any]) -> ast.ArrayType:
        return self._deep(ast.ArrayType(self._span(t), k[0], int(k[1])), k, self._span(t))

    def r_const_decl(self, t: _Node, k: list[Any]) -> ast.ConstDecl:
        return ast.ConstDecl(self._span(t), str(k[0]), self._tok(k[0]), k[1], k[2])

    def r_extern_decl(self, t: _Node, k: list[Any]) -> ast.ExternDecl:
        params = tuple(x for x in k[1:-2] if isinstance(x, ast.Param))
        return ast.ExternDecl(self._span(t), str(k[0]), self._tok(k[0]), params, k[-2],
                              _unquote(str(k[-1])), self._tok(k[-1]))

    def r_param(self, t: _Node, k: list[Any]) -> ast.Param:
        return ast.Param(self._span(t), str(k[0]), k[1])

    # ------------------------------------------------------------- devices
    def r_device_kind(self, t: _Node, k: list[Any]) -> ast.DeviceKind:
        return ast.DeviceKind(str(k[0]))

    def r_device_decl(self, t: _Node, k: list[Any]) -> ast.DeviceDecl:
        items = k[3:]
        bindings = [x for x in items if isinstance(x, ast.BindingDecl)]
        return ast.DeviceDecl(
            self._span(t), k[0], str(k[1]), self._tok(k[1]), k[2],
            tuple(x for x in items if isinstance(x, ast.BufferDecl)),
            tuple(x for x in items if isinstance(x, ast.ParamDecl)),
            bindings[0] if bindings else None,
        )

    def r_binding_decl(self, t: _Node, k: list[Any]) -> ast.BindingDecl:
        return ast.BindingDecl(self._span(t), _unquote(str(k[0])))

    # ------------------------------------------------------------- structure
    def r_system_decl(self, t: _Node, k: list[Any]) -> ast.SystemDecl:
        items = k[1:]
        return ast.SystemDecl(self._span(t), str(k[0]), self._tok(k[0]),
                              tuple(x for x in items if isinstance(x, ast.AgentDecl)),
                              tuple(x for x in items if isinstance(x, ast.PropertyDecl)))

    def r_property_always(self, t: _Node, k: list[Any]) -> ast.PropertyDecl:
        return ast.PropertyDecl(self._span(t), str(k[0]), self._tok(k[0]), "always", k[1],
                                None, None)

    def r_property_response(self, t: _Node, k: list[Any]) -> ast.PropertyDecl:
        return ast.PropertyDecl(self._span(t), str(k[0]), self._tok(k[0]), "response", None,
                                k[1], k[2])

    def r_agent_decl(self, t: _Node, k: list[Any]) -> ast.AgentDecl:
        items = k[1:]
        return ast.AgentDecl(
            self._span(t), str(k[0]), self._tok(k[0]),
            tuple(x for x in items if isinstance(x, ast.SubsystemDecl)),
            tuple(x for x in items if isinstance(x, ast.DeviceInstance)),
        )

    def r_subsystem_kind(self, t: _Node, k: list[Any]) -> tuple[ast.SubsystemKind, Span]:
        return ast.SubsystemKind(str(k[0])), self._tok(k[0])

    def r_subsystem_decl(self, t: _Node, k: list[Any]) -> ast.SubsystemDecl:
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

    def r_device_instance(self, t: _Node, k: list[Any]) -> ast.DeviceInstance:
        return ast.DeviceInstance(self._span(t), k[0], str(k[1]), self._tok(k[1]), str(k[2]),
                                  self._tok(k[2]), k[4], k[3] or ())

    def r_device_args(self, t: _Node, k: list[Any]) -> tuple[ast.DeviceArg, ...]:
        return tuple(a for a in k if a is not None)

    def r_device_arg(self, t: _Node, k: list[Any]) -> ast.DeviceArg:
        return ast.DeviceArg(self._span(t), str(k[0]), self._tok(k[0]), k[1])

    def r_frequency(self, t: _Node, k: list[Any]) -> ast.Frequency:
        value = k[0].value
        unit = str(k[1])
        return ast.Frequency(self._span(t), float(value) * (1000.0 if unit == "kHz" else 1.0))

    def r_freq_unit(self, t: _Node, k: list[Any]) -> Token:
        unit: Token = k[0]  # the token (a str) keeps its position for the frequency's span
        return unit

    def r_memory_decl(self, t: _Node, k: list[Any]) -> ast.MemoryDecl:
        return ast.MemoryDecl(self._span(t), str(k[0]), self._tok(k[0]), k[1], k[2])

    def r_param_decl(self, t: _Node, k: list[Any]) -> ast.ParamDecl:
        return ast.ParamDecl(self._span(t), str(k[0]), self._tok(k[0]), k[1], k[2])

    def r_direction(self, t: _Node, k: list[Any]) -> ast.Direction:
        return ast.Direction(str(k[0]))

    def r_peer_arrow(self, t: _Node, k: list[Any]) -> tuple[str, Span]:
        return str(k[0]), self._tok(k[0])

    def r_mode(self, t: _Node, k: list[Any]) -> tuple[Mode, Span]:
        return Mode(str(k[0])), self._tok(k[0])

    def r_peer(self, t: _Node, k: list[Any]) -> ast.PeerRef:
        return ast.PeerRef(self._span(t), tuple(str(x) for x in k))

    def r_buffer_decl(self, t: _Node, k: list[Any]) -> ast.BufferDecl:
        direction, name, type_, arrow, peer, mode, init = k
        return ast.BufferDecl(
            self._span(t), direction, str(name), self._tok(name), type_,
            peer, mode[0] if mode else None, mode[1] if mode else None, init, arrow,
        )

    # ------------------------------------------------------------- behaviours
    def r_behaviour_decl(self, t: _Node, k: list[Any]) -> ast.BehaviourDecl:
        items = k[1:]
        sends = tuple(x[1] for x in items if isinstance(x, tuple) and x[0] == "send")
        receives = tuple(x[1] for x in items if isinstance(x, tuple) and x[0] == "receive")
        return ast.BehaviourDecl(
            self._span(t), str(k[0]), self._tok(k[0]),
            tuple(x for x in items if isinstance(x, ast.UpdateDecl)),
            tuple(x for x in items if isinstance(x, ast.ConditionDecl)),
            sends, receives,
        )

    def r_update_target(self, t: _Node, k: list[Any]) -> Token:
        tok: Token = k[0]
        return tok

    def r_update_plain(self, t: _Node, k: list[Any]) -> ast.UpdateDecl:
        span = self._span(t)
        return ast.UpdateDecl(span, str(k[0]), self._tok(k[0]),
                              (ast.Case(span, None, tuple(k[1:])),), True)

    def r_update_cases(self, t: _Node, k: list[Any]) -> ast.UpdateDecl:
        return ast.UpdateDecl(self._span(t), str(k[0]), self._tok(k[0]), tuple(k[1:]), False)

    def r_case(self, t: _Node, k: list[Any]) -> ast.Case:
        return ast.Case(self._span(t), k[0], tuple(k[1:]))

    def r_otherwise(self, t: _Node, k: list[Any]) -> ast.Case:
        return ast.Case(self._span(t), None, tuple(k))

    def r_condition_kind(self, t: _Node, k: list[Any]) -> str:
        return str(k[0])

    def r_condition_decl(self, t: _Node, k: list[Any]) -> ast.ConditionDecl:
        return ast.ConditionDecl(self._span(t), k[0], str(k[1]), self._tok(k[1]), k[2])

    def r_send_decl(self, t: _Node, k: list[Any]) -> tuple[str, ast.Arrangement]:
        return "send", k[0]

    def r_receive_decl(self, t: _Node, k: list[Any]) -> tuple[str, ast.Arrangement]:
        return "receive", k[0]

    def r_arr_seq(self, t: _Node, k: list[Any]) -> ast.ArrSeq:
        span = self._span(t)
        return self._deep(ast.ArrSeq(span, tuple(k)), k, span)

    def r_arr_par(self, t: _Node, k: list[Any]) -> ast.ArrPar:
        span = self._span(t)
        return self._deep(ast.ArrPar(span, tuple(k)), k, span)

    def r_arr_buffer(self, t: _Node, k: list[Any]) -> ast.ArrBuffer:
        return ast.ArrBuffer(self._span(t), str(k[0]))

    def r_initial_decl(self, t: _Node, k: list[Any]) -> ast.InitialDecl:
        return ast.InitialDecl(self._span(t), str(k[0]), self._tok(k[0]))

    def r_switch_when(self, t: _Node, k: list[Any]) -> ast.SwitchDecl:
        return ast.SwitchDecl(self._span(t), str(k[0]), self._tok(k[0]), str(k[1]),
                              self._tok(k[1]), k[2])

    def r_switch_otherwise(self, t: _Node, k: list[Any]) -> ast.SwitchDecl:
        return ast.SwitchDecl(self._span(t), str(k[0]), self._tok(k[0]), str(k[1]),
                              self._tok(k[1]), None)

    # ------------------------------------------------------------- statements
    def r_assign(self, t: _Node, k: list[Any]) -> ast.Assign:
        return ast.Assign(self._span(t), k[0], k[1])

    def r_let(self, t: _Node, k: list[Any]) -> ast.Let:
        return ast.Let(self._span(t), str(k[0]), k[1])

    def r_skip(self, t: _Node, k: list[Any]) -> ast.Skip:
        return ast.Skip(self._span(t))

    def r_lvalue(self, t: _Node, k: list[Any]) -> ast.Expr:
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

    def r_lv_field(self, t: _Node, k: list[Any]) -> tuple[str, Any, Span]:
        return "field", str(k[0]), self._span(t)

    def r_lv_index(self, t: _Node, k: list[Any]) -> tuple[str, Any, Span]:
        return "index", k[0], self._span(t)

    # ------------------------------------------------------------- expressions
    def _expr(self, node: ast.Expr, children: list[Any]) -> ast.Expr:
        return self._deep(node, children, node.span)  # type: ignore[no-any-return]

    def r_if_expr(self, t: _Node, k: list[Any]) -> ast.Expr:
        return self._expr(ast.IfExpr(self._span(t), k[0], k[1], k[2]), k)

    def r_chain(self, t: _Node, k: list[Any]) -> ast.Expr:
        if len(k) == 1 and not isinstance(k[0], _Prefixed):
            return k[0]  # type: ignore[no-any-return]
        stream: list[Any] = []
        for i, item in enumerate(k):
            if i % 2:
                if not (isinstance(item, Token) and str(item) in _BINARY):
                    return k[0]  # type: ignore[no-any-return]  # debris of error recovery
                stream.append(item)  # a binary operator token
            elif isinstance(item, _Prefixed):
                if len(item.prefixes) > MAX_DEPTH:
                    raise NestingTooDeep(self._tok(item.prefixes[0]), MAX_DEPTH)
                stream.extend(item.prefixes)
                stream.append(_Operand(item.operand))
            else:
                stream.append(_Operand(item))
        result: ast.Expr = _Climber(self, stream).parse(0)
        return result

    def r_prefixed(self, t: _Node, k: list[Any]) -> _Prefixed:
        # only operator tokens precede the operand (error recovery may leave other debris)
        prefixes = tuple(x for x in k[:-1] if isinstance(x, Token) and str(x) in _PREFIX)
        return _Prefixed(prefixes, k[-1])

    def r_field(self, t: _Node, k: list[Any]) -> ast.Expr:
        return self._expr(ast.FieldAccess(self._span(t), k[0], str(k[1])), k)

    def r_index(self, t: _Node, k: list[Any]) -> ast.Expr:
        return self._expr(ast.Index(self._span(t), k[0], k[1]), k)

    def r_in_behaviour(self, t: _Node, k: list[Any]) -> ast.Expr:
        return self._expr(ast.InBehaviour(self._span(t), k[0], str(k[1]), self._tok(k[1])), k)

    def r_call(self, t: _Node, k: list[Any]) -> ast.Expr:
        args = [a for a in k[1:] if a is not None]
        return self._expr(ast.Call(self._span(t), str(k[0]), self._tok(k[0]), tuple(args)), args)

    def r_number(self, t: _Node, k: list[Any]) -> ast.Expr:
        tok: Token = k[0]
        value: int | float = int(tok) if tok.type == "INT" else float(tok)
        return ast.Literal(self._tok(tok), value)

    def r_true(self, t: _Node, k: list[Any]) -> ast.Expr:
        return ast.Literal(self._span(t), True)

    def r_false(self, t: _Node, k: list[Any]) -> ast.Expr:
        return ast.Literal(self._span(t), False)

    def r_name(self, t: _Node, k: list[Any]) -> ast.Expr:
        return ast.Name(self._tok(k[0]), str(k[0]))

    def r_array_lit(self, t: _Node, k: list[Any]) -> ast.Expr:
        items = [x for x in k if x is not None]
        return self._expr(ast.ArrayLit(self._span(t), tuple(items)), items)

    def r_record_lit(self, t: _Node, k: list[Any]) -> ast.Expr:
        return self._expr(ast.RecordLit(self._span(t), tuple(k)), [v for _, v in k])

    def r_field_init(self, t: _Node, k: list[Any]) -> tuple[str, ast.Expr]:
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
            builder: AstBuilder = _current.builder
            return method(builder, _Node(builder.children_span(children)), children)

        return callback


def building(builder: AstBuilder) -> None:
    """Make `builder` receive the callbacks of the parses this thread runs next."""
    _current.builder = builder
