"""Document symbols: the outline of a file (system > agents > subsystems > behaviours, the
system's properties, and the library declarations), from its AST (a partial one while the
text has errors). An outline has at most MAX_SYMBOLS entries (and the declarations that
enclose them): a generated file with 80,000 agents would otherwise take seconds to convert
and send, on every request."""

from __future__ import annotations

import json
import re
from collections.abc import Callable, Iterable
from typing import Any, TypeVar

from lsprotocol import types as lsp
from pygls.protocol import default_converter

from rssm_core.records import dataclass
from rssm_dsl.lsp.positions import LineIndex
from rssm_dsl.source import Span
from rssm_dsl.syntax import ast

K = lsp.SymbolKind
MAX_SYMBOLS = 10_000
X = TypeVar("X")
Symbol = dict[str, Any]      # a DocumentSymbol as JSON values


def _type_text(t: ast.TypeExpr) -> str:
    from rssm_dsl.syntax.printer import type_text
    return type_text(t)


def _same(span: Span) -> Span:
    return span


@dataclass(frozen=True)
class OutlinedAgent:
    """An agent's DocumentSymbol in JSON, made when the agent's text (`source`) started on
    line `line` at `character`."""

    agent: ast.AgentDecl
    line: int
    character: int
    source: str
    text: str
    symbols: int


# the outlined agents of a document's last outline, by id() of their AST (an incremental
# analysis keeps the AST of the agents it did not reparse)
AgentOutlines = dict[int, OutlinedAgent]
_LINE = re.compile(r'"line": (\d+)')
_MARK = re.compile(r'"\\u0000(\d+)"')


def _moved(text: str, lines: int) -> str:
    """An outlined agent's JSON with every line number moved (an agent moves as a whole
    when an edit elsewhere adds or removes lines: its columns stay)."""
    return _LINE.sub(lambda m: f'"line": {int(m.group(1)) + lines}', text)


