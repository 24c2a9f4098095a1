"""Completion from the semantic model, at the place of the cursor in the current text
(scope.py finds it, and the names there with their types):

- after `x.`, `a.b.`, `a[i].`, `f(...).`: the fields of the record the expression is (with
  their types); after `Phase.`: the members of the enum Phase;
- in a behaviour: the names in scope there: the subsystem's parameters, memory and buffers,
  the `let` values before the cursor in its case, constants, external operations, built-ins
  (and, in a switch condition, the source behaviour's conditions); never another
  subsystem's names;
- after `switch`, `initial`, `->`: the behaviours of the subsystem (`end` after `->`);
- after `from`/`to` in a buffer declaration: the peers the structure allows this subsystem
  (the channel pass's rule), then after `e.`, `AGENT.`, `PEER.` the rest of the peer and
  the peer's buffers of the other direction;
- after `update`, `send`, `receive`, `new(`: the subsystem's outputs (and memory), outputs,
  inputs; after `:` in a declaration: the types;
- where a declaration may start: snippets of a behaviour (in a subsystem) and of a control
  subsystem (in an agent without one), a virtual effector and a virtual receptor (in an
  agent);
- in a property: the behaviours after `AGENT.SUB in`, the subsystems after `AGENT.`, the
  variables after `AGENT.SUB.`, the fields after `AGENT.SUB.VAR.`."""

from __future__ import annotations

import re

from lsprotocol import types as lsp

from rssm_dsl.lsp.index import SymbolIndex
from rssm_dsl.lsp.positions import line_start
from rssm_dsl.lsp.scope import (
    SUBSYSTEM_KINDS,
    Beh,
    Context,
    Dev,
    Env,
    Sub,
    blank_comments,
    chain_before,
    chain_type,
    context,
    cursor_locals,
    env_of,
    locate,
    sub_of_decl,
    subsystem_symbols,
    walk,
)
from rssm_dsl.semantics.loader import Program
from rssm_dsl.semantics.model import System
from rssm_dsl.semantics.typecheck import BUILTIN_CONSTS, BUILTIN_FUNCTIONS, Symbol
from rssm_dsl.semantics.types import BOOL, EnumT, RecordT, Type
from rssm_dsl.syntax import ast
from rssm_dsl.syntax.format import keywords

CK = lsp.CompletionItemKind
_TRIGGER = re.compile(r"([A-Za-z_][A-Za-z0-9_]*|->|:=|:|\(|\.)$")
_WORD = re.compile(r"[A-Za-z_][A-Za-z0-9_]*$")
_KIND = {"buf": CK.Field, "mem": CK.Variable, "param": CK.Constant, "const": CK.Constant,
         "extern": CK.Function, "type": CK.Struct, "beh": CK.Method, "cond": CK.Event,
         "local": CK.Variable, "device": CK.Interface}
# a symbol's kind (typecheck.Symbol) -> the item's kind, its order and what it is called
_SYMBOL = {"local": (CK.Variable, "0", "let"), "param": (CK.Constant, "1", "param"),
           "memory": (CK.Variable, "1", "memory"), "input": (CK.Field, "1", "input"),
           "output": (CK.Field, "1", "output"), "condition": (CK.Event, "1", "condition"),
           "const": (CK.Constant, "3", "constant"), "enum": (CK.Enum, "3", "enum")}
# words after which a declaration goes on: no new declaration starts there
_GOES_ON = frozenset({
    "when", "to", "from", "then", "else", "and", "or", "not", "switch", "initial",
    "behaviour", "update", "param", "memory", "input", "output", "terminal", "error", "send",
    "receive", "let", "case", "if", "in", "always", "whenever", "eventually", "agent",
    "system", "control", "effector", "receptor", "real", "device", "record", "enum", "type",
    "const", "extern", "import", "property", "binding"})
_ITEM = re.compile(r"(?<![A-Za-z0-9_])(param|memory|input|output|initial|switch)"
                   r"(?![A-Za-z0-9_])")
_SWITCH = re.compile(r"switch\s+([A-Za-z_][A-Za-z0-9_]*)\s*->\s*[A-Za-z_][A-Za-z0-9_]*"
                     r"\s+when(?![A-Za-z0-9_])")
