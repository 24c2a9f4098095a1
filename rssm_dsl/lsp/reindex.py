"""The symbol index of an edited text made from the index of the text before it.

An edit the incremental analysis reparses stays inside one agent (rssm_dsl.lsp.incremental).
Its index is the previous one with that agent indexed again: the agent's definitions,
occurrences, scopes and links are replaced by those of the reparsed agent, and what follows
the agent moves by the edit's size (whole lines: the next declaration starts on a later line,
so columns do not change).

This is exact when the agent's declarations are the same as before (the same keys, with the
same kind, detail and container): nothing else in the index depends on the agent's text then.
Another agent's peer reference is resolved through keys, a property reads the declared types,
which are in the details. When they differ (a buffer added, renamed or retyped...), or the
agent's name is not unique, :func:`reindex` gives None and the caller indexes the whole text.

Several edits made before anything asked for the index are applied at once: one per agent
edited (edits of different agents do not interfere), and what lies between the edited agents
is moved once, by what the agents before it added.
"""

from __future__ import annotations

import bisect
import itertools
from collections.abc import Callable, Sequence

from rssm_core.records import dataclass
from rssm_dsl.lsp.incremental import ShiftMap
from rssm_dsl.lsp.index import Definition, IndexBuilder, Occurrence, Scope, SymbolIndex
from rssm_dsl.semantics.loader import Program
from rssm_dsl.source import Span
from rssm_dsl.syntax import ast


@dataclass(frozen=True)
class AgentEdit:
    """One incremental step: the agent whose key was `old_key` replaced by `new` (parsed
    with stale spans that `shifts` maps to the new text), the text after it moved by
    `chars` characters and `lines` lines."""

    program: Program          # the program of the new text (stale spans)
    system: ast.SystemDecl    # the system of the new text, holding `new`
    old_key: str
    replaced: ast.AgentDecl   # the agent as it was (stale spans)
    new: ast.AgentDecl
    shifts: ShiftMap
    chars: int
    lines: int

    def then(self, edit: AgentEdit) -> AgentEdit | None:
        """This edit and the next as one, when the next edits the agent this one made."""
        if edit.replaced is not self.new:
            return None
        return AgentEdit(edit.program, edit.system, self.old_key, self.replaced, edit.new,
                         edit.shifts, self.chars + edit.chars, self.lines + edit.lines)


def _signature(d: Definition) -> tuple[str, str, str, str | None, bool]:
    return d.name, d.kind, d.detail, d.container, d.renameable


class _Mover:
    """Moves the spans of one file by what the edited agents before them added: a span
    ending at or after the end of an edited agent's old text moves by that agent's (chars,
    lines), its start too if it starts there or after."""

    def __init__(self, file: str, moves: list[tuple[int, int, int]]) -> None:
        self.file = file
        self.ends = [hi for hi, _, _ in moves]         # ascending
        self.sums: list[tuple[int, int]] = [(0, 0)]
        for _, chars, lines in moves:
            c, n = self.sums[-1]
            self.sums.append((c + chars, n + lines))

    def delta(self, offset: int) -> tuple[int, int]:
        return self.sums[bisect.bisect_right(self.ends, offset)]

    def span(self, s: Span) -> Span:
        if s.file != self.file:
            return s
        (c0, l0), (c1, l1) = self.delta(s.offset), self.delta(s.end_offset)
        if c0 == c1 == 0 and l0 == l1 == 0:
            return s
        return Span(s.file, s.line + l0, s.column, s.end_line + l1, s.end_column,
                    s.offset + c0, s.end_offset + c1)

    def definition(self, d: Definition) -> Definition:
        span, full = self.span(d.span), self.span(d.full)
        if span is d.span and full is d.full:
            return d
        return Definition(d.key, d.name, d.kind, span, full, d.detail, d.container,
                          d.renameable)


def _mapped(d: Definition, to_real: Callable[[Span], Span]) -> Definition:
    return Definition(d.key, d.name, d.kind, to_real(d.span), to_real(d.full), d.detail,
                      d.container, d.renameable)


def merged(edits: Sequence[AgentEdit]) -> list[AgentEdit]:
    """The edits as one per agent: edits of different agents do not interfere (each
    replaces its own agent and moves what follows it), so an agent edited again after
    others is still one edit."""
    out: list[AgentEdit] = []
    for e in edits:
        for k, m in enumerate(out):
            both = m.then(e)
            if both is not None:
                out[k] = both
                break
        else:
            out.append(e)
    return out


@dataclass
class _Agent:
    """One edited agent: its old region, the keys of its old definitions, its new index."""

    lo: int
    hi: int
    edit: AgentEdit
    removed: set[str]
    added: dict[str, Definition]
    scratch: SymbolIndex


