"""Where the cursor is, and which names it may use there with their types: what completion
and hover are computed from.

The enclosing declarations (system, agent, subsystem, behaviour, `update`, device) are found
in the *current* text by its braces (`locate`), then looked up by name in the analysis's AST
(`context`): the editor asks for completion right after a keystroke, before that text is
analysed, and while the text has a syntax error the parser could not recover from the AST is
an older text's; its offsets may then be off, its names are not.

The types are the semantic model's: the declaration pass (rssm_dsl.semantics.declarations)
resolves the program's types (aliases, records of imported modules), constants and external
operations once per analysed program (`env_of`), and the same pass resolves the declared
types of parameters, memory and buffers; a `let` value has the type the type checker gives
its value. Nothing here re-analyses the program for a request.
"""

from __future__ import annotations

import re
from collections.abc import Iterator
from dataclasses import field

from rssm_core.records import dataclass
from rssm_dsl.diagnostics import DiagnosticBag
from rssm_dsl.semantics.declarations import DeclarationPass, Globals
from rssm_dsl.semantics.loader import Program
from rssm_dsl.semantics.model import Agent, Extern, Subsystem, System
from rssm_dsl.semantics.typecheck import ExprChecker, Scope, Symbol, owner_symbols
from rssm_dsl.semantics.types import BOOL, ArrayT, RecordT, Type
from rssm_dsl.source import Span
from rssm_dsl.syntax import ast

# the braces, and what the brace scanner steps over: comments and strings (their braces are
# no blocks); what lies between is skipped in one go (a `/` alone is a division)
_TOKENS = re.compile(r'[^/"{}]*(//[^\n\r]*|/\*.*?(?:\*/|\Z)|"(?:\\.|[^"\\\n\r])*"?|[{}]|/)',
                     re.S)
_COMMENT = re.compile(r"//[^\n\r]*|/\*.*?(?:\*/|\Z)", re.S)
_HEADER = re.compile(
    r"(?<![A-Za-z0-9_.])(?:(?P<device>device)\s+)?"
    r"(?P<kind>system|agent|control|effector|receptor|behaviour|update|record|enum)"
    r"(?:\s+(?P<name>[A-Za-z_][A-Za-z0-9_]*))?"
    r"(?:\s*@\s*[0-9][0-9.eE+-]*\s*k?Hz)?\s*$")
_NAME_END = re.compile(r"[A-Za-z_][A-Za-z0-9_]*$")
SUBSYSTEM_KINDS = ("control", "effector", "receptor")


@dataclass(frozen=True)
class Block:
    """A `{ ... }` around the cursor: what declares it (`other` for a record literal or
    anything unknown) and its name (None for an unnamed control subsystem)."""

    kind: str
    name: str | None
    open: int          # the offset just after its `{`


@dataclass(frozen=True)
class Place:
    blocks: tuple[Block, ...]   # the blocks around the cursor, outermost first
    item_start: int             # just after the last brace before the cursor
    in_comment: bool            # in a comment or a string

    @property
    def inner(self) -> Block | None:
        """The innermost block that is a declaration (record literals are expressions)."""
        return next((b for b in reversed(self.blocks) if b.kind != "other"), None)

    def of(self, kind: str) -> Block | None:
        return next((b for b in self.blocks if b.kind == kind), None)


def blank_comments(text: str) -> str:
    """The text with its comments replaced by spaces (offsets are kept)."""
    return _COMMENT.sub(lambda m: re.sub(r"[^\n\r]", " ", m.group()), text)


def _header(text: str, start: int, brace: int) -> Block:
    head = blank_comments(text[max(start, brace - 2000):brace])
    m = _HEADER.search(head)
    if m is None:
        return Block("other", None, brace + 1)
    kind = "device" if m.group("device") else m.group("kind")
    return Block(kind, m.group("name"), brace + 1)


def _unclosed(tok: str) -> bool:
    """Is this comment or string token (cut at the cursor) still open there?"""
    if tok.startswith("//"):
        return True
    if tok.startswith("/*"):
        return not tok.endswith("*/") or len(tok) < 4
    return len(tok) == 1 or not tok.endswith('"') or tok.endswith('\\"')