_PEER_DOT = re.compile(r"(?<![A-Za-z0-9_.])(?:from|to)\s+([A-Za-z_][A-Za-z0-9_]*"
                       r"(?:\s*\.\s*[A-Za-z_][A-Za-z0-9_]*)*)\s*\.$")

# The skeletons (LSP snippet syntax: ${N:default} is a placeholder, repeated ones change
# together). Each parses where it is offered (tests/lsp/test_completion_semantic.py).
BEHAVIOUR_SNIPPET = """behaviour ${1:name} {
  update ${2:memory} {
    ${3:skip}
  }
  terminal ${4:done} when ${5:false}
}"""
SUBSYSTEM_SNIPPETS = {
    "control": """control ${1:c} @ ${2:10} Hz {
  memory ${3:count}: int = 0

  behaviour ${4:run} {
    update memory {
      ${3:count} := ${3:count} + 1
    }
    terminal ${5:done} when ${3:count} >= ${6:10}
  }

  initial ${4:run}
  switch ${4:run} -> end when ${5:done}
}""",
    "effector": """effector ${1:name} @ ${2:100} Hz {
  input ${3:command}: ${4:float} from c
  output ${5:drive}: ${4:float} to E.${6:motors}

  behaviour ${7:relay} {
    update ${5:drive} {
      ${5:drive} := ${3:command}
    }
    terminal never when false
  }

  initial ${7:relay}
}""",
    "receptor": """receptor ${1:name} @ ${2:100} Hz {
  input ${3:raw}: ${4:float} from R.${5:camera}
  output ${6:reading}: ${4:float} to c

  behaviour ${7:relay} {
    update ${6:reading} {
      ${6:reading} := ${3:raw}
    }
    terminal never when false
  }

  initial ${7:relay}
}""",
}
_SNIPPET_DETAIL = {
    "behaviour": "behaviour skeleton: an update, a terminal condition",
    "control": "control subsystem skeleton: memory, a behaviour, initial, switch",
    "effector": "virtual effector skeleton: input from c, output to a real effector",
    "receptor": "virtual receptor skeleton: input from a real receptor, output to c",
}


def _item(label: str, kind: lsp.CompletionItemKind, detail: str | None = None,
          sort: str = "5") -> lsp.CompletionItem:
    return lsp.CompletionItem(label=label, kind=kind, detail=detail, sort_text=f"{sort}{label}")


def _snippet(label: str, body: str) -> lsp.CompletionItem:
    return lsp.CompletionItem(label=label, kind=CK.Snippet, detail=_SNIPPET_DETAIL[label],
                              insert_text=body, filter_text=label,
                              insert_text_format=lsp.InsertTextFormat.Snippet,
                              sort_text=f"2{label}")


def complete(module: ast.Module | None, index: SymbolIndex, text: str, offset: int,
             program: Program | None = None, system: System | None = None
             ) -> list[lsp.CompletionItem]:
    """The items at `offset` of `text` (the current text: `module`, `index` and `program`
    may be of an older one)."""
    place = locate(text, offset)
    if place.in_comment:
        return []
    line = text[line_start(text, offset):offset]
    word = _WORD.search(line)
    word_start = offset - (len(word.group()) if word else 0)
    before = line[:len(line) - (len(word.group()) if word else 0)].rstrip()
    m = _TRIGGER.search(before)
    trigger = m.group(1) if m else ""
    env = env_of(program)
    ctx = context(module if module is not None else program.root if program else None, place,
                  env, system)
    if trigger == ".":
        return _after_dot(ctx, env, index, text, before, word_start)
    inner = place.inner.kind if place.inner is not None else ""
    if ctx.sub is not None and ctx.agent is not None:
        narrowed = _narrowed(trigger, before, ctx)
        if narrowed is not None:
            return narrowed
    elif ctx.system is not None and inner == "system":     # between the agents: a property
        narrowed = _property(trigger, before, ctx.system)
        if narrowed is not None:
            return narrowed
    type_only = trigger == ":" and inner not in ("update", "behaviour") and \
        not (place.blocks and place.blocks[-1].kind == "other")
    items: list[lsp.CompletionItem] = []
    if not type_only:
        items += _snippets(ctx, text, word_start, line, inner)
        if ctx.sub is not None:
            items += _names(_scope_names(ctx, env, text, word_start))
        elif ctx.system is not None and inner == "system":
            items += [_item(a.name, CK.Module, "agent", "1") for a in ctx.system.agents]
    items += _global(index, "types" if type_only else "values" if ctx.sub else "all")
    if type_only:
        return [i for i in items if i.kind in (CK.Struct, CK.TypeParameter, CK.Interface)]
    return _with_builtins(items)