class _Outline:
    def __init__(self, lines: LineIndex, encoding: str, file: str,
                 real: Callable[[Span], Span], known: AgentOutlines | None = None) -> None:
        self.lines = lines
        self.encoding = encoding
        self.file = file
        self.real = real
        self.left = MAX_SYMBOLS
        # with `known`: agents are outlined as JSON texts (reused from `known` when their
        # AST is the same), left in the values as marks "\0N" for texts[N]
        self.known = known
        self.outlined: AgentOutlines = {}
        self.texts: list[str] = []

    def each(self, items: Iterable[X], fn: Callable[[X], Symbol]) -> list[Symbol]:
        """fn of each item, while the outline has room."""
        out: list[Symbol] = []
        for x in items:
            if self.left <= 0:
                break
            out.append(fn(x))
        return out

    def _range(self, span: Span) -> dict[str, dict[str, int]]:
        (l0, c0), (l1, c1) = self.lines.ends_of(self.real(span), self.encoding)
        return {"start": {"line": l0, "character": c0}, "end": {"line": l1, "character": c1}}

    def sym(self, name: str, kind: lsp.SymbolKind, full: Span, sel: Span,
            detail: str | None = None, children: list[Symbol] | None = None) -> Symbol:
        self.left -= 1
        rng = self._range(full)
        sel_rng = self._range(sel)
        # the selection range must be contained in the full range
        start, end = rng["start"], rng["end"]
        if (sel_rng["start"]["line"], sel_rng["start"]["character"]) \
                < (start["line"], start["character"]) \
                or (sel_rng["end"]["line"], sel_rng["end"]["character"]) \
                > (end["line"], end["character"]):
            sel_rng = {"start": start, "end": start}
        out: Symbol = {"name": name or "_", "kind": kind.value, "range": rng,
                       "selectionRange": sel_rng}
        if detail is not None:
            out["detail"] = detail
        if children:
            out["children"] = children
        return out

    def buffer(self, b: ast.BufferDecl) -> Symbol:
        peer = f" {'to' if b.direction is ast.Direction.OUTPUT else 'from'} {b.peer}" \
            if b.peer else ""
        mode = f" {b.mode.value}" if b.mode else ""
        return self.sym(b.name, K.Field, b.span, b.name_span,
                        f"{b.direction.value}: {_type_text(b.type)}{peer}{mode}")

    def behaviour(self, bd: ast.BehaviourDecl) -> Symbol:
        kids = self.each(bd.updates, lambda u: self.sym(
            f"update {u.target}", K.Function, u.span, u.target_span,
            "partial function" + ("" if u.plain else f", {len(u.cases)} cases")))
        kids += self.each(bd.conditions, lambda c: self.sym(
            c.name, K.Event, c.span, c.name_span, f"{c.kind} condition"))
        return self.sym(bd.name, K.Method, bd.span, bd.name_span, "behaviour", kids)

    def subsystem(self, s: ast.SubsystemDecl) -> Symbol:
        kids = self.each(s.params, lambda p: self.sym(
            p.name, K.Constant, p.span, p.name_span, f"param: {_type_text(p.type)}"))
        kids += self.each(s.memory, lambda m: self.sym(
            m.name, K.Variable, m.span, m.name_span, f"memory: {_type_text(m.type)}"))
        kids += self.each(s.buffers, self.buffer)
        kids += self.each(s.behaviours, self.behaviour)
        freq = f" @ {s.frequency.hertz:g} Hz" if s.frequency else ""
        return self.sym(s.name, K.Class, s.span, s.name_span,
                        f"{s.kind.value} subsystem{freq}", kids)

    def agent(self, a: ast.AgentDecl) -> Symbol:
        if self.known is None:
            return self.agent_symbol(a)
        span = self.real(a.span)
        line, character = self.lines.ends_of(span, self.encoding)[0]
        source = self.lines.text[span.offset + self.lines.bom:span.end_offset + self.lines.bom]
        hit = self.known.get(id(a))
        if hit is not None and hit.agent is a and hit.symbols <= self.left \
                and hit.character == character and hit.source == source:
            self.left -= hit.symbols
            got = hit if hit.line == line else OutlinedAgent(
                a, line, character, source, _moved(hit.text, line - hit.line), hit.symbols)
        else:
            before = self.left
            got = OutlinedAgent(a, line, character, source, json.dumps(self.agent_symbol(a)),
                                before - self.left)
        if self.left > 0:     # (not cut short by MAX_SYMBOLS)
            self.outlined[id(a)] = got
        self.texts.append(got.text)
        return f"\0{len(self.texts) - 1}"      # type: ignore[return-value]

    def agent_symbol(self, a: ast.AgentDecl) -> Symbol:
        kids = self.each(a.subsystems, self.subsystem)
        kids += self.each(a.devices, lambda d: self.sym(
            d.name, K.Object, d.span, d.name_span, f"real {d.kind.value}: {d.device}"))
        return self.sym(a.name, K.Module, a.span, a.name_span, "agent", kids)

    def decl(self, d: ast.Decl) -> Symbol:
        match d:
            case ast.SystemDecl():
                kids = self.each(d.agents, self.agent)
                kids += self.each(d.instances, lambda i: self.sym(
                    i.name if i.lo is None else f"{i.name}[{i.lo}..{i.hi}]", K.Module, i.span,
                    i.name_span,
                    f"agent: {i.definition}"))
                kids += self.each(d.properties, lambda p: self.sym(
                    p.name, K.Property, p.span, p.name_span,
                    "always property" if p.kind == "always"
                    else "response property (whenever ... eventually ...)"))
                return self.sym(d.name, K.Namespace, d.span, d.name_span, "system", kids)
            case ast.RecordDecl():
                fields = self.each(d.fields, lambda f: self.sym(
                    f.name, K.Field, f.span, f.span, _type_text(f.type)))
                return self.sym(d.name, K.Struct, d.span, d.name_span, "record", fields)
            case ast.AliasDecl():
                return self.sym(d.name, K.TypeParameter, d.span, d.name_span,
                                f"type = {_type_text(d.type)}")
            case ast.EnumDecl():
                members = self.each(d.members, lambda m: self.sym(
                    m.name, K.EnumMember, m.span, m.span, "member"))
                return self.sym(d.name, K.Enum, d.span, d.name_span, "enum", members)
            case ast.ConstDecl():
                return self.sym(d.name, K.Constant, d.span, d.name_span, "const")
            case ast.ExternDecl():
                params = ", ".join(f"{p.name}: {_type_text(p.type)}" for p in d.params)
                return self.sym(d.name, K.Function, d.span, d.name_span,
                                f"extern ({params}) -> {_type_text(d.result)}")
            case ast.AgentDef():
                kids = self.each(d.subsystems, self.subsystem)
                kids += self.each(d.devices, lambda x: self.sym(
                    x.name, K.Object, x.span, x.name_span, f"real {x.kind.value}: {x.device}"))
                return self.sym(d.name, K.Class, d.span, d.name_span, "agent definition", kids)
            case ast.DeviceDecl():
                kids = self.each(d.buffers, self.buffer)
                kids += self.each(d.params, lambda p: self.sym(
                    p.name, K.Constant, p.span, p.name_span, "param"))
                return self.sym(d.name, K.Interface, d.span, d.name_span,
                                f"device {d.kind.value}", kids)
        raise AssertionError(d)


def outline_values(module: ast.Module | None, lines: LineIndex, encoding: str,
                   real: Callable[[Span], Span] = _same) -> list[Symbol]:
    """The outline of `module` as the JSON values of DocumentSymbols (what is sent: made
    directly, for the outline of a large file is long to convert); `real` maps its spans to
    the text's (an AST whose spans are stale after an incremental analysis is outlined
    without mapping all of it first)."""
    if module is None:
        return []
    outline = _Outline(lines, encoding, module.path, real)
    return outline.each(module.decls, outline.decl)


def outline_json(module: ast.Module | None, lines: LineIndex, encoding: str,
                 real: Callable[[Span], Span], known: AgentOutlines
                 ) -> tuple[str, AgentOutlines]:
    """The outline in JSON, what outline_values gives, with the JSON of each agent that is
    in `known` (the same AST, outlined for an earlier text in the same encoding) reused:
    moved by whole lines if the agent moved. Also the outlined agents, for the next text."""
    if module is None:
        return "[]", {}
    outline = _Outline(lines, encoding, module.path, real, known)
    text = json.dumps(outline.each(module.decls, outline.decl))
    return _MARK.sub(lambda m: outline.texts[int(m.group(1))], text), outline.outlined


def document_symbols(module: ast.Module | None, lines: LineIndex, encoding: str,
                     real: Callable[[Span], Span] = _same) -> list[lsp.DocumentSymbol]:
    """The outline as DocumentSymbols."""
    values = outline_values(module, lines, encoding, real)
    return _CONVERTER.structure(values, list[lsp.DocumentSymbol])  # type: ignore[no-any-return]


_CONVERTER = default_converter()  # type: ignore[no-untyped-call]