def locate(text: str, offset: int) -> Place:
    """The blocks around `offset` in `text`, from its braces (comments and strings aside)."""
    stack: list[tuple[int, int]] = []     # (the end of the brace before it, its `{`)
    last = 0
    in_comment = False
    for m in _TOKENS.finditer(text, 0, offset):
        tok = m.group(1)
        if tok == "{":
            stack.append((last, m.start(1)))
            last = m.end()
        elif tok == "}":
            if stack:
                stack.pop()
            last = m.end()
        elif m.end() >= offset and tok != "/":
            in_comment = _unclosed(tok)
    return Place(tuple(_header(text, start, brace) for start, brace in stack), last,
                 in_comment)


# ---------------------------------------------------------------------- the cursor's declarations
@dataclass(frozen=True)
class Var:
    """A parameter, memory variable or buffer of a subsystem, with its type."""

    name: str
    kind: str                  # param | memory | input | output
    type: Type | None
    span: Span


@dataclass(frozen=True)
class Beh:
    name: str
    conditions: tuple[tuple[str, Span], ...]
    decl: ast.BehaviourDecl | None       # None: known from the semantic model only


@dataclass(frozen=True)
class Sub:
    """A designed subsystem, from the AST of the text or else from the last good semantic
    model (the AST of a text with a syntax error may have lost what follows the error)."""

    agent: str
    kind: str                  # control | effector | receptor
    name: str
    span: Span
    variables: tuple[Var, ...]
    behaviours: tuple[Beh, ...]

    def named(self, *kinds: str) -> list[str]:
        return [v.name for v in self.variables if v.kind in kinds]


@dataclass(frozen=True)
class Dev:
    """A device instance of an agent."""

    kind: str                  # effector | receptor
    name: str
    device: str                # its device type
    span: Span


@dataclass(frozen=True)
class AgentView:
    name: str
    subsystems: tuple[Sub, ...]
    devices: tuple[Dev, ...]


def sub_of_decl(env: Env, agent: str, s: ast.SubsystemDecl) -> Sub:
    variables = [Var(p.name, "param", env.resolve(p.type), p.span) for p in s.params]
    variables += [Var(m.name, "memory", env.resolve(m.type), m.span) for m in s.memory]
    variables += [Var(b.name, b.direction.value, env.resolve(b.type), b.span)
                  for b in s.buffers]
    behaviours = [Beh(b.name, tuple((c.name, c.span) for c in b.conditions), b)
                  for b in s.behaviours]
    return Sub(agent, s.kind.value, s.name, s.span, tuple(variables), tuple(behaviours))


def _sub_of_model(s: Subsystem) -> Sub:
    variables = [Var(p.name, "param", p.type, p.span) for p in s.params]
    variables += [Var(m.name, "memory", m.type, m.span) for m in s.memory]
    variables += [Var(b.name, b.direction.value, b.type, b.span)
                  for b in (*s.inputs, *s.outputs)]
    behaviours = [Beh(b.name, tuple((c.name, c.span) for c in b.conditions), None)
                  for b in s.behaviours]
    return Sub(s.agent, s.kind, "c" if s.kind == "control" else s.name, s.span,
               tuple(variables), tuple(behaviours))


def _agent_of_decl(env: Env, a: ast.AgentDecl) -> AgentView:
    return AgentView(a.name, tuple(sub_of_decl(env, a.name, s) for s in a.subsystems),
                     tuple(Dev(d.kind.value, d.name, d.device, d.span) for d in a.devices))


def _agent_of_model(a: Agent) -> AgentView:
    return AgentView(a.name, tuple(_sub_of_model(s) for s in a.subsystems),
                     tuple(Dev(d.kind, d.name, d.device_type, d.span) for d in a.devices))


