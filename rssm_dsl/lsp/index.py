"""The symbol index of a program: every declaration and every use of a declared name, with
spans. It is built from the AST of every file of a program (partial modules too), so it
works while the text has errors; go to definition, find references, rename, completion and
hover read it.

Keys are global: `type:Vec3`, `const:K`, `extern:f`, `device:LWR4Plus`,
`devbuf:LWR4Plus.torque`, `system:S`, `field:Rec.f`, `member:Phase.idle` (an enum's member),
`module:<display path>`; inside a
system, with F|S its file and name (system_id): `agent:F|S/a1`, `sub:F|S/a1.e.lwr`,
`inst:F|S/a1.E.lwr`, `buf:F|S/a1.e.lwr.setpoint`, `mem:F|S/a1.c.phase`,
`param:F|S/a1.c.radius`, `beh:F|S/a1.c.cw`, `cond:F|S/a1.c.cw.full_circle`,
`prop:F|S/no_clash`; locals (`let`) get a key made of their position. The same declaration
seen from two programs has the same key.

Peer references name subsystems and buffers: in `from e.lwr`, `lwr` refers to the virtual
effector a1.e.lwr; in `to E.lwr.torque`, `lwr` is the device instance and `torque` its
buffer; in `a2.c`, `a2` is the agent and `c` its control subsystem. `new(x)` refers to the
input buffer x. In a property, `arm.c in release` refers to the agent arm, its control
subsystem and its behaviour release; `arm.c.waited` to arm, arm.c and its variable waited.
In `real effector big: Heater(watts = 2000.0)`, `watts` is the device type's parameter.

A record field is referred to by `x.f` (read, or written by `x.f := ...`) where x is of that
record type, and by `{f: ...}`, a record literal of the type its context expects (the
declared type of what it initialises or is assigned to, a parameter of an external
operation, the enclosing literal's field...): the index follows the types of expressions
as far as records go, as the type checker does.

`links` records the peer of each buffer (what pairing and rename need).
"""

from __future__ import annotations

import logging
import re
from collections.abc import Iterator
from dataclasses import field
from pathlib import Path

from rssm_core.records import dataclass
from rssm_dsl.lsp.positions import line_start
from rssm_dsl.semantics.instances import definition_agent
from rssm_dsl.semantics.loader import Program, _candidates, display_path
from rssm_dsl.semantics.typecheck import BUILTIN_CONSTS, BUILTIN_FUNCTIONS
from rssm_dsl.source import SourceFile, Span
from rssm_dsl.syntax import ast

log = logging.getLogger("rssmc.lsp")
_NAME = re.compile(r"[A-Za-z_][A-Za-z0-9_]*")
_LETTERS = ("c", "e", "r", "E", "R")
_KIND_LETTER = {"control": "c", "effector": "e", "receptor": "r"}
_DEVICE_LETTER = {"effector": "E", "receptor": "R"}


@dataclass(frozen=True, slots=True)
class Definition:
    key: str
    name: str
    kind: str             # what a person calls it: "input buffer", "behaviour", ...
    span: Span            # the name
    full: Span            # the whole declaration
    detail: str           # one line of RSSM text describing it
    container: str | None = None   # key of the enclosing declaration
    renameable: bool = True


@dataclass(frozen=True, slots=True)
class _Rec:
    """A record type (records are nominal: named by their declaration)."""

    name: str


@dataclass(frozen=True, slots=True)
class _Arr:
    element: _Ty


# What the index knows of a value's type: enough to tell which record a field belongs to
# (None: not a record, nor an array of them, or unknown).
_Ty = _Rec | _Arr | None


@dataclass(frozen=True, slots=True)
class Occurrence:
    span: Span
    key: str
    definition: bool = False


@dataclass
class Scope:
    """What the names inside one subsystem (or device) can refer to."""

    sub: str | None = None                                    # the subsystem key
    names: dict[str, str] = field(default_factory=dict)        # local name -> key


@dataclass
class SymbolIndex:
    definitions: dict[str, Definition] = field(default_factory=dict)
    occurrences: dict[str, list[Occurrence]] = field(default_factory=dict)  # by file
    scopes: list[tuple[Span, Scope]] = field(default_factory=list)  # subsystem spans
    # the peer of each buffer that names one: buffer key -> the key of the subsystem or
    # device instance, or of the buffer (`PEER.BUFFER`)
    links: dict[str, str] = field(default_factory=dict)

    # ------------------------------------------------------------------ queries
    def at(self, file: str, offset: int) -> Occurrence | None:
        """The occurrence under a code-point offset (a cursor just after a name counts)."""
        best: Occurrence | None = None
        for occ in self.occurrences.get(file, ()):
            s = occ.span
            if s.offset <= offset <= s.end_offset and (
                    best is None or s.end_offset - s.offset < best.span.end_offset
                    - best.span.offset):
                best = occ
        return best

    def references(self, key: str) -> list[Occurrence]:
        return [o for occs in self.occurrences.values() for o in occs if o.key == key]

    def scope_at(self, file: str, offset: int) -> Scope | None:
        found: Scope | None = None
        for span, scope in self.scopes:
            if span.file == file and span.offset <= offset <= span.end_offset:
                found = scope
        return found

    def children(self, key: str) -> list[Definition]:
        return [d for d in self.definitions.values() if d.container == key]


def _name_span(source: SourceFile | None, span: Span, name: str, start: int | None = None
               ) -> Span:
    """The span of `name` inside `span` (the first occurrence at or after `start`)."""
    if source is None:
        return span
    text = source.text
    begin = span.offset if start is None else start
    for m in _NAME.finditer(text, begin, max(span.end_offset, begin)):
        if m.group() == name:
            return source.span(m.start(), m.end())
    return span


# what block_end steps over: comments and strings whole (an unclosed one to the end of its
# line or of the text, as the compiler reads it), and the brackets
_BLOCK_SCAN = re.compile(r'//[^\n\r]*|/\*[\s\S]*?\*/|/\*[\s\S]*'
                         r'|"(?:[^"\\\n\r]|\\[\s\S])*[\s\S]?|[()\[\]{}]')


