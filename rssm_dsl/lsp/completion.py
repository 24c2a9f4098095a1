"""Completion: keywords and the names in scope at the cursor, narrowed by the word before it
(`from`/`to` -> peers, `:` -> types, `initial`/`->` -> behaviours, `update` -> outputs and
memory, `send`/`receive` -> buffers, `new(` -> inputs, `Phase.` -> the members of the enum
Phase; in a property, `AGENT.SUB in` -> the
behaviours of SUB, `AGENT.` -> its subsystems, `AGENT.SUB.` -> the variables of SUB)."""

from __future__ import annotations

import re

from lsprotocol import types as lsp

from rssm_dsl.lsp.index import SymbolIndex, block_close
from rssm_dsl.lsp.positions import line_start
from rssm_dsl.semantics.typecheck import BUILTIN_CONSTS, BUILTIN_FUNCTIONS
from rssm_dsl.semantics.types import SCALARS
from rssm_dsl.syntax import ast
from rssm_dsl.syntax.format import keywords

CK = lsp.CompletionItemKind
_TRIGGER = re.compile(r"([A-Za-z_][A-Za-z0-9_]*|->|:=|:|\(|\.)$")
_KIND = {"buf": CK.Field, "mem": CK.Variable, "param": CK.Constant, "const": CK.Constant,
         "extern": CK.Function, "type": CK.Struct, "beh": CK.Method, "cond": CK.Event,
         "local": CK.Variable, "device": CK.Interface}


def _item(label: str, kind: lsp.CompletionItemKind, detail: str | None = None,
          sort: str = "5") -> lsp.CompletionItem:
    return lsp.CompletionItem(label=label, kind=kind, detail=detail, sort_text=f"{sort}{label}")


def _enclosing(module: ast.Module | None, text: str, offset: int
               ) -> tuple[ast.SystemDecl | None, ast.AgentDecl | None, ast.SubsystemDecl | None,
                          ast.BehaviourDecl | None]:
    if module is None:
        return None, None, None, None

    def inside(node: ast.SystemDecl | ast.AgentDecl | ast.SubsystemDecl | ast.BehaviourDecl
               ) -> bool:
        start = min(node.span.offset, node.name_span.offset)
        return start <= offset < block_close(text, node.name_span.end_offset)

    for d in module.decls:
        if isinstance(d, ast.SystemDecl) and inside(d):
            for a in d.agents:
                if inside(a):
                    for s in a.subsystems:
                        if inside(s):
                            b = next((bd for bd in s.behaviours if inside(bd)), None)
                            return d, a, s, b
                    return d, a, None, None
            return d, None, None, None
    return None, None, None, None


def _peers(agent: ast.AgentDecl, system: ast.SystemDecl,
           sub: ast.SubsystemDecl) -> list[lsp.CompletionItem]:
    from rssm_dsl.lsp.index import _DEVICE_LETTER, _KIND_LETTER
    out: list[lsp.CompletionItem] = []
    for s in agent.subsystems:
        if s is sub:
            continue
        label = "c" if s.kind is ast.SubsystemKind.CONTROL else \
            f"{_KIND_LETTER[s.kind.value]}.{s.name}"
        out.append(_item(label, CK.Class, f"{s.kind.value} subsystem", "1"))
    for d in agent.devices:
        out.append(_item(f"{_DEVICE_LETTER[d.kind.value]}.{d.name}", CK.Interface,
                         f"real {d.kind.value}: {d.device}", "1"))
    if sub.kind is ast.SubsystemKind.CONTROL:
        for other in system.agents:
            if other is not agent:
                out.append(_item(f"{other.name}.c", CK.Class, "control subsystem of another "
                                 "agent", "2"))
    return out


def complete(module: ast.Module | None, index: SymbolIndex, text: str,
             offset: int) -> list[lsp.CompletionItem]:
    before = re.sub(r"[A-Za-z_][A-Za-z0-9_]*$", "", text[line_start(text, offset):offset]).rstrip()
    m = _TRIGGER.search(before)
    trigger = m.group(1) if m else ""
    members = _enum_members(index, before) if trigger == "." else None
    if members:
        return members
    system, agent, sub, behaviour = _enclosing(module, text, offset)
    items: list[lsp.CompletionItem] = []
    if sub is not None and agent is not None and system is not None:
        narrowed = _narrowed(trigger, before, system, agent, sub)
        if narrowed is not None:
            return narrowed
        items += _local(module, index, offset, sub, behaviour)
    elif system is not None and agent is None:     # between the agents: a property
        narrowed = _property(trigger, before, system)
        if narrowed is not None:
            return narrowed
        items += [_item(a.name, CK.Module, "agent", "1") for a in system.agents]
    type_only = trigger == ":"
    items += _global(index, type_only)
    if type_only:
        return [i for i in items if i.kind in (CK.Struct, CK.TypeParameter, CK.Interface)]
    for fn in BUILTIN_FUNCTIONS:
        items.append(_item(fn, CK.Function, "built-in function", "4"))
    for const in BUILTIN_CONSTS:
        items.append(_item(const, CK.Constant, "built-in constant", "4"))
    for kw in sorted(keywords()):
        items.append(_item(kw, CK.Keyword, None, "6"))
    seen: set[str] = set()
    unique: list[lsp.CompletionItem] = []
    for it in items:
        if it.label not in seen:
            seen.add(it.label)
            unique.append(it)
    return unique