def _with_builtins(items: list[lsp.CompletionItem]) -> list[lsp.CompletionItem]:
    """The items, then the built-in functions and constants and the keywords, each once."""
    for fn in BUILTIN_FUNCTIONS:
        items.append(_item(fn, CK.Function, "built-in function", "4"))
    for const in BUILTIN_CONSTS:
        items.append(_item(const, CK.Constant, "built-in constant", "4"))
    for kw in sorted(keywords()):
        items.append(_item(kw, CK.Keyword, None, "6"))
    seen: set[tuple[str, bool]] = set()
    unique: list[lsp.CompletionItem] = []
    for it in items:
        key = (it.label, it.kind is CK.Snippet)
        if key not in seen:
            seen.add(key)
            unique.append(it)
    return unique


# ---------------------------------------------------------------------- names in scope
def _scope_names(ctx: Context, env: Env, text: str, offset: int) -> dict[str, Symbol]:
    """The names an expression at the cursor may use (a subsystem's)."""
    assert ctx.sub is not None
    symbols = subsystem_symbols(env, ctx.sub)
    out = dict(cursor_locals(env, ctx, symbols, text, offset))
    out.update({k: v for k, v in symbols.items() if k not in out})
    source = _switch_source(ctx, text, offset)
    if source is not None:
        for name, span in source.conditions:
            out.setdefault(name, Symbol("condition", BOOL, span))
    return out


def _switch_source(ctx: Context, text: str, offset: int) -> Beh | None:
    """The source behaviour of the switch whose condition the cursor is in."""
    inner = ctx.place.inner
    if ctx.sub is None or inner is None or inner.kind not in SUBSYSTEM_KINDS:
        return None
    segment = blank_comments(text[ctx.place.item_start:offset])
    items = list(_ITEM.finditer(segment))
    if not items or items[-1].group(1) != "switch":
        return None
    m = _SWITCH.match(segment, items[-1].start())
    if m is None:
        return None
    return next((b for b in ctx.sub.behaviours if b.name == m.group(1)), None)


def _names(symbols: dict[str, Symbol]) -> list[lsp.CompletionItem]:
    items: list[lsp.CompletionItem] = []
    for name, sym in symbols.items():
        kind, sort, what = _SYMBOL.get(sym.kind, (CK.Variable, "1", sym.kind))
        detail = f"{what}: {sym.type}" if sym.type is not None and sym.kind != "enum" \
            else what
        items.append(_item(name, kind, detail, sort))
    return sorted(items, key=lambda i: (i.sort_text or "")[:1])


# ---------------------------------------------------------------------- after a dot
def _after_dot(ctx: Context, env: Env, index: SymbolIndex, text: str, before: str,
               word_start: int) -> list[lsp.CompletionItem]:
    dot = len(text[:word_start].rstrip()) - 1
    peer = _PEER_DOT.search(before)
    if peer is not None and ctx.sub is not None:
        return _peer_path(ctx, env, [p.strip() for p in peer.group(1).split(".")], before)
    inner = ctx.place.inner.kind if ctx.place.inner is not None else ""
    chain = chain_before(text, dot)
    if ctx.system is not None and inner == "system":
        if chain is not None and not chain.call and len(chain.parts) >= 2 \
                and None not in chain.parts[:2]:
            return _fields(index, walk(_property_variable(env, ctx.system, chain.root,
                                                          chain.parts), chain.parts[2:]))
        return _property(".", before, ctx.system) or []
    if chain is None:
        return []
    if ctx.sub is not None:
        symbols = _scope_names(ctx, env, text, dot)
    else:
        symbols = env.base()
    sym = symbols.get(chain.root)
    if not chain.call and not chain.parts and (sym is None or sym.kind == "enum"):
        members = _enum_members(index, chain.root, sym.type if sym is not None else None)
        if members is not None:
            return members
    return _fields(index, chain_type(env, chain, symbols))