def block_end(text: str, end: int) -> int:
    """The offset just after the `}` that closes the block whose contents end near `end`:
    the first `}` after `end` that closes no bracket opened after `end` (node spans stop at
    their last child, before closing punctuation). `end` when there is none."""
    depth = 0
    for m in _BLOCK_SCAN.finditer(text, end):
        ch = m.group()
        if ch in ("(", "[", "{"):
            depth += 1
        elif ch in (")", "]"):
            depth = max(0, depth - 1)
        elif ch == "}":
            if depth == 0:
                return m.end()
            depth -= 1
    return end


def block_close(text: str, name_end: int) -> int:
    """The offset after the `}` closing the block that opens with the first `{` after a
    declaration's name (found from the text: node spans may stop short of it)."""
    brace = text.find("{", name_end)
    return block_end(text, brace + 1) if brace >= 0 else name_end


def _type_text(t: ast.TypeExpr) -> str:
    from rssm_dsl.syntax.printer import type_text
    return type_text(t)


def _type_names(t: ast.TypeExpr) -> Iterator[ast.NamedType]:
    while isinstance(t, ast.ArrayType):
        t = t.element
    if isinstance(t, ast.NamedType):
        yield t


def _exprs(e: ast.Expr) -> Iterator[ast.Expr]:
    """Every sub-expression, without recursion."""
    stack: list[ast.Expr] = [e]
    while stack:
        x = stack.pop()
        yield x
        match x:
            case ast.FieldAccess():
                stack.append(x.value)
            case ast.Index():
                stack += [x.value, x.index]
            case ast.Call():
                stack += list(x.args)
            case ast.Unary():
                stack.append(x.operand)
            case ast.Binary():
                stack += [x.left, x.right]
            case ast.IfExpr():
                stack += [x.condition, x.then, x.otherwise]
            case ast.ArrayLit():
                stack += list(x.items)
            case ast.RecordLit():
                stack += [v for _, v in x.fields]
            case ast.InBehaviour():
                stack.append(x.subject)


def _arr_leaves(a: ast.Arrangement) -> Iterator[ast.ArrBuffer]:
    stack: list[ast.Arrangement] = [a]
    while stack:
        x = stack.pop()
        if isinstance(x, ast.ArrBuffer):
            yield x
        else:
            stack += list(x.items)


def system_id(sd: ast.SystemDecl) -> str:
    """What makes a system's declarations unique: its file and its name."""
    return f"{sd.span.file}|{sd.name}"


def subsystem_key(system: str, agent: str, s: ast.SubsystemDecl) -> str:
    """`system` is a system_id()."""
    if s.kind is ast.SubsystemKind.CONTROL:
        return f"sub:{system}/{agent}.c"
    return f"sub:{system}/{agent}.{_KIND_LETTER[s.kind.value]}.{s.name}"


def instance_key(system: str, agent: str, d: ast.DeviceInstance) -> str:
    return f"inst:{system}/{agent}.{_DEVICE_LETTER[d.kind.value]}.{d.name}"


def _buffer_detail(b: ast.BufferDecl) -> str:
    text = f"{b.direction.value} {b.name}: {_type_text(b.type)}"
    if b.peer is not None:
        text += f" {'to' if b.direction is ast.Direction.OUTPUT else 'from'} {b.peer}"
    if b.mode is not None:
        text += f" {b.mode.value}"
    return text