@dataclass
class Context:
    """The declarations around the cursor: from the AST where it has them, else from the
    last good semantic model (None where neither has them)."""

    place: Place
    env: Env = field(default_factory=lambda: Env())
    model: System | None = None       # the last good semantic model
    system: ast.SystemDecl | None = None
    agent: AgentView | None = None
    sub: Sub | None = None
    behaviour: Beh | None = None
    update: ast.UpdateDecl | None = None

    def model_agents(self) -> list[Agent]:
        if self.model is None or (self.system is not None
                                  and self.model.name != self.system.name):
            return []
        return list(self.model.agents)

    def agent_view(self, name: str) -> AgentView | None:
        """An agent of the AST, completed by the model (the AST of a broken text may have
        lost some of it), or the model's alone."""
        decl = next((a for a in self.system.agents if a.name == name), None) \
            if self.system is not None else None
        old = next((a for a in self.model_agents() if a.name == name), None)
        if decl is None:
            return _agent_of_model(old) if old is not None else None
        mine = _agent_of_decl(self.env, decl)
        return _merged(mine, _agent_of_model(old)) if old is not None else mine

    def other_agents(self) -> list[AgentView]:
        """The other agents of the system, without the variables and behaviours of their
        subsystems (see `agent_view`)."""
        here = self.agent.name if self.agent is not None else None
        out = [AgentView(a.name, tuple(Sub(a.name, s.kind.value, s.name, s.span, (), ())
                                       for s in a.subsystems),
                         tuple(Dev(d.kind.value, d.name, d.device, d.span) for d in a.devices))
               for a in (self.system.agents if self.system is not None else ())
               if a.name != here]
        names = {a.name for a in out} | {here}
        out += [AgentView(a.name, tuple(Sub(a.name, s.kind, s.name, s.span, (), ())
                                        for s in a.subsystems),
                          tuple(Dev(d.kind, d.name, d.device_type, d.span) for d in a.devices))
                for a in self.model_agents() if a.name not in names]
        return out


def _subsystem(subs: tuple[Sub, ...], block: Block) -> Sub | None:
    same = [s for s in subs if s.kind == block.kind]
    if block.kind == "control":
        return next((s for s in same if s.name == block.name), same[0] if same else None)
    return next((s for s in same if s.name == block.name), None)


def _merged(mine: AgentView, old: AgentView) -> AgentView:
    """An agent of the AST, with the subsystems and devices only the model still has."""
    subs = {(s.kind, s.name) for s in mine.subsystems}
    devices = {d.name for d in mine.devices}
    return AgentView(mine.name,
                     mine.subsystems + tuple(s for s in old.subsystems
                                             if (s.kind, s.name) not in subs),
                     mine.devices + tuple(d for d in old.devices if d.name not in devices))


def context(module: ast.Module | None, place: Place, env: Env | None = None,
            model: System | None = None) -> Context:
    """The declarations around the cursor (`model`: the last good semantic model, for what
    the AST of a broken text lost)."""
    ctx = Context(place, env or Env(), model)
    systems = [d for d in module.decls if isinstance(d, ast.SystemDecl)] if module else []
    for block in place.blocks:
        if block.kind == "system":
            ctx.system = next((s for s in systems if s.name == block.name),
                              systems[0] if systems else None)
        elif block.kind == "agent" and block.name is not None:
            ctx.agent = ctx.agent_view(block.name)
        elif block.kind in SUBSYSTEM_KINDS and ctx.agent is not None:
            ctx.sub = _subsystem(ctx.agent.subsystems, block)
        elif block.kind == "behaviour" and ctx.sub is not None:
            ctx.behaviour = next((b for b in ctx.sub.behaviours if b.name == block.name),
                                 None)
        elif block.kind == "update" and ctx.behaviour is not None and \
                ctx.behaviour.decl is not None:
            ctx.update = next((u for u in ctx.behaviour.decl.updates
                               if u.target == block.name), None)
    return ctx