def _fields(index: SymbolIndex, t: Type | None) -> list[lsp.CompletionItem]:
    """The fields of a record type, in their order, with their types."""
    if not isinstance(t, RecordT):
        return []
    out: list[lsp.CompletionItem] = []
    for k, (name, ft) in enumerate(t.fields):
        d = index.definitions.get(f"field:{t.name}.{name}")
        written = d.detail.partition(":")[2].strip() if d is not None else ""
        detail = str(ft) if not written or written == str(ft) else f"{written} = {ft}"
        out.append(lsp.CompletionItem(label=name, kind=CK.Field, detail=detail,
                                      sort_text=f"1{k:04d}"))
    return out


def _enum_members(index: SymbolIndex, name: str, t: Type | None
                  ) -> list[lsp.CompletionItem] | None:
    """After `Phase.`: the members of the enum Phase (None when the name is no enum)."""
    enum = index.definitions.get(f"type:{name}")
    if enum is not None and enum.kind == "enum":
        return [_item(d.name, CK.EnumMember, d.detail, "1") for d in index.children(enum.key)]
    if isinstance(t, EnumT):
        return [lsp.CompletionItem(label=x, kind=CK.EnumMember, detail=f"{t.name}.{x}",
                                   sort_text=f"1{k:04d}") for k, x in enumerate(t.members)]
    return None


# ---------------------------------------------------------------------- peers
def _allowed(ctx: Context) -> list[tuple[str, str, Sub | Dev]]:
    """The peers the structure allows the subsystem at the cursor (the channel pass's rule,
    paper III-A): (how it names each, what it is, the peer)."""
    from rssm_dsl.semantics.channels import _link_allowed
    from rssm_dsl.semantics.model import DEVICE_LETTER, KIND_LETTER
    from rssm_dsl.semantics.structure import Shell

    sub, agent = ctx.sub, ctx.agent
    assert sub is not None and agent is not None
    me = Shell(agent.name, sub.kind, sub.name, False, sub.span, None)
    out: list[tuple[str, str, Sub | Dev]] = []
    for a in (agent, *ctx.other_agents()):
        prefix = "" if a is agent else f"{a.name}."
        for s in a.subsystems:
            if (s.kind, s.name) == (sub.kind, sub.name) and a is agent:
                continue
            if not _link_allowed(me, Shell(a.name, s.kind, s.name, False, s.span, None)):
                continue
            label = "c" if s.kind == "control" else f"{KIND_LETTER[s.kind]}.{s.name}"
            what = f"{s.kind} subsystem" + ("" if a is agent else " of another agent")
            out.append((prefix + label, what, s))
        for d in a.devices:
            if _link_allowed(me, Shell(a.name, d.kind, d.name, True, d.span, None)):
                out.append((f"{prefix}{DEVICE_LETTER[d.kind]}.{d.name}",
                            f"real {d.kind}: {d.device}", d))
    return out


def _peers(ctx: Context) -> list[lsp.CompletionItem]:
    out: list[lsp.CompletionItem] = []
    for label, what, decl in _allowed(ctx):
        kind = CK.Interface if isinstance(decl, Dev) else CK.Class
        out.append(_item(label, kind, what, "2" if what.endswith("another agent") else "1"))
    return out


def _peer_path(ctx: Context, env: Env, parts: list[str], before: str
               ) -> list[lsp.CompletionItem]:
    """After `to e.`, `to AGENT.`: the rest of the allowed peers; after `to PEER.`: the
    peer's buffers of the other direction."""
    out: list[lsp.CompletionItem] = []
    seen: set[str] = set()
    for label, what, decl in _allowed(ctx):
        names = label.split(".")
        if names[:len(parts)] != parts:
            continue
        if len(names) > len(parts):
            nxt = names[len(parts)]
            if nxt not in seen:
                seen.add(nxt)
                kind = CK.Interface if isinstance(decl, Dev) else CK.Class
                out.append(_item(nxt, kind, what if len(names) == len(parts) + 1 else None,
                                 "1"))
            continue
        items = list(_ITEM.finditer(blank_comments(before)))
        declaring = items[-1].group(1) if items else ""
        buffers: list[tuple[str, str]] = []
        if isinstance(decl, Sub):
            if ctx.agent is not None and decl.agent != ctx.agent.name:
                decl = _full(ctx, decl)    # another agent's: its variables too
            buffers = [(v.name, v.kind) for v in decl.variables if v.kind in ("input",
                                                                              "output")]
        else:
            device = env.globals.devices.get(decl.device)
            buffers = [(b.name, b.direction.value) for b in device.buffers] if device else []
        for name, direction in buffers:
            if direction != declaring:
                out.append(_item(name, CK.Field, f"{direction} of {label}", "1"))
    return out