class IndexBuilder:
    def __init__(self, program: Program, only_agent: ast.AgentDecl | None = None,
                 known: dict[str, Definition] | None = None) -> None:
        """`only_agent`: index the declarations and uses of that agent alone (its peers
        are looked up in `known`, the definitions of the rest of the program)."""
        self.program = program
        self.only_agent = only_agent
        self.index = SymbolIndex(definitions=dict(known) if known is not None else {})
        self.globals: dict[str, str] = {}           # global name -> key
        self.device_types: dict[str, ast.DeviceDecl] = {}
        self.agent_defs: dict[str, ast.AgentDef] = {}
        self.def_agents: dict[str, ast.AgentDecl] = {}     # each as an agent (its text)
        self.alias: dict[tuple[str, int], str] = {}    # a definition's parameter, by its name
        # what the record fields of an expression's value need: declared types by name,
        # the declared type of each variable's key, and the values of untyped constants
        self.type_decls: dict[str, ast.RecordDecl | ast.AliasDecl | ast.EnumDecl] = {}
        self.externs: dict[str, ast.ExternDecl] = {}
        self.declared: dict[str, ast.TypeExpr] = {}
        self.untyped: dict[str, ast.Expr] = {}
        self.local_types: dict[str, _Ty] = {}
        self._typing: set[str] = set()

    def source(self, span: Span) -> SourceFile | None:
        return self.program.sources.get(span.file)

    def define(self, d: Definition) -> None:
        self.index.definitions.setdefault(d.key, d)
        self.use(d.span, d.key, True)

    def use(self, span: Span, key: str, definition: bool = False) -> None:
        self.index.occurrences.setdefault(span.file, []).append(
            Occurrence(span, key, definition))

    # ------------------------------------------------------------------ driver
    def build(self) -> SymbolIndex:
        modules = [m for m in self.program.modules]
        if self.program.root is not None and self.program.root not in modules:
            modules.append(self.program.root)
        for m in modules:
            self._globals(m)
        for m in modules:
            if self.only_agent is not None:
                self._only_agent_uses(m, self.only_agent)
            else:
                self._module(m)
        for occs in self.index.occurrences.values():
            occs.sort(key=lambda o: (o.span.offset, o.span.end_offset))
        return self.index

    def _globals(self, m: ast.Module) -> None:
        for d in m.decls:
            match d:
                case ast.RecordDecl():
                    key = f"type:{d.name}"
                    self.type_decls.setdefault(d.name, d)
                    self.define(Definition(key, d.name, "record", d.name_span, d.span,
                                           f"record {d.name}"))
                    for f in d.fields:
                        span = _name_span(self.source(f.span), f.span, f.name)
                        self.define(Definition(f"field:{d.name}.{f.name}", f.name, "field",
                                               span, f.span, f"{f.name}: {_type_text(f.type)}",
                                               key))
                case ast.AliasDecl():
                    self.type_decls.setdefault(d.name, d)
                    self.define(Definition(f"type:{d.name}", d.name, "type alias", d.name_span,
                                           d.span, f"type {d.name} = {_type_text(d.type)}"))
                case ast.EnumDecl():
                    key = f"type:{d.name}"
                    self.type_decls.setdefault(d.name, d)
                    members = ", ".join(m.name for m in d.members)
                    self.define(Definition(key, d.name, "enum", d.name_span, d.span,
                                           f"enum {d.name} {{ {members} }}"))
                    for k, mem in enumerate(d.members):
                        self.define(Definition(f"member:{d.name}.{mem.name}", mem.name,
                                               "enum member", mem.span, mem.span,
                                               f"{d.name}.{mem.name}  // member {k} of "
                                               f"{len(d.members)}", key))
                case ast.ConstDecl():
                    from rssm_dsl.syntax.printer import expr_text
                    t = f": {_type_text(d.type)}" if d.type is not None else ""
                    if d.type is not None:
                        self.declared.setdefault(f"const:{d.name}", d.type)
                    else:
                        self.untyped.setdefault(f"const:{d.name}", d.value)
                    self.define(Definition(f"const:{d.name}", d.name, "constant", d.name_span,
                                           d.span, f"const {d.name}{t} = {expr_text(d.value)}"))
                case ast.ExternDecl():
                    self.externs.setdefault(d.name, d)
                    params = ", ".join(f"{p.name}: {_type_text(p.type)}" for p in d.params)
                    self.define(Definition(
                        f"extern:{d.name}", d.name, "external operation", d.name_span, d.span,
                        f"extern {d.name}({params}) -> {_type_text(d.result)} "
                        f"= \"{d.binding}\""))
                case ast.DeviceDecl():
                    self._device_type(d)
                case ast.AgentDef():
                    self._agent_def(d)
                case ast.SystemDecl():
                    self._system(d)
            name = getattr(d, "name", None)
            if isinstance(name, str) and not isinstance(d, ast.SystemDecl):
                prefix = {ast.RecordDecl: "type", ast.AliasDecl: "type", ast.EnumDecl: "type",
                          ast.ConstDecl: "const",
                          ast.ExternDecl: "extern", ast.DeviceDecl: "device",
                          ast.AgentDef: "agentdef"}[type(d)]
                self.globals.setdefault(name, f"{prefix}:{name}")

    def _device_type(self, d: ast.DeviceDecl) -> None:
        key = f"device:{d.name}"
        self.device_types[d.name] = d
        self.define(Definition(key, d.name, f"device type (real {d.kind.value})", d.name_span,
                               d.span, f"device {d.kind.value} {d.name}"))
        for b in d.buffers:
            self.declared.setdefault(f"devbuf:{d.name}.{b.name}", b.type)
            self.define(Definition(f"devbuf:{d.name}.{b.name}", b.name,
                                   f"{b.direction.value} buffer of a device", b.name_span,
                                   b.span, _buffer_detail(b), key))
        for p in d.params:
            self.declared.setdefault(f"devparam:{d.name}.{p.name}", p.type)
            self.define(Definition(f"devparam:{d.name}.{p.name}", p.name, "device parameter",
                                   p.name_span, p.span, f"param {p.name}: {_type_text(p.type)}",
                                   key))

    def _agent_def(self, d: ast.AgentDef) -> None:
        self.agent_defs.setdefault(d.name, d)
        key = f"agentdef:{d.name}"
        params = ", ".join(p.name + (": agent" if p.type is None else f": {_type_text(p.type)}")
                           for p in d.params)
        self.define(Definition(key, d.name, "agent definition", d.name_span, d.span,
                               f"agent {d.name}({params})"))
        for p in d.params:
            self.define(Definition(
                f"agentparam:{d.name}.{p.name}", p.name, "agent parameter", p.name_span,
                p.span, f"{p.name}: " + ("agent" if p.type is None else _type_text(p.type)),
                key))

    def _system(self, sd: ast.SystemDecl) -> None:
        if self.only_agent is None:
            self.define(Definition(f"system:{system_id(sd)}", sd.name, "system", sd.name_span,
                                   sd.span, f"system {sd.name}"))
            self._structure(sd)
        elif any(x is self.only_agent for x in sd.agents):
            self._agent_structure(sd, self.only_agent)

    def _structure(self, sd: ast.SystemDecl) -> None:
        """Declarations inside the system: agents, subsystems, instances, their members."""
        for a in sd.agents:
            self._agent_structure(sd, a)
        for inst in sd.instances:        # `agent r[1..8]: Robot(...)`: r1, ..., r8 there
            for name in inst.names():
                self.define(Definition(f"agent:{system_id(sd)}/{name}", name, "agent",
                                       inst.name_span, inst.span,
                                       f"agent {name}: {inst.definition}",
                                       f"system:{system_id(sd)}",
                                       renameable=inst.lo is None))
        from rssm_dsl.syntax.printer import property_text
        for prop in sd.properties:
            self.define(Definition(f"prop:{system_id(sd)}/{prop.name}", prop.name, "property",
                                   prop.name_span, prop.span, property_text(prop),
                                   f"system:{system_id(sd)}"))

    def _agent_structure(self, sd: ast.SystemDecl, a: ast.AgentDecl,
                         container: str | None = None) -> None:
        """The declarations of one agent: its own, its subsystems', its instances'. Those
        of an agent definition's text (``container``: the definition's key) have no agent
        of their own."""
        akey = f"agent:{system_id(sd)}/{a.name}"
        if container is None:
            self.define(Definition(akey, a.name, "agent", a.name_span, a.span,
                                   f"agent {a.name}", f"system:{system_id(sd)}"))
        else:
            akey = container
        for s in a.subsystems:
            skey = subsystem_key(system_id(sd), a.name, s)
            named = s.kind is not ast.SubsystemKind.CONTROL or s.name_span != s.span
            head = f"{s.kind.value} {s.name}" if s.kind is not ast.SubsystemKind.CONTROL \
                else f"control {s.name}"
            self.define(Definition(skey, s.name, f"{s.kind.value} subsystem", s.name_span,
                                   s.span, head, akey,
                                   renameable=s.kind is not ast.SubsystemKind.CONTROL
                                   and named))
            for b in s.buffers:
                self.declared.setdefault(f"buf:{skey[4:]}.{b.name}", b.type)
                self.define(Definition(f"buf:{skey[4:]}.{b.name}", b.name,
                                       f"{b.direction.value} buffer", b.name_span, b.span,
                                       _buffer_detail(b), skey))
            for mem in s.memory:
                self.declared.setdefault(f"mem:{skey[4:]}.{mem.name}", mem.type)
                self.define(Definition(f"mem:{skey[4:]}.{mem.name}", mem.name, "memory",
                                       mem.name_span, mem.span,
                                       f"memory {mem.name}: {_type_text(mem.type)}", skey))
            for p in s.params:
                if (p.name_span.file, p.name_span.offset) in self.alias:
                    continue
                self.declared.setdefault(f"param:{skey[4:]}.{p.name}", p.type)
                self.define(Definition(f"param:{skey[4:]}.{p.name}", p.name, "parameter",
                                       p.name_span, p.span,
                                       f"param {p.name}: {_type_text(p.type)}", skey))
            for bd in s.behaviours:
                bkey = f"beh:{skey[4:]}.{bd.name}"
                self.define(Definition(bkey, bd.name, "behaviour", bd.name_span, bd.span,
                                       f"behaviour {bd.name}", skey))
                for c in bd.conditions:
                    self.define(Definition(f"cond:{bkey[4:]}.{c.name}", c.name,
                                           f"{c.kind} condition", c.name_span, c.span,
                                           f"{c.kind} {c.name}", bkey))
        for inst in a.devices:
            self.define(Definition(instance_key(system_id(sd), a.name, inst), inst.name,
                                   f"real {inst.kind.value}", inst.name_span, inst.span,
                                   f"real {inst.kind.value} {inst.name}: {inst.device}",
                                   akey))

    # ------------------------------------------------------------------ uses
    def _module(self, m: ast.Module) -> None:
        src = self.program.sources.get(m.path)
        for imp in m.imports:
            self._import(imp, m)
        for d in m.decls:
            match d:
                case ast.RecordDecl():
                    for f in d.fields:
                        self._types(f.type)
                case ast.AliasDecl():
                    self._types(d.type)
                case ast.ConstDecl():
                    if d.type is not None:
                        self._types(d.type)
                    self._expr(d.value, {}, self._ty(d.type))
                case ast.ExternDecl():
                    for p in d.params:
                        self._types(p.type)
                    self._types(d.result)
                case ast.DeviceDecl():
                    self._device(d)
                case ast.SystemDecl():
                    for a in d.agents:
                        self._agent(d, a, src)
                    self._instances(d, src)
                    for prop in d.properties:
                        for e in prop.expressions:
                            self._property_expr(d, e)

    def _instances(self, sd: ast.SystemDecl, src: SourceFile | None) -> None:
        """The instance lines (their definition, parameters, the agents they name) and the
        text of the definitions, indexed as an agent each (a name in a definition is the
        definition's in every instance)."""
        sys = system_id(sd)
        for inst in sd.instances:
            d = self.agent_defs.get(inst.definition)
            if d is None:
                continue
            self.use(inst.definition_span, f"agentdef:{d.name}")
            kinds = {p.name: p for p in d.params}
            for arg in inst.args:
                p = kinds.get(arg.name)
                if p is None:
                    self._expr(arg.value, {})
                    continue
                self.use(arg.name_span, f"agentparam:{d.name}.{p.name}")
                if p.type is None and isinstance(arg.value, ast.Name):
                    self.use(arg.value.span, f"agent:{sys}/{arg.value.name}")
                else:
                    self._expr(arg.value, {}, self._ty(p.type) if p.type else None)
        for d in self.agent_defs.values():
            if d.span.file != sd.span.file:
                continue
            pseudo = self.def_agents.setdefault(d.name, definition_agent(d))
            for p in d.params:
                if p.type is not None:
                    self.alias[p.name_span.file, p.name_span.offset] = \
                        f"agentparam:{d.name}.{p.name}"
                    self.declared.setdefault(f"agentparam:{d.name}.{p.name}", p.type)
            self._agent_structure(sd, pseudo, f"agentdef:{d.name}")
            self._agent(sd, pseudo, src)
            for p in d.params:
                if p.type is not None:
                    self._types(p.type)

    def _agent_param(self, a: ast.AgentDecl, name: str, span: Span) -> bool:
        """Is ``name`` (the first part of a peer of ``a``) a parameter `agent` of the
        definition ``a`` stands for (`boss.c` in a definition: the agent its instances give
        `boss`)? Its use is recorded."""
        d = self.agent_defs.get(a.name)
        if d is None or self.def_agents.get(a.name) is not a or \
                not any(p.name == name and p.type is None for p in d.params):
            return False
        self.use(span, f"agentparam:{d.name}.{name}")
        return True

    def _peer_parts(self, peer: ast.PeerRef) -> list[tuple[str, Span]] | None:
        """Each part of a peer with its span (None when the text is not at hand)."""
        src = self.source(peer.span)
        if src is None:
            return None
        spans = [src.span(m.start(), m.end()) for m in
                 _NAME.finditer(src.text, peer.span.offset, peer.span.end_offset)]
        if len(spans) != len(peer.parts):
            return None
        return list(zip(peer.parts, spans, strict=True))

    def _other_agent(self, sd: ast.SystemDecl, name: str) -> ast.AgentDecl | None:
        """The agent a peer's first part names (an instance's: its definition's text, whose
        keys its subsystems share), None when it names no agent."""
        if name in _LETTERS:
            return None
        return next((x for x in sd.agents if x.name == name), None) or \
            self._instance_agent(sd, name)

    def _instance_agent(self, sd: ast.SystemDecl, name: str) -> ast.AgentDecl | None:
        """The definition (as :func:`definition_agent`) of the instance ``name`` of ``sd``."""
        for inst in sd.instances:
            if name in inst.names() and inst.definition in self.agent_defs:
                d = self.agent_defs[inst.definition]
                if d.name not in self.def_agents:
                    self.def_agents[d.name] = definition_agent(d)
                return self.def_agents[d.name]
        return None

    def _only_agent_uses(self, m: ast.Module, agent: ast.AgentDecl) -> None:
        for d in m.decls:
            if isinstance(d, ast.SystemDecl) and any(x is agent for x in d.agents):
                self._agent(d, agent, None)

    def _device(self, d: ast.DeviceDecl) -> None:
        scope = {p.name: f"devparam:{d.name}.{p.name}" for p in d.params}
        for b in d.buffers:
            self._types(b.type)
            if b.init is not None:
                self._expr(b.init, scope, self._ty(b.type))
        for dp in d.params:
            self._types(dp.type)
            self._expr(dp.value, scope, self._ty(dp.type))

    def _import(self, imp: ast.Import, m: ast.Module) -> None:
        path = Path(m.path)
        if m.path.startswith("<stdlib>/"):
            from rssm_dsl.resources import stdlib_dir
            path = stdlib_dir() / m.path.removeprefix("<stdlib>/")
        target = next((c for c in _candidates(imp, path) if c.is_file()), None)
        if target is None:
            return
        shown = display_path(target)
        key = f"module:{shown}"
        if key not in self.index.definitions:
            here = Span(shown, 1, 1, 1, 1, 0, 0)
            self.index.definitions[key] = Definition(key, imp.path, "module", here, here,
                                                     f"import {imp.path}", renameable=False)
        span = self._import_path_span(imp)
        if span is not None:
            self.use(span, key)

    def _import_path_span(self, imp: ast.Import) -> Span | None:
        """The span of the module path of an import (found in the text when the parser gave
        the import no position)."""
        src = self.source(imp.span)
        if src is None:
            return None
        written = f'"{imp.path}"' if imp.quoted else imp.path
        if imp.span.end_offset > imp.span.offset:
            at = src.text.find(written, imp.span.offset, imp.span.end_offset)
            return src.span(at, at + len(written)) if at >= 0 else None
        pattern = re.compile(r"\bimport\s+" + re.escape(written).replace(r"\.", r"\s*\.\s*"))
        for m in pattern.finditer(src.text):
            if "//" not in src.text[line_start(src.text, m.start()):m.start()]:
                start = m.start() + len("import")
                start += len(src.text[start:m.end()]) - len(src.text[start:m.end()].lstrip())
                return src.span(start, m.end())
        return None

    def _types(self, t: ast.TypeExpr) -> None:
        for named in _type_names(t):
            key = self.globals.get(named.name)
            if key is not None and key.startswith("type:"):
                self.use(named.span, key)

    def _expr(self, e: ast.Expr, scope: dict[str, str], expected: _Ty = None) -> None:
        """The names of `e` (in `scope`: local name -> key) and its record fields (`expected`:
        the type its context gives it, which record literals take)."""
        self._fields(e, scope, expected)
        for x in _exprs(e):
            if isinstance(x, ast.Name):
                key = scope.get(x.name) or self.globals.get(x.name)
                if key is not None and not key.startswith(("type:", "device:", "extern:")):
                    self.use(x.span, key)
            elif isinstance(x, ast.Call):
                key = self.globals.get(x.function)
                if key is not None and key.startswith("extern:"):
                    self.use(x.function_span, key)
            elif isinstance(x, ast.FieldAccess) and isinstance(x.value, ast.Name) \
                    and x.value.name not in scope:
                self._member(x, x.value)

    # ------------------------------------------------------------------ record fields
    def _ty(self, t: ast.TypeExpr | None) -> _Ty:
        """A declared type, as far as records go (aliases followed)."""
        arrays = 0
        seen: set[str] = set()
        found: _Ty = None
        while t is not None:
            if isinstance(t, ast.ArrayType):
                arrays += 1
                t = t.element
                continue
            if not isinstance(t, ast.NamedType) or t.name in seen:
                break
            seen.add(t.name)
            d = self.type_decls.get(t.name)
            if isinstance(d, ast.AliasDecl):
                t = d.type
                continue
            if isinstance(d, ast.RecordDecl):
                found = _Rec(d.name)
            break
        if found is None:
            return None
        for _ in range(arrays):
            found = _Arr(found)
        return found

    def _field_decl(self, record: str, name: str) -> ast.FieldDecl | None:
        d = self.type_decls.get(record)
        if not isinstance(d, ast.RecordDecl):
            return None
        return next((f for f in d.fields if f.name == name), None)

    def _key_type(self, key: str | None) -> _Ty:
        """The type of the variable, buffer, parameter, constant or local of a key."""
        if key is None:
            return None
        if key in self.local_types:
            return self.local_types[key]
        declared = self.declared.get(key)
        if declared is not None:
            return self._ty(declared)
        value = self.untyped.get(key)
        if value is None or key in self._typing or len(self._typing) > 32:
            return None
        self._typing.add(key)
        try:
            return self._type_of(value, {})
        finally:
            self._typing.discard(key)

    def _type_of(self, e: ast.Expr, scope: dict[str, str], expected: _Ty = None) -> _Ty:
        """The type of an expression's value, as far as records go (as the type checker
        finds it: a record literal takes the type its context expects)."""
        match e:
            case ast.Name():
                return self._key_type(scope.get(e.name) or self.globals.get(e.name))
            case ast.FieldAccess():
                base = self._type_of(e.value, scope)
                f = self._field_decl(base.name, e.field) if isinstance(base, _Rec) else None
                return self._ty(f.type) if f is not None else None
            case ast.Index():
                base = self._type_of(e.value, scope)
                return base.element if isinstance(base, _Arr) else None
            case ast.Call():
                ext = self.externs.get(e.function)
                if ext is None or e.function in BUILTIN_FUNCTIONS:
                    return None
                return self._ty(ext.result)
            case ast.IfExpr():
                return (self._type_of(e.then, scope, expected)
                        or self._type_of(e.otherwise, scope, expected))
            case ast.ArrayLit():
                want = expected.element if isinstance(expected, _Arr) else None
                first = self._type_of(e.items[0], scope, want) if e.items else None
                return _Arr(first) if first is not None else None
            case ast.RecordLit():
                return expected if isinstance(expected, _Rec) else None
        return None

    def _fields(self, e: ast.Expr, scope: dict[str, str], expected: _Ty) -> None:
        """The record fields named in `e`: `x.f` (x a record) and `{f: ...}` (a record
        literal, of the type its context expects)."""
        try:
            self._fields_of(e, scope, expected)
        except RecursionError:   # a pathological nesting: its fields are not indexed
            log.info("record fields of a deeply nested expression are not indexed")

    def _fields_of(self, e: ast.Expr, scope: dict[str, str], expected: _Ty) -> None:
        stack: list[tuple[ast.Expr, _Ty]] = [(e, expected)]
        while stack:
            x, want = stack.pop()
            match x:
                case ast.FieldAccess():
                    self._field_use(x, self._type_of(x.value, scope))
                    stack.append((x.value, None))
                case ast.RecordLit():
                    stack += self._record_literal(x, want)
                case ast.IfExpr():
                    stack += [(x.condition, None), (x.then, want), (x.otherwise, want)]
                case ast.ArrayLit():
                    elem = want.element if isinstance(want, _Arr) else None
                    stack += [(item, elem) for item in x.items]
                case ast.Call():
                    ext = None if x.function in BUILTIN_FUNCTIONS else \
                        self.externs.get(x.function)
                    params = [p.type for p in ext.params] if ext is not None else []
                    stack += [(a, self._ty(params[i]) if i < len(params) else None)
                              for i, a in enumerate(x.args)]
                case ast.Index():
                    stack += [(x.value, None), (x.index, None)]
                case ast.Unary():
                    stack.append((x.operand, None))
                case ast.Binary():
                    stack += [(x.left, None), (x.right, None)]
                case ast.InBehaviour():
                    stack.append((x.subject, None))

    def _field_use(self, x: ast.FieldAccess, base: _Ty) -> None:
        """`x.f`, x of type `base`: a use of the field f of that record."""
        if isinstance(base, _Rec) and self._field_decl(base.name, x.field) is not None:
            span = self._field_span(x)
            if span is not None:
                self.use(span, f"field:{base.name}.{x.field}")

    def _record_literal(self, x: ast.RecordLit, want: _Ty) -> list[tuple[ast.Expr, _Ty]]:
        """The fields named by a record literal of type `want`; its values, with the types
        they are expected to have."""
        out: list[tuple[ast.Expr, _Ty]] = []
        start: int | None = None     # the end of the previous field's value
        for name, v in x.fields:
            f = self._field_decl(want.name, name) if isinstance(want, _Rec) else None
            if isinstance(want, _Rec) and f is not None:
                span = self._record_field_span(v.span, start, name)
                if span is not None:
                    self.use(span, f"field:{want.name}.{name}")
            start = v.span.end_offset
            out.append((v, self._ty(f.type) if f is not None else None))
        return out

    def _record_field_span(self, value: Span, start: int | None, name: str) -> Span | None:
        """The span of the field name written before `value` in a record literal (`name:`
        just before it; else the last `name:` after `start`, the previous value's end).
        A literal's span starts at its first value, so the names are found in the text."""
        src = self.source(value)
        if src is None:
            return None
        text = src.text
        i = value.offset
        while i > 0 and text[i - 1] in " \t\r\n":
            i -= 1
        if i > 0 and text[i - 1] == ":":
            i -= 1
            while i > 0 and text[i - 1] in " \t\r\n":
                i -= 1
            if text[max(0, i - len(name)):i] == name and not (
                    i - len(name) > 0 and (text[i - len(name) - 1].isalnum()
                                           or text[i - len(name) - 1] == "_")):
                return src.span(i - len(name), i)
        lo = start if start is not None else max(0, value.offset - 4096)
        found: re.Match[str] | None = None
        pattern = re.compile(r"(?<![A-Za-z0-9_])" + re.escape(name) + r"\s*:")
        for m in pattern.finditer(text, lo, value.offset):
            found = m
        if found is None:
            return None
        return src.span(found.start(), found.start() + len(name))

    def _member(self, x: ast.FieldAccess, base: ast.Name) -> None:
        """`Phase.grasp`: the enum type and its member (the type alone when it has no such
        member)."""
        key = self.globals.get(base.name)
        member = f"member:{base.name}.{x.field}"
        if key is None or not key.startswith("type:") or not isinstance(
                self.type_decls.get(base.name), ast.EnumDecl):
            return
        self.use(base.span, key)
        if member not in self.index.definitions:
            return
        src = self.source(x.span)
        if src is not None and x.span.end_offset - len(x.field) >= base.span.end_offset:
            self.use(src.span(x.span.end_offset - len(x.field), x.span.end_offset), member)

    def _property_expr(self, sd: ast.SystemDecl, e: ast.Expr) -> None:
        """A property's expression: `AGENT.SUB` names a subsystem, `AGENT.SUB.NAME` one of
        its variables, `AGENT.SUB in BEH` one of its behaviours; other names are constants."""
        agents = {a.name: a for a in sd.agents}
        # the names followed by a field: an agent's there (AGENT.SUB...), else a constant's
        # or an enum type's (as the property checker reads them)
        roots = {id(x.value) for x in _exprs(e)
                 if isinstance(x, ast.FieldAccess) and isinstance(x.value, ast.Name)}
        for x in _exprs(e):
            if isinstance(x, ast.Name):
                self._property_name(x, x.name in agents and id(x) in roots)
                continue
            if isinstance(x, ast.FieldAccess):
                self._property_field(sd, agents, x)
            if isinstance(x, ast.InBehaviour):
                s = self._property_subsystem(sd, agents, x.subject)
                if s is not None:
                    skey = subsystem_key(system_id(sd), s[0], s[1])
                    if any(b.name == x.behaviour for b in s[1].behaviours):
                        self.use(x.behaviour_span, f"beh:{skey[4:]}.{x.behaviour}")
                continue
            if not isinstance(x, ast.FieldAccess):
                continue
            s = self._property_subsystem(sd, agents, x.value)
            if s is None:
                continue
            base = subsystem_key(system_id(sd), s[0], s[1])[4:]
            for prefix, names in (("mem", s[1].memory), ("buf", s[1].buffers),
                                  ("param", s[1].params)):
                if any(v.name == x.field for v in names):
                    span = self._field_span(x)
                    if span is not None:
                        self.use(span, f"{prefix}:{base}.{x.field}")
                    break
        for x in _exprs(e):
            if isinstance(x, ast.FieldAccess) and isinstance(x.value, ast.Name):
                s = self._property_subsystem(sd, agents, x)
                span = self._field_span(x)
                if s is not None and span is not None:
                    self.use(x.value.span, f"agent:{system_id(sd)}/{s[0]}")
                    self.use(span, subsystem_key(system_id(sd), s[0], s[1]))

    def _property_name(self, x: ast.Name, agent: bool) -> None:
        """A name in a property: a constant's, unless it is an agent's (`agent`)."""
        key = self.globals.get(x.name)
        if key is not None and key.startswith("const:") and not agent:
            self.use(x.span, key)

    def _property_field(self, sd: ast.SystemDecl, agents: dict[str, ast.AgentDecl],
                        x: ast.FieldAccess) -> None:
        """`Phase.idle` (an enum member) or `VALUE.f` (a record field) in a property."""
        if isinstance(x.value, ast.Name) and x.value.name not in agents:
            self._member(x, x.value)
            return
        self._field_use(x, self._property_type(sd, agents, x.value))

    def _property_type(self, sd: ast.SystemDecl, agents: dict[str, ast.AgentDecl],
                       e: ast.Expr) -> _Ty:
        """The type of a value in a property (AGENT.SUB.VAR, a constant, their fields)."""
        match e:
            case ast.Name():
                return None if e.name in agents else self._key_type(self.globals.get(e.name))
            case ast.FieldAccess():
                s = self._property_subsystem(sd, agents, e.value)
                if s is not None:
                    base = subsystem_key(system_id(sd), s[0], s[1])[4:]
                    for prefix in ("param", "mem", "buf"):
                        if f"{prefix}:{base}.{e.field}" in self.declared:
                            return self._key_type(f"{prefix}:{base}.{e.field}")
                    return None
                rec = self._property_type(sd, agents, e.value)
                f = self._field_decl(rec.name, e.field) if isinstance(rec, _Rec) else None
                return self._ty(f.type) if f is not None else None
            case ast.Index():
                arr = self._property_type(sd, agents, e.value)
                return arr.element if isinstance(arr, _Arr) else None
            case ast.IfExpr():
                return (self._property_type(sd, agents, e.then)
                        or self._property_type(sd, agents, e.otherwise))
        return None

    def _property_subsystem(self, sd: ast.SystemDecl, agents: dict[str, ast.AgentDecl],
                            e: ast.Expr) -> tuple[str, ast.SubsystemDecl] | None:
        """The subsystem `AGENT.SUB` names in a property: (agent name, its declaration)."""
        if not (isinstance(e, ast.FieldAccess) and isinstance(e.value, ast.Name)):
            return None
        agent = agents.get(e.value.name)
        if agent is None:
            return None
        if e.field == "c":
            control = next((s for s in agent.subsystems
                            if s.kind is ast.SubsystemKind.CONTROL), None)
            if control is not None:
                return agent.name, control
        found = next((s for s in agent.subsystems if s.name == e.field), None)
        return (agent.name, found) if found is not None else None

    def _field_span(self, e: ast.FieldAccess) -> Span | None:
        """The span of the field name of `x.field` (the last token of the node)."""
        src = self.source(e.span)
        end = e.span.end_offset
        if src is None or src.text[end - len(e.field):end] != e.field:
            return None
        return src.span(end - len(e.field), end)

    def _agent(self, sd: ast.SystemDecl, a: ast.AgentDecl, src: SourceFile | None) -> None:
        for inst in a.devices:
            decl = self.device_types.get(inst.device)
            if decl is None:
                for arg in inst.args:
                    self._expr(arg.value, {})
                continue
            self.use(inst.device_span, f"device:{inst.device}")
            # `(k = VALUE)`: the device type's parameter k (VALUE sees the type's parameters)
            params = {p.name: f"devparam:{decl.name}.{p.name}" for p in decl.params}
            for arg in inst.args:
                key = params.get(arg.name)
                if key is not None:
                    self.use(arg.name_span, key)
                self._expr(arg.value, params, self._key_type(key))
        for s in a.subsystems:
            self._subsystem(sd, a, s)

    def _subsystem(self, sd: ast.SystemDecl, a: ast.AgentDecl, s: ast.SubsystemDecl) -> None:
        skey = subsystem_key(system_id(sd), a.name, s)
        base = skey[4:]
        names: dict[str, str] = {}
        for p in s.params:      # (a definition's value parameter is the definition's)
            names[p.name] = self.alias.get((p.name_span.file, p.name_span.offset),
                                           f"param:{base}.{p.name}")
        for mem in s.memory:
            names[mem.name] = f"mem:{base}.{mem.name}"
        for b in s.buffers:
            names[b.name] = f"buf:{base}.{b.name}"
        src = self.source(s.span)
        scope_span = s.span
        if src is not None:
            start = min(s.span.offset, s.name_span.offset)
            scope_span = src.span(start, block_close(src.text, s.name_span.end_offset))
        self.index.scopes.append((scope_span, Scope(skey, dict(names))))
        self._variables(sd, a, s, names)
        for bd in s.behaviours:
            self._behaviour(bd, base, names)
        self._switches(s, base, names)

    def _variables(self, sd: ast.SystemDecl, a: ast.AgentDecl, s: ast.SubsystemDecl,
                   names: dict[str, str]) -> None:
        """The types and initial values of the parameters, memory and buffers of `s`, and
        the peers of its buffers."""
        for p in s.params:
            self._types(p.type)
            self._expr(p.value, names, self._ty(p.type))
        for mem in s.memory:
            self._types(mem.type)
            if mem.init is not None:
                self._expr(mem.init, names, self._ty(mem.type))
        for b in s.buffers:
            self._types(b.type)
            if b.init is not None:
                self._expr(b.init, names, self._ty(b.type))
            if b.peer is not None:
                link = self._peer(sd, a, b.peer)
                if link is not None:
                    skey = subsystem_key(system_id(sd), a.name, s)
                    self.index.links.setdefault(f"buf:{skey[4:]}.{b.name}", link)

    def _switches(self, s: ast.SubsystemDecl, base: str, names: dict[str, str]) -> None:
        """The behaviours named by `initial` and the switches, and the switch conditions."""
        behaviours = {bd.name: f"beh:{base}.{bd.name}" for bd in s.behaviours}
        for ini in s.initial:
            if ini.behaviour in behaviours:
                self.use(ini.behaviour_span, behaviours[ini.behaviour])
        for sw in s.switches:
            if sw.source in behaviours:
                self.use(sw.source_span, behaviours[sw.source])
            if sw.target in behaviours:
                self.use(sw.target_span, behaviours[sw.target])
            if sw.condition is not None:
                # a condition of another behaviour is out of scope (E608), but it is the one
                # the name refers to when nothing else has it
                scope = {c.name: f"cond:{base}.{bd.name}.{c.name}" for bd in reversed(s.behaviours)
                         for c in reversed(bd.conditions)
                         if not self.globals.get(c.name, "").startswith(("const:", "type:"))}
                scope.update(names)
                source = next((bd for bd in s.behaviours if bd.name == sw.source), None)
                if source is not None:
                    for c in source.conditions:
                        scope[c.name] = f"cond:{base}.{source.name}.{c.name}"
                self._expr(sw.condition, scope)

    def _behaviour(self, bd: ast.BehaviourDecl, base: str, names: dict[str, str]) -> None:
        bkey = f"beh:{base}.{bd.name}"
        for u in bd.updates:
            if u.target in names and names[u.target].startswith("buf:"):
                self.use(u.target_span, names[u.target])
            for case in u.cases:
                if case.condition is not None:
                    self._expr(case.condition, names)
                scope = dict(names)
                for st in case.body:
                    self._stmt(st, scope, bkey)
        for c in bd.conditions:
            self._expr(c.expr, names)
        for arr in (*bd.send, *bd.receive):
            for leaf in _arr_leaves(arr):
                if leaf.name in names and names[leaf.name].startswith("buf:"):
                    self.use(leaf.span, names[leaf.name])

    def _stmt(self, st: ast.Stmt, scope: dict[str, str], container: str | None = None) -> None:
        """A statement of a behaviour (`container`, the key of the local values it
        declares)."""
        match st:
            case ast.Assign():
                self._expr(st.target, scope)
                self._expr(st.value, scope, self._type_of(st.target, scope))
            case ast.Let():
                self._expr(st.value, scope)
                src = self.source(st.span)
                span = _name_span(src, st.span, st.name)   # (the span starts at the name)
                key = f"local:{span.file}:{span.offset}"
                self.define(Definition(key, st.name, "local value", span, st.span,
                                       f"let {st.name}", container))
                self.local_types[key] = self._type_of(st.value, scope)
                scope[st.name] = key

    def _device_letter(self, d: ast.DeviceInstance) -> str:
        """E or R: what the device type is (declared as the other kind it is still that:
        E308), or what the instance says when the type is unknown."""
        decl = self.device_types.get(d.device)
        return _DEVICE_LETTER[(decl.kind if decl is not None else d.kind).value]

    def _peer(self, sd: ast.SystemDecl, a: ast.AgentDecl, peer: ast.PeerRef) -> str | None:
        """The uses in a peer reference; the key of what it names (a subsystem, a device
        instance, or the buffer of `PEER.BUFFER`)."""
        parts = self._peer_parts(peer)
        if parts is None:
            return None
        agent = a
        named = parts[0][0]
        if self._agent_param(a, named, parts[0][1]):
            return None
        other = self._other_agent(sd, named) if len(parts) >= 2 else None
        if other is not None:
            agent = other
            self.use(parts[0][1], f"agent:{system_id(sd)}/{named}")
            parts = parts[1:]
        letter, letter_span = parts[0]
        if letter not in _LETTERS:
            return None
        target: str | None = None
        rest = parts[1:]
        if letter == "c":
            control = next((s for s in agent.subsystems
                            if s.kind is ast.SubsystemKind.CONTROL), None)
            if control is None:
                return None
            target = subsystem_key(system_id(sd), agent.name, control)
            self.use(letter_span, target)
        elif rest:
            name, name_span = rest[0]
            rest = rest[1:]
            if letter in ("E", "R"):
                inst = next((d for d in agent.devices if d.name == name
                             and self._device_letter(d) == letter), None)
                if inst is None:
                    return None
                target = instance_key(system_id(sd), agent.name, inst)
                self.use(name_span, target)
                if rest and inst.device in self.device_types:
                    bkey = f"devbuf:{inst.device}.{rest[0][0]}"
                    if bkey in self.index.definitions:
                        self.use(rest[0][1], bkey)
                        return bkey
                return target
            sub = next((s for s in agent.subsystems if s.name == name
                        and s.kind is not ast.SubsystemKind.CONTROL
                        and _KIND_LETTER[s.kind.value] == letter), None)
            if sub is None:
                return None
            target = subsystem_key(system_id(sd), agent.name, sub)
            self.use(name_span, target)
        if target is not None and rest:
            bkey = f"buf:{target[4:]}.{rest[0][0]}"
            if bkey in self.index.definitions:
                self.use(rest[0][1], bkey)
                return bkey
        return target


def build_index(program: Program) -> SymbolIndex:
    return IndexBuilder(program).build()


BUILTIN_NAMES: tuple[str, ...] = (*BUILTIN_FUNCTIONS, *BUILTIN_CONSTS)