# ---------------------------------------------------------------------- types
@dataclass
class Env:
    """The program-wide names with their types: the declaration pass of the semantic model,
    run once per analysed program."""

    globals: Globals = field(default_factory=Globals)
    resolver: DeclarationPass | None = None

    @property
    def types(self) -> dict[str, Type]:
        return self.globals.types

    @property
    def externs(self) -> dict[str, Extern]:
        return self.globals.externs

    def resolve(self, t: ast.TypeExpr) -> Type | None:
        if self.resolver is None:
            return None
        try:
            return self.resolver.resolve_type(t)
        except Exception:   # a partial module's type: nothing to say about it
            return None

    def const_type(self, name: str) -> Type | None:
        c = self.globals.consts.get(name)
        return c.type if c is not None else None

    def base(self) -> dict[str, Symbol]:
        """The names every expression sees: the enums (for their members) and constants."""
        return self.globals.symbols()


_ENVS: list[tuple[Program, Env]] = []


def env_of(program: Program | None) -> Env:
    """The Env of a program (kept for the last few programs: one per open document)."""
    if program is None:
        return Env()
    for p, env in _ENVS:
        if p is program:
            return env
    dp = DeclarationPass(DiagnosticBag())
    try:
        g = dp.run(program.modules, program.root)
        env = Env(g, dp)
    except Exception:   # a partial module the pass cannot read: no types
        env = Env()
    _ENVS.insert(0, (program, env))
    del _ENVS[4:]
    return env


@dataclass(frozen=True)
class _Declared:
    name: str
    type: Type | None
    span: Span


@dataclass(frozen=True)
class _DeclaredBuffer(_Declared):
    direction: ast.Direction


def subsystem_symbols(env: Env, sub: Sub) -> dict[str, Symbol]:
    """The names the expressions of a subsystem see (as the behaviour pass builds them):
    constants and enums, then its parameters, memory variables and buffers."""
    return owner_symbols(
        env.base(),
        [_Declared(v.name, v.type, v.span) for v in sub.variables if v.kind == "param"],
        [_Declared(v.name, v.type, v.span) for v in sub.variables if v.kind == "memory"],
        [_DeclaredBuffer(v.name, v.type, v.span, ast.Direction(v.kind))
         for v in sub.variables if v.kind in ("input", "output")])


def _scope(env: Env, symbols: dict[str, Symbol]) -> Scope:
    return Scope(symbols, env.externs)


def type_of(env: Env, e: ast.Expr, scope: Scope) -> Type | None:
    """The type the type checker gives an expression (None when it has none)."""
    try:
        return ExprChecker(DiagnosticBag()).check(e, Scope(scope.symbols, scope.externs,
                                                            extra=dict(scope.extra)))
    except Exception:   # a partial module's expression
        return None


def locals_of(env: Env, symbols: dict[str, Symbol], body: tuple[ast.Stmt, ...],
              upto: int | None = None) -> dict[str, Symbol]:
    """The `let` values of a case body with their types (those before statement `upto`)."""
    scope = _scope(env, symbols)
    for st in body[:upto]:
        if isinstance(st, ast.Let) and st.name not in scope.extra:
            scope.extra[st.name] = Symbol("local", type_of(env, st.value, scope), st.span)
    return scope.extra


_CASE = re.compile(r"(?<![A-Za-z0-9_])(case|otherwise)(?![A-Za-z0-9_])")
_LET = re.compile(r"(?<![A-Za-z0-9_])let\s+([A-Za-z_][A-Za-z0-9_]*)")


def cursor_locals(env: Env, ctx: Context, symbols: dict[str, Symbol], text: str,
                  offset: int) -> dict[str, Symbol]:
    """The `let` values declared before the cursor in its case of an `update`: their names
    from the current text, their types from the AST's case (unknown for a new one)."""
    block = ctx.place.of("update")
    if block is None:
        return {}
    written = blank_comments(text[block.open:offset])
    labels = list(_CASE.finditer(written))
    body_start = labels[-1].end() if labels else 0
    names = [m.group(1) for m in _LET.finditer(written, body_start)]
    known: dict[str, Symbol] = {}
    if ctx.update is not None and ctx.update.cases:
        k = min(max(len(labels) - 1, 0), len(ctx.update.cases) - 1)
        known = locals_of(env, symbols, ctx.update.cases[k].body)
    out: dict[str, Symbol] = {}
    for name in names:
        out[name] = known.get(name) or Symbol("local", None, Span("", 1, 1, 1, 1, 0, 0))
    return out