def _enum_members(index: SymbolIndex, before: str) -> list[lsp.CompletionItem] | None:
    """After `Phase.`: the members of the enum Phase (None when the name is no enum)."""
    m = re.search(r"([A-Za-z_][A-Za-z0-9_]*)\s*\.$", before)
    if m is None:
        return None
    enum = index.definitions.get(f"type:{m.group(1)}")
    if enum is None or enum.kind != "enum":
        return None
    return [_item(d.name, CK.EnumMember, d.detail, "1") for d in index.children(enum.key)]


def _narrowed(trigger: str, before: str, system: ast.SystemDecl, agent: ast.AgentDecl,
              sub: ast.SubsystemDecl) -> list[lsp.CompletionItem] | None:
    """What the word before the cursor asks for inside a subsystem (None: anything)."""
    if trigger in ("from", "to"):
        return _peers(agent, system, sub)
    if trigger in ("initial", "switch", "->"):
        out = [_item(b.name, CK.Method, "behaviour", "1") for b in sub.behaviours]
        if trigger == "->":
            out.append(_item("end", CK.Keyword, "the subsystem ends", "2"))
        return out
    inputs = [b.name for b in sub.buffers if b.direction is ast.Direction.INPUT]
    outputs = [b.name for b in sub.buffers if b.direction is ast.Direction.OUTPUT]
    if trigger == "update":
        return [_item(o, CK.Field, "output buffer", "1") for o in outputs] + \
            [_item("memory", CK.Keyword, "the memory partial function", "2")]
    if trigger == "send":
        return [_item(o, CK.Field, "output buffer", "1") for o in outputs]
    if trigger == "receive" or (trigger == "(" and before.endswith("new(")):
        return [_item(i, CK.Field, "input buffer", "1") for i in inputs]
    return None


_SUBJECT = re.compile(r"([A-Za-z_][A-Za-z0-9_]*)\s*\.\s*([A-Za-z_][A-Za-z0-9_]*)\s+in$")
_DOTTED = re.compile(r"(?<![A-Za-z0-9_.])([A-Za-z_][A-Za-z0-9_]*)"
                     r"(?:\s*\.\s*([A-Za-z_][A-Za-z0-9_]*))?\s*\.$")


def _property_subsystem(system: ast.SystemDecl, agent: str, name: str
                        ) -> ast.SubsystemDecl | None:
    a = next((x for x in system.agents if x.name == agent), None)
    if a is None:
        return None
    if name == "c":
        control = next((s for s in a.subsystems if s.kind is ast.SubsystemKind.CONTROL), None)
        if control is not None:
            return control
    return next((s for s in a.subsystems if s.name == name), None)


def _property(trigger: str, before: str, system: ast.SystemDecl
              ) -> list[lsp.CompletionItem] | None:
    """In a property: the behaviours after `AGENT.SUB in`, the subsystems after `AGENT.`,
    the variables after `AGENT.SUB.` (None: anything)."""
    if trigger == "in":
        m = _SUBJECT.search(before)
        sub = _property_subsystem(system, m.group(1), m.group(2)) if m else None
        if sub is None:
            return None
        return [_item(b.name, CK.Method, "behaviour", "1") for b in sub.behaviours]
    if trigger != ".":
        return None
    m = _DOTTED.search(before)
    if m is None:
        return None
    if m.group(2) is None:
        agent = next((a for a in system.agents if a.name == m.group(1)), None)
        if agent is None:
            return None
        return [_item("c" if s.kind is ast.SubsystemKind.CONTROL else s.name, CK.Class,
                      f"{s.kind.value} subsystem", "1") for s in agent.subsystems]
    sub = _property_subsystem(system, m.group(1), m.group(2))
    if sub is None:
        return None
    from rssm_dsl.lsp.index import _type_text
    out = [_item(v.name, CK.Variable, f"memory: {_type_text(v.type)}", "1") for v in sub.memory]
    out += [_item(b.name, CK.Field, f"{b.direction.value}: {_type_text(b.type)}", "1")
            for b in sub.buffers]
    out += [_item(p.name, CK.Constant, f"param: {_type_text(p.type)}", "2") for p in sub.params]
    return out


def _local(module: ast.Module | None, index: SymbolIndex, offset: int, sub: ast.SubsystemDecl,
           behaviour: ast.BehaviourDecl | None) -> list[lsp.CompletionItem]:
    """The names in scope at the cursor and the conditions it can name."""
    items: list[lsp.CompletionItem] = []
    scope = index.scope_at(module.path if module else "", offset)
    for name, key in (scope.names.items() if scope else ()):
        d = index.definitions.get(key)
        items.append(_item(name, _KIND.get(key.split(":")[0], CK.Variable),
                           d.detail if d else None, "1"))
    if behaviour is not None:
        for c in behaviour.conditions:
            items.append(_item(c.name, CK.Event, f"{c.kind} condition", "2"))
    for sw in sub.switches:
        if sw.span.offset <= offset <= sw.span.end_offset:
            src = next((b for b in sub.behaviours if b.name == sw.source), None)
            if src is not None:
                for cd in src.conditions:
                    items.append(_item(cd.name, CK.Event,
                                       f"{cd.kind} condition of {src.name}", "1"))
    return items


def _global(index: SymbolIndex, type_only: bool) -> list[lsp.CompletionItem]:
    """Types, devices, constants and external operations of the whole program."""
    items: list[lsp.CompletionItem] = []
    for key, d in index.definitions.items():
        prefix = key.split(":")[0]
        if prefix == "type" or (prefix in ("const", "extern") and not type_only):
            items.append(_item(d.name, _KIND[prefix], d.detail, "3"))
        elif prefix == "device":
            items.append(_item(d.name, CK.Interface, d.detail, "3"))
    for name in SCALARS:
        items.append(_item(name, CK.TypeParameter, "built-in type", "3"))
    return items