def _full(ctx: Context, sub: Sub) -> Sub:
    agent = ctx.agent_view(sub.agent)
    subs = agent.subsystems if agent is not None else ()
    return next((x for x in subs if (x.kind, x.name) == (sub.kind, sub.name)), sub)


# ---------------------------------------------------------------------- narrowed
def _narrowed(trigger: str, before: str, ctx: Context) -> list[lsp.CompletionItem] | None:
    """What the word before the cursor asks for inside a subsystem (None: anything)."""
    sub = ctx.sub
    assert sub is not None
    if trigger in ("from", "to"):
        return _peers(ctx)
    if trigger in ("initial", "switch", "->"):
        out = [_item(b.name, CK.Method, "behaviour", "1") for b in sub.behaviours]
        if trigger == "->":
            out.append(_item("end", CK.Keyword, "the subsystem ends", "2"))
        return out
    inputs, outputs = sub.named("input"), sub.named("output")
    if trigger == "update":
        return [_item(o, CK.Field, "output buffer", "1") for o in outputs] + \
            [_item("memory", CK.Keyword, "the memory partial function", "2")]
    if trigger == "send":
        return [_item(o, CK.Field, "output buffer", "1") for o in outputs]
    if trigger == "receive" or (trigger == "(" and before.endswith("new(")):
        return [_item(i, CK.Field, "input buffer", "1") for i in inputs]
    return None


# ---------------------------------------------------------------------- snippets
def _starts_item(text: str, item_start: int, word_start: int, line: str, word: str) -> bool:
    """May a declaration start at the cursor: first on its line, after a complete one?"""
    if line[:len(line) - len(word)].strip():
        return False
    prev = blank_comments(text[item_start:word_start]).rstrip()
    if not prev:
        return True
    last = _WORD.search(prev)
    if last is not None:
        return last.group() not in _GOES_ON
    return prev[-1] in ')]"'


def _snippets(ctx: Context, text: str, word_start: int, line: str, inner: str
              ) -> list[lsp.CompletionItem]:
    """The skeletons of the declarations that may start at the cursor."""
    if inner not in (*SUBSYSTEM_KINDS, "agent"):
        return []
    word = _WORD.search(line)
    if not _starts_item(text, ctx.place.item_start, word_start, line,
                        word.group() if word else ""):
        return []
    if inner != "agent":
        return [_snippet("behaviour", BEHAVIOUR_SNIPPET)]
    has_control = ctx.agent is not None and any(
        s.kind == "control" for s in ctx.agent.subsystems)
    return [_snippet(kind, body) for kind, body in SUBSYSTEM_SNIPPETS.items()
            if not (kind == "control" and has_control)]


# ---------------------------------------------------------------------- properties
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


def _property_variable(env: Env, system: ast.SystemDecl, agent: str,
                       parts: tuple[str | None, ...]) -> Type | None:
    """The type of `AGENT.SUB.NAME` in a property."""
    sub = _property_subsystem(system, agent, parts[0] or "")
    if sub is None:
        return None
    sym = subsystem_symbols(env, sub_of_decl(env, agent, sub)).get(parts[1] or "")
    return sym.type if sym is not None and sym.kind in ("param", "memory", "input",
                                                        "output") else None


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


# ---------------------------------------------------------------------- program-wide
def _global(index: SymbolIndex, what: str) -> list[lsp.CompletionItem]:
    """Types, devices, constants and external operations of the whole program: `types`
    (after `:`), `values` (in a subsystem: no device types), or `all`."""
    from rssm_dsl.semantics.types import SCALARS
    items: list[lsp.CompletionItem] = []
    for key, d in index.definitions.items():
        prefix = key.split(":")[0]
        if prefix == "type" or (prefix in ("const", "extern") and what != "types"):
            items.append(_item(d.name, _KIND[prefix], d.detail, "3"))
        elif prefix == "device" and what != "values":
            items.append(_item(d.name, CK.Interface, d.detail, "3"))
    for name in SCALARS:
        items.append(_item(name, CK.TypeParameter, "built-in type", "3"))
    return items