# ---------------------------------------------------------------------- `a.b[i].`
@dataclass(frozen=True)
class Chain:
    """`root.f[i].g` before a dot: the root name, whether it is called (`f(...)`), and the
    accessors after it (a field name, or None for an index)."""

    root: str
    call: bool
    parts: tuple[str | None, ...]


def _skip_space(text: str, i: int) -> int:
    while i >= 0 and text[i] in " \t\r\n":
        i -= 1
    return i


def _match_back(text: str, close: int, opener: str, closer: str) -> int | None:
    depth = 0
    for i in range(close, max(-1, close - 4000), -1):
        ch = text[i]
        if ch == closer:
            depth += 1
        elif ch == opener:
            depth -= 1
            if depth == 0:
                return i
    return None


def chain_before(text: str, dot: int) -> Chain | None:
    """The chain that ends at the `.` at offset `dot` (None when what precedes is no name,
    e.g. a number)."""
    parts: list[str | None] = []
    i = dot
    while True:
        j = _skip_space(text, i - 1)
        if j < 0:
            return None
        ch = text[j]
        if ch == "]":
            k = _match_back(text, j, "[", "]")
            if k is None:
                return None
            parts.append(None)
            i = k
            continue
        if ch == ")":
            k = _match_back(text, j, "(", ")")
            if k is None:
                return None
            m = _NAME_END.search(text, max(0, k - 200), _skip_space(text, k - 1) + 1)
            if m is None or m.group()[0].isdigit():
                return None
            return Chain(m.group(), True, tuple(reversed(parts)))
        m = _NAME_END.search(text, max(0, j - 200), j + 1)
        if m is None:
            return None
        name = m.group()
        if name[0].isdigit() or (m.start() > 0 and text[m.start() - 1].isdigit()):
            return None
        p = _skip_space(text, m.start() - 1)
        if p >= 0 and text[p] == "." and not (p > 0 and text[p - 1] == "."):
            parts.append(name)
            i = p
            continue
        return Chain(name, False, tuple(reversed(parts)))


def walk(t: Type | None, parts: tuple[str | None, ...]) -> Type | None:
    """The type reached from `t` through field names and indexes."""
    for part in parts:
        if t is None:
            return None
        if part is None:
            t = t.element if isinstance(t, ArrayT) else None
        else:
            t = t.field(part) if isinstance(t, RecordT) else None
    return t


def chain_type(env: Env, chain: Chain, symbols: dict[str, Symbol]) -> Type | None:
    if chain.call:
        ext = env.externs.get(chain.root)
        root = ext.result if ext is not None else None
    else:
        sym = symbols.get(chain.root)
        root = sym.type if sym is not None else None
    return walk(root, chain.parts)


# ---------------------------------------------------------------------- the whole module
@dataclass(frozen=True)
class Seen:
    """An expression with the scope the type checker sees it in."""

    expr: ast.Expr
    scope: Scope


def _all(e: ast.Expr) -> Iterator[ast.Expr]:
    from rssm_dsl.syntax.walk import children
    stack = [e]
    while stack:
        x = stack.pop()
        yield x
        stack += children(x)


def _holds(span: Span, offset: int | None) -> bool:
    return offset is None or span.offset <= offset <= span.end_offset


def module_exprs(env: Env, module: ast.Module, at: int | None = None) -> Iterator[Seen]:
    """Every expression of a module (constants, and the subsystems of its system), each with
    the scope the type checker sees it in: `let` values before it in its case, the source
    behaviour's conditions in a switch. With `at`: those of the declaration at that offset
    only."""
    base = env.base()
    for d in module.decls:
        if isinstance(d, ast.ConstDecl) and _holds(d.span, at):
            yield Seen(d.value, _scope(env, base))
        if not isinstance(d, ast.SystemDecl) or not _holds(d.span, at):
            continue
        for a in d.agents:
            for s in a.subsystems:
                if _holds(s.span, at):
                    yield from _subsystem_exprs(env, s)