def _reindex_agent(index: SymbolIndex, edit: AgentEdit, display: str,
                   program: Program, system: ast.SystemDecl) -> _Agent | None:
    old = index.definitions.get(edit.old_key)
    if old is None or old.full.file != display:
        return None
    if sum(1 for a in system.agents if a.name == edit.new.name) != 1:
        return None
    lo, hi = old.full.offset, old.full.end_offset

    def straddles(s: Span) -> bool:     # in part inside the agent (text with errors)
        return s.file == display and (lo < s.offset < hi < s.end_offset
                                      or s.offset < lo < s.end_offset < hi)

    if any(straddles(s) for s, _ in index.scopes) or any(
            straddles(d.full) for d in index.definitions.values()):
        return None
    removed = {k for k, d in index.definitions.items()
               if d.span.file == display and lo <= d.span.offset and d.span.end_offset <= hi}
    known = {k: d for k, d in index.definitions.items() if k not in removed}
    scratch = IndexBuilder(program, only_agent=edit.new, known=known).build()
    added = {k: d for k, d in scratch.definitions.items() if k not in known}
    before = {k: _signature(index.definitions[k]) for k in removed if not k.startswith("local:")}
    after = {k: _signature(d) for k, d in added.items() if not k.startswith("local:")}
    if before != after:
        return None
    return _Agent(lo, hi, edit, removed, added, scratch)


def reindex(index: SymbolIndex, edits: Sequence[AgentEdit], display: str
            ) -> SymbolIndex | None:
    """The index after `edits` (in order, the last one's text is the new text) from `index`
    (the text's before the first one, in its real positions), or None when the whole text
    must be indexed. What the edits left alone is moved once, whatever their number."""
    if not edits:
        return index
    last = edits[-1]
    agents: list[_Agent] = []
    for edit in merged(edits):
        got = _reindex_agent(index, edit, display, last.program, last.system)
        if got is None:
            return None
        agents.append(got)
    agents.sort(key=lambda x: x.lo)
    if any(b.lo <= a.hi for a, b in itertools.pairwise(agents)):
        return None
    to_real = last.shifts.span          # maps every reparsed agent of the new text
    move = _Mover(display, [(x.hi, x.edit.chars, x.edit.lines) for x in agents])
    out = SymbolIndex()
    out.definitions = _definitions(index, agents, move, to_real)
    out.occurrences = dict(index.occurrences)
    out.occurrences[display] = _occurrences(index.occurrences.get(display, []), agents, move,
                                            to_real)
    out.scopes = _scopes(index, agents, move, to_real, display)
    gone = set().union(*(x.removed for x in agents))
    out.links = {k: v for k, v in index.links.items() if k not in gone}
    for x in agents:
        out.links.update(x.scratch.links)
    return out


def _definitions(index: SymbolIndex, agents: list[_Agent], move: _Mover,
                 to_real: Callable[[Span], Span]) -> dict[str, Definition]:
    """Each edited agent's new definitions where its old ones were, the rest moved."""
    owner = {k: x for x in agents for k in x.removed}
    out: dict[str, Definition] = {}
    placed: set[int] = set()
    for k, d in index.definitions.items():
        x = owner.get(k)
        if x is None:
            out[k] = move.definition(d)
        elif id(x) not in placed:
            placed.add(id(x))
            for nk, nd in x.added.items():
                out[nk] = _mapped(nd, to_real)
    return out


def _occurrences(occs: list[Occurrence], agents: list[_Agent], move: _Mover,
                 to_real: Callable[[Span], Span]) -> list[Occurrence]:
    """The occurrences of the file (sorted): each edited agent's new ones in its place."""
    starts = [o.span.offset for o in occs]
    out: list[Occurrence] = []
    at = 0
    for x in agents:
        i0, i1 = bisect.bisect_left(starts, x.lo), bisect.bisect_right(starts, x.hi)
        out += _moved(occs[at:i0], move)
        file = x.edit.new.span.file
        out += sorted((Occurrence(to_real(o.span), o.key, o.definition)
                       for o in x.scratch.occurrences.get(file, ())),
                      key=lambda o: (o.span.offset, o.span.end_offset))
        at = i1
    out += _moved(occs[at:], move)
    return out


def _scopes(index: SymbolIndex, agents: list[_Agent], move: _Mover,
            to_real: Callable[[Span], Span], display: str) -> list[tuple[Span, Scope]]:
    """The subsystem scopes in order: each edited agent's new ones in its place."""
    def new(x: _Agent) -> list[tuple[Span, Scope]]:
        file = x.edit.new.span.file
        return [(to_real(t), tc) for t, tc in x.scratch.scopes if t.file == file]

    out: list[tuple[Span, Scope]] = []
    placed: set[int] = set()
    for s, sc in index.scopes:
        x = next((x for x in agents if s.file == display and x.lo <= s.offset
                  and s.end_offset <= x.hi), None)
        if x is None:
            out.append((move.span(s), sc))
        elif id(x) not in placed:
            placed.add(id(x))
            out += new(x)
    for x in agents:        # agents that had no scope before
        if id(x) not in placed:
            out += new(x)
    return out


def _moved(occs: list[Occurrence], move: _Mover) -> list[Occurrence]:
    """Occurrences between two edited agents (all moved by the same amount)."""
    if not occs:
        return []
    chars, lines = move.delta(occs[0].span.offset)
    if chars == 0 and lines == 0:
        return occs
    return [Occurrence(Span(s.file, s.line + lines, s.column, s.end_line + lines,
                            s.end_column, s.offset + chars, s.end_offset + chars),
                       o.key, o.definition) for o in occs for s in (o.span,)]
