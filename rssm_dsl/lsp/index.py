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
"""

from __future__ import annotations

import re
from collections.abc import Iterator
from dataclasses import dataclass, field
from pathlib import Path

from rssm_dsl.lsp.positions import line_end, line_start
from rssm_dsl.semantics.loader import Program, _candidates, display_path
from rssm_dsl.semantics.typecheck import BUILTIN_CONSTS, BUILTIN_FUNCTIONS
from rssm_dsl.source import SourceFile, Span
from rssm_dsl.syntax import ast

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


def block_end(text: str, end: int) -> int:
    """The offset just after the `}` that closes the block whose contents end near `end`:
    the first `}` after `end` that closes no bracket opened after `end` (node spans stop at
    their last child, before closing punctuation). `end` when there is none."""
    i, n, depth = end, len(text), 0
    while i < n:
        ch = text[i]
        if text.startswith("//", i):
            i = line_end(text, i)
            continue
        if text.startswith("/*", i):
            j = text.find("*/", i + 2)
            i = n if j < 0 else j + 2
            continue
        if ch == '"':
            j = i + 1
            while j < n and text[j] not in '"\n\r':
                j += 2 if text[j] == "\\" else 1
            i = j + 1
            continue
        if ch in "([{":
            depth += 1
        elif ch in ")]":
            depth = max(0, depth - 1)
        elif ch == "}":
            if depth == 0:
                return i + 1
            depth -= 1
        i += 1
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
    def __init__(self, program: Program) -> None:
        self.program = program
        self.index = SymbolIndex()
        self.globals: dict[str, str] = {}           # global name -> key
        self.device_types: dict[str, ast.DeviceDecl] = {}

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
            self._module(m)
        for occs in self.index.occurrences.values():
            occs.sort(key=lambda o: (o.span.offset, o.span.end_offset))
        return self.index

    def _globals(self, m: ast.Module) -> None:
        for d in m.decls:
            match d:
                case ast.RecordDecl():
                    key = f"type:{d.name}"
                    self.define(Definition(key, d.name, "record", d.name_span, d.span,
                                           f"record {d.name}"))
                    for f in d.fields:
                        span = _name_span(self.source(f.span), f.span, f.name)
                        self.define(Definition(f"field:{d.name}.{f.name}", f.name, "field",
                                               span, f.span, f"{f.name}: {_type_text(f.type)}",
                                               key))
                case ast.AliasDecl():
                    self.define(Definition(f"type:{d.name}", d.name, "type alias", d.name_span,
                                           d.span, f"type {d.name} = {_type_text(d.type)}"))
                case ast.EnumDecl():
                    key = f"type:{d.name}"
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
                    self.define(Definition(f"const:{d.name}", d.name, "constant", d.name_span,
                                           d.span, f"const {d.name}{t} = {expr_text(d.value)}"))
                case ast.ExternDecl():
                    params = ", ".join(f"{p.name}: {_type_text(p.type)}" for p in d.params)
                    self.define(Definition(
                        f"extern:{d.name}", d.name, "external operation", d.name_span, d.span,
                        f"extern {d.name}({params}) -> {_type_text(d.result)} "
                        f"= \"{d.binding}\""))
                case ast.DeviceDecl():
                    key = f"device:{d.name}"
                    self.device_types[d.name] = d
                    self.define(Definition(key, d.name, f"device type (real {d.kind.value})",
                                           d.name_span, d.span,
                                           f"device {d.kind.value} {d.name}"))
                    for b in d.buffers:
                        self.define(Definition(f"devbuf:{d.name}.{b.name}", b.name,
                                               f"{b.direction.value} buffer of a device",
                                               b.name_span, b.span, _buffer_detail(b), key))
                    for p in d.params:
                        self.define(Definition(f"devparam:{d.name}.{p.name}", p.name,
                                               "device parameter", p.name_span, p.span,
                                               f"param {p.name}: {_type_text(p.type)}", key))
                case ast.SystemDecl():
                    self.define(Definition(f"system:{system_id(d)}", d.name, "system", d.name_span,
                                           d.span, f"system {d.name}"))
                    self._structure(d)
            name = getattr(d, "name", None)
            if isinstance(name, str) and not isinstance(d, ast.SystemDecl):
                prefix = {ast.RecordDecl: "type", ast.AliasDecl: "type", ast.EnumDecl: "type",
                          ast.ConstDecl: "const",
                          ast.ExternDecl: "extern", ast.DeviceDecl: "device"}[type(d)]
                self.globals.setdefault(name, f"{prefix}:{name}")

    def _structure(self, sd: ast.SystemDecl) -> None:
        """Declarations inside the system: agents, subsystems, instances, their members."""
        for a in sd.agents:
            akey = f"agent:{system_id(sd)}/{a.name}"
            self.define(Definition(akey, a.name, "agent", a.name_span, a.span,
                                   f"agent {a.name}", f"system:{system_id(sd)}"))
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
                    self.define(Definition(f"buf:{skey[4:]}.{b.name}", b.name,
                                           f"{b.direction.value} buffer", b.name_span, b.span,
                                           _buffer_detail(b), skey))
                for mem in s.memory:
                    self.define(Definition(f"mem:{skey[4:]}.{mem.name}", mem.name, "memory",
                                           mem.name_span, mem.span,
                                           f"memory {mem.name}: {_type_text(mem.type)}", skey))
                for p in s.params:
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
        from rssm_dsl.syntax.printer import property_text
        for prop in sd.properties:
            self.define(Definition(f"prop:{system_id(sd)}/{prop.name}", prop.name, "property",
                                   prop.name_span, prop.span, property_text(prop),
                                   f"system:{system_id(sd)}"))

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
                    self._expr(d.value, {})
                case ast.ExternDecl():
                    for p in d.params:
                        self._types(p.type)
                    self._types(d.result)
                case ast.DeviceDecl():
                    self._device(d)
                case ast.SystemDecl():
                    for a in d.agents:
                        self._agent(d, a, src)
                    for prop in d.properties:
                        for e in prop.expressions:
                            self._property_expr(d, e)

    def _device(self, d: ast.DeviceDecl) -> None:
        scope = {p.name: f"devparam:{d.name}.{p.name}" for p in d.params}
        for b in d.buffers:
            self._types(b.type)
            if b.init is not None:
                self._expr(b.init, scope)
        for dp in d.params:
            self._types(dp.type)
            self._expr(dp.value, scope)

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

    def _expr(self, e: ast.Expr, scope: dict[str, str]) -> None:
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

    def _member(self, x: ast.FieldAccess, base: ast.Name) -> None:
        """`Phase.grasp`: the enum type and its member."""
        key = self.globals.get(base.name)
        member = f"member:{base.name}.{x.field}"
        if key is None or not key.startswith("type:") or member not in self.index.definitions:
            return
        self.use(base.span, key)
        src = self.source(x.span)
        if src is not None and x.span.end_offset - len(x.field) >= base.span.end_offset:
            self.use(src.span(x.span.end_offset - len(x.field), x.span.end_offset), member)

    def _property_expr(self, sd: ast.SystemDecl, e: ast.Expr) -> None:
        """A property's expression: `AGENT.SUB` names a subsystem, `AGENT.SUB.NAME` one of
        its variables, `AGENT.SUB in BEH` one of its behaviours; other names are constants."""
        agents = {a.name: a for a in sd.agents}
        for x in _exprs(e):
            if isinstance(x, ast.Name):
                key = self.globals.get(x.name)
                if key is not None and key.startswith("const:") and x.name not in agents:
                    self.use(x.span, key)
                continue
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
            if inst.device in self.device_types:
                self.use(inst.device_span, f"device:{inst.device}")
        for s in a.subsystems:
            self._subsystem(sd, a, s)

    def _subsystem(self, sd: ast.SystemDecl, a: ast.AgentDecl, s: ast.SubsystemDecl) -> None:
        skey = subsystem_key(system_id(sd), a.name, s)
        base = skey[4:]
        names: dict[str, str] = {}
        for p in s.params:
            names[p.name] = f"param:{base}.{p.name}"
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
            self._expr(p.value, names)
        for mem in s.memory:
            self._types(mem.type)
            if mem.init is not None:
                self._expr(mem.init, names)
        for b in s.buffers:
            self._types(b.type)
            if b.init is not None:
                self._expr(b.init, names)
            if b.peer is not None:
                self._peer(sd, a, b.peer)

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
                scope = dict(names)
                source = next((bd for bd in s.behaviours if bd.name == sw.source), None)
                if source is not None:
                    for c in source.conditions:
                        scope[c.name] = f"cond:{base}.{source.name}.{c.name}"
                self._expr(sw.condition, scope)

    def _behaviour(self, bd: ast.BehaviourDecl, base: str, names: dict[str, str]) -> None:
        for u in bd.updates:
            if u.target in names and names[u.target].startswith("buf:"):
                self.use(u.target_span, names[u.target])
            for case in u.cases:
                if case.condition is not None:
                    self._expr(case.condition, names)
                scope = dict(names)
                for st in case.body:
                    self._stmt(st, scope)
        for c in bd.conditions:
            self._expr(c.expr, names)
        for arr in (*bd.send, *bd.receive):
            for leaf in _arr_leaves(arr):
                if leaf.name in names and names[leaf.name].startswith("buf:"):
                    self.use(leaf.span, names[leaf.name])

    def _stmt(self, st: ast.Stmt, scope: dict[str, str]) -> None:
        match st:
            case ast.Assign():
                self._expr(st.target, scope)
                self._expr(st.value, scope)
            case ast.Let():
                self._expr(st.value, scope)
                src = self.source(st.span)
                span = _name_span(src, st.span, st.name, st.span.offset + len("let"))
                key = f"local:{span.file}:{span.offset}"
                self.define(Definition(key, st.name, "local value", span, st.span,
                                       f"let {st.name}"))
                scope[st.name] = key

    def _peer(self, sd: ast.SystemDecl, a: ast.AgentDecl, peer: ast.PeerRef) -> None:
        src = self.source(peer.span)
        if src is None:
            return
        spans = [src.span(m.start(), m.end()) for m in
                 _NAME.finditer(src.text, peer.span.offset, peer.span.end_offset)]
        if len(spans) != len(peer.parts):
            return
        parts = list(zip(peer.parts, spans, strict=True))
        agents = {x.name: x for x in sd.agents}
        agent = a
        if parts[0][0] not in _LETTERS and parts[0][0] in agents and len(parts) >= 2:
            agent = agents[parts[0][0]]
            self.use(parts[0][1], f"agent:{system_id(sd)}/{agent.name}")
            parts = parts[1:]
        letter, letter_span = parts[0]
        if letter not in _LETTERS:
            return
        target: str | None = None
        rest = parts[1:]
        if letter == "c":
            control = next((s for s in agent.subsystems
                            if s.kind is ast.SubsystemKind.CONTROL), None)
            if control is None:
                return
            target = subsystem_key(system_id(sd), agent.name, control)
            self.use(letter_span, target)
        elif rest:
            name, name_span = rest[0]
            rest = rest[1:]
            if letter in ("E", "R"):
                inst = next((d for d in agent.devices if d.name == name
                             and _DEVICE_LETTER[d.kind.value] == letter), None)
                if inst is None:
                    return
                target = instance_key(system_id(sd), agent.name, inst)
                self.use(name_span, target)
                if rest and inst.device in self.device_types:
                    bkey = f"devbuf:{inst.device}.{rest[0][0]}"
                    if bkey in self.index.definitions:
                        self.use(rest[0][1], bkey)
                return
            sub = next((s for s in agent.subsystems if s.name == name
                        and s.kind is not ast.SubsystemKind.CONTROL
                        and _KIND_LETTER[s.kind.value] == letter), None)
            if sub is None:
                return
            target = subsystem_key(system_id(sd), agent.name, sub)
            self.use(name_span, target)
        if target is not None and rest:
            bkey = f"buf:{target[4:]}.{rest[0][0]}"
            if bkey in self.index.definitions:
                self.use(rest[0][1], bkey)


def build_index(program: Program) -> SymbolIndex:
    return IndexBuilder(program).build()


BUILTIN_NAMES: tuple[str, ...] = (*BUILTIN_FUNCTIONS, *BUILTIN_CONSTS)