def _subsystem_exprs(env: Env, s: ast.SubsystemDecl) -> Iterator[Seen]:
    symbols = subsystem_symbols(env, sub_of_decl(env, "", s))
    plain = _scope(env, symbols)
    inits = [p.value for p in s.params] + [m.init for m in s.memory] + \
        [b.init for b in s.buffers]
    for init in inits:
        if init is not None:
            yield Seen(init, plain)
    for bd in s.behaviours:
        for u in bd.updates:
            for case in u.cases:
                if case.condition is not None:
                    yield Seen(case.condition, plain)
                for k, st in enumerate(case.body):
                    scope = _scope(env, symbols)
                    scope.extra.update(locals_of(env, symbols, case.body, k))
                    if isinstance(st, ast.Let):
                        yield Seen(st.value, scope)
                    elif isinstance(st, ast.Assign):
                        yield Seen(st.target, scope)
                        yield Seen(st.value, scope)
        for c in bd.conditions:
            yield Seen(c.expr, plain)
    for sw in s.switches:
        if sw.condition is None:
            continue
        scope = _scope(env, symbols)
        source = next((b for b in s.behaviours if b.name == sw.source), None)
        for c in source.conditions if source is not None else ():
            scope.extra[c.name] = Symbol("condition", BOOL, c.span)
        yield Seen(sw.condition, scope)


def field_span(x: ast.FieldAccess) -> tuple[int, int]:
    """The offsets of the field name of `x.field` (its last token)."""
    return x.span.end_offset - len(x.field), x.span.end_offset


def record_fields(env: Env, module: ast.Module) -> Iterator[tuple[ast.FieldAccess, RecordT]]:
    """Every `x.field` of a module whose `x` is a record, with that record type."""
    for seen in module_exprs(env, module):
        for x in _all(seen.expr):
            if isinstance(x, ast.FieldAccess):
                t = type_of(env, x.value, seen.scope)
                if isinstance(t, RecordT) and t.field(x.field) is not None:
                    yield x, t


def field_at(env: Env, module: ast.Module, offset: int
             ) -> tuple[ast.FieldAccess, RecordT] | None:
    """The record field access whose field name is under the cursor."""
    for seen in module_exprs(env, module, offset):
        if not seen.expr.span.offset <= offset <= seen.expr.span.end_offset:
            continue
        for x in _all(seen.expr):
            if isinstance(x, ast.FieldAccess):
                start, end = field_span(x)
                if start <= offset <= end:
                    t = type_of(env, x.value, seen.scope)
                    if isinstance(t, RecordT) and t.field(x.field) is not None:
                        return x, t
    return None


def local_type(env: Env, module: ast.Module, name: str, at: int) -> Type | None:
    """The type of the `let` value `name` declared by the statement at offset `at`."""
    for d in module.decls:
        if not isinstance(d, ast.SystemDecl):
            continue
        for a in d.agents:
            for s in a.subsystems:
                if not s.span.offset <= at <= s.span.end_offset:
                    continue
                for bd in s.behaviours:
                    for u in bd.updates:
                        for case in u.cases:
                            for k, st in enumerate(case.body):
                                if isinstance(st, ast.Let) and st.name == name and \
                                        st.span.offset <= at <= st.span.end_offset:
                                    symbols = subsystem_symbols(env, sub_of_decl(env, "", s))
                                    return type_of(env, st.value, _scope(
                                        env, {**symbols, **locals_of(env, symbols,
                                                                     case.body, k)}))
    return None


def field_uses(env: Env, modules: list[ast.Module], key: str) -> list[Span]:
    """The spans of the field names of the uses of `key` (`field:Record.name`) as `x.name`
    in these modules."""
    record, _, name = key.removeprefix("field:").partition(".")
    out: list[Span] = []
    for module in modules:
        for x, t in record_fields(env, module):
            if t.name == record and x.field == name:
                start, end = field_span(x)
                out.append(Span(x.span.file, 1, 1, 1, 1, start, end))
    return out
