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
"""

from __future__ import annotations

import bisect
from collections.abc import Callable
from dataclasses import dataclass

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
    """Moves the spans of one file that end at or after `end` by (chars, lines)."""

    def __init__(self, file: str, end: int, chars: int, lines: int) -> None:
        self.file, self.end, self.chars, self.lines = file, end, chars, lines

    def span(self, s: Span) -> Span:
        if s.file != self.file or s.end_offset < self.end:
            return s
        if s.offset >= self.end:
            return Span(s.file, s.line + self.lines, s.column, s.end_line + self.lines,
                        s.end_column, s.offset + self.chars, s.end_offset + self.chars)
        return Span(s.file, s.line, s.column, s.end_line + self.lines, s.end_column,
                    s.offset, s.end_offset + self.chars)

    def definition(self, d: Definition) -> Definition:
        span, full = self.span(d.span), self.span(d.full)
        if span is d.span and full is d.full:
            return d
        return Definition(d.key, d.name, d.kind, span, full, d.detail, d.container,
                          d.renameable)


def _mapped(d: Definition, to_real: Callable[[Span], Span]) -> Definition:
    return Definition(d.key, d.name, d.kind, to_real(d.span), to_real(d.full), d.detail,
                      d.container, d.renameable)


def reindex(index: SymbolIndex, edit: AgentEdit, display: str) -> SymbolIndex | None:
    """The index after `edit` from `index` (the previous text's, in its real positions), or
    None when the whole text must be indexed."""
    old = index.definitions.get(edit.old_key)
    if old is None or old.full.file != display:
        return None
    if sum(1 for a in edit.system.agents if a.name == edit.new.name) != 1:
        return None
    lo, hi = old.full.offset, old.full.end_offset

    def inside(s: Span) -> bool:
        return s.file == display and lo <= s.offset and s.end_offset <= hi

    def straddles(s: Span) -> bool:     # in part inside the agent (text with errors)
        return s.file == display and (lo < s.offset < hi < s.end_offset
                                      or s.offset < lo < s.end_offset < hi)

    if any(straddles(s) for s, _ in index.scopes) or any(
            straddles(d.full) for d in index.definitions.values()):
        return None
    removed = {k for k, d in index.definitions.items() if inside(d.span)}
    known = {k: d for k, d in index.definitions.items() if k not in removed}
    scratch = IndexBuilder(edit.program, only_agent=edit.new, known=known).build()
    added = {k: d for k, d in scratch.definitions.items() if k not in known}
    before = {k: _signature(index.definitions[k]) for k in removed if not k.startswith("local:")}
    after = {k: _signature(d) for k, d in added.items() if not k.startswith("local:")}
    if before != after:
        return None

    file = edit.new.span.file
    to_real = edit.shifts.span
    move = _Mover(display, hi, edit.chars, edit.lines)
    out = SymbolIndex()
    placed = False
    for k, d in index.definitions.items():
        if k in removed:
            if not placed:
                for nk, nd in added.items():
                    out.definitions[nk] = _mapped(nd, to_real)
                placed = True
            continue
        out.definitions[k] = move.definition(d)

    out.occurrences = dict(index.occurrences)
    occs = index.occurrences.get(display, [])
    starts = [o.span.offset for o in occs]
    i0, i1 = bisect.bisect_left(starts, lo), bisect.bisect_right(starts, hi)
    fresh = sorted((Occurrence(to_real(o.span), o.key, o.definition)
                    for o in scratch.occurrences.get(file, ())),
                   key=lambda o: (o.span.offset, o.span.end_offset))
    out.occurrences[display] = [*occs[:i0], *fresh,
                                *(Occurrence(move.span(o.span), o.key, o.definition)
                                  for o in occs[i1:])]

    scopes: list[tuple[Span, Scope]] = []
    new_scopes = [(to_real(s), sc) for s, sc in scratch.scopes if s.file == file]
    for s, sc in index.scopes:
        if inside(s):
            scopes += new_scopes
            new_scopes = []
        else:
            scopes.append((move.span(s), sc))
    out.scopes = scopes + new_scopes

    out.links = {k: v for k, v in index.links.items() if k not in removed}
    out.links.update(scratch.links)
    return out
