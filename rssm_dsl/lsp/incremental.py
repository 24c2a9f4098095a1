"""Incremental reparsing: an edit inside one agent reparses that agent only.

Parsing is most of the work of an analysis (a 5,000-line spec takes about half a second),
and almost every edit a person makes stays inside one `agent { ... }`. Such an edit is
reparsed alone: the new text of the agent is parsed in a copy of the document where every
other character is blanked (newlines kept), so its spans are those of the real document; the
semantic passes then run on the module with that agent replaced.

The other agents keep the AST they had, with *stale* spans (positions in the text they were
parsed from). Instead of rebuilding every node behind the edit, each file name a parse used
(the document's, or a fresh name per reparsed agent) gets a piecewise shift: from a stale
offset on, add so many characters and lines. Spans leaving the analysis (diagnostics, the
symbol index, the outline) are mapped through it. Anything unusual (an edit outside an
agent, a syntax error, imports that changed, edits that end on the line of the next agent)
falls back to a full analysis, as do the first analysis and every 200th edit. A syntax
error inside the agent stays there: the parser recovers within the agent, and the rest of
the file keeps its AST and its diagnostics.
"""

from __future__ import annotations

import bisect
import dataclasses
import itertools
import re
from collections.abc import Callable
from enum import Enum
from typing import Any

from rssm_core.records import dataclass
from rssm_dsl.diagnostics import Diagnostic, Related
from rssm_dsl.lsp.index import block_close, block_end
from rssm_dsl.lsp.positions import count_lines
from rssm_dsl.semantics.analyze import AgentMemo
from rssm_dsl.semantics.loader import Program
from rssm_dsl.source import SourceFile, Span
from rssm_dsl.syntax import ast
from rssm_dsl.syntax.parser import parse

MAX_STEPS = 200
_serial = itertools.count(1)


@dataclass(frozen=True)
class ShiftMap:
    """Stale file name -> breakpoints (stale offsets, ascending) and their (chars, lines)."""

    display: str
    files: dict[str, tuple[tuple[int, ...], tuple[tuple[int, int], ...]]]

    @staticmethod
    def identity(display: str, *names: str) -> ShiftMap:
        return ShiftMap(display, {n: ((0,), ((0, 0),)) for n in names})

    def with_file(self, name: str) -> ShiftMap:
        files = dict(self.files)
        files[name] = ((0,), ((0, 0),))
        return ShiftMap(self.display, files)

    def _delta(self, file: str, offset: int) -> tuple[int, int] | None:
        m = self.files.get(file)
        if m is None:
            return None
        starts, deltas = m
        return deltas[max(0, bisect.bisect_right(starts, offset) - 1)]

    def span(self, s: Span) -> Span:
        first = self._delta(s.file, s.offset)
        if first is None:
            return s
        last = self._delta(s.file, max(s.offset, s.end_offset - 1)) or first
        return Span(self.display, s.line + first[1], s.column, s.end_line + last[1],
                    s.end_column, s.offset + first[0], s.end_offset + last[0])

    def after_edit(self, real_end: int, d_chars: int, d_lines: int) -> ShiftMap:
        """Everything at or after the real offset `real_end` moves by the edit's size."""
        files: dict[str, tuple[tuple[int, ...], tuple[tuple[int, int], ...]]] = {}
        for name, (starts, deltas) in self.files.items():
            ns: list[int] = []
            nd: list[tuple[int, int]] = []
            for k, (s0, (dc, dl)) in enumerate(zip(starts, deltas, strict=True)):
                s1 = starts[k + 1] if k + 1 < len(starts) else None
                if s0 + dc >= real_end:
                    ns.append(s0)
                    nd.append((dc + d_chars, dl + d_lines))
                elif s1 is None or s1 + dc > real_end:
                    ns.append(s0)
                    nd.append((dc, dl))
                    ns.append(real_end - dc)
                    nd.append((dc + d_chars, dl + d_lines))
                else:
                    ns.append(s0)
                    nd.append((dc, dl))
            files[name] = (tuple(ns), tuple(nd))
        return ShiftMap(self.display, files)


@dataclass(frozen=True)
class State:
    """What the next edit of a document needs to be analysed incrementally."""

    text: str
    module: ast.Module            # stale spans, see ShiftMap
    shifts: ShiftMap
    program: Program
    steps: int = 0
    # agents reparsed with syntax errors, and those errors (stale spans)
    broken: tuple[tuple[ast.AgentDecl, tuple[Diagnostic, ...]], ...] = ()
    # the semantic passes' work on each agent, reused for the agents an edit left alone
    memo: AgentMemo = dataclasses.field(default_factory=AgentMemo)
    masked: str | None = None     # _mask(text), once made


@dataclass(frozen=True)
class Reparsed:
    state: State
    program: Program
    system: ast.SystemDecl        # of the new text
    replaced: ast.AgentDecl       # the agent reparsed, as it was
    agent: ast.AgentDecl          # and as it is (stale spans of its own pseudo-file)
    chars: int                    # what the text after the agent moved by
    lines: int


_NOT_BREAK = re.compile(r"[^\r\n]+")


def _mask(text: str) -> str:
    """`text` blanked but for its line terminators (so that offsets and lines are kept)."""
    return _NOT_BREAK.sub(lambda m: " " * len(m.group()), text)


def _line_count(text: str) -> int:
    """The lines of `text` as the compiler counts them (spans must agree with it)."""
    return count_lines(text)


def _keyword_before(text: str, word: str, at: int) -> int | None:
    """The offset of `word` just before `at` (only blanks between), or None."""
    start = text.rfind(word, 0, at)
    if start < 0 or text[start + len(word):at].strip():
        return None
    if start > 0 and (text[start - 1].isalnum() or text[start - 1] == "_"):
        return None
    return start


def _next_line_follows(text: str, at: int) -> bool:
    """Only blanks, or a line comment, between `at` and the next line break."""
    rest = text[at:at + 400].lstrip(" \t")
    return rest == "" or rest.startswith(("\n", "\r", "//"))


def reparse(state: State, text: str, display: str,
            unchanged_imports: Callable[[Program], bool]) -> Reparsed | None:
    """The program of `text` made from `state` by reparsing one agent, or None when the
    edit does not allow it (the caller then analyses the whole text)."""
    old = state.text
    if state.steps >= MAX_STEPS or not unchanged_imports(state.program):
        return None
    a, b = _common_ends(old, text)
    old_end = len(old) - b
    d_chars = len(text) - len(old)
    d_lines = _line_count(text) - _line_count(old)   # the prefix and suffix are common
    systems = [d for d in state.module.decls if isinstance(d, ast.SystemDecl)]
    if len(systems) != 1:
        return None
    sd = systems[0]
    if sd.instances or any(isinstance(d, ast.AgentDef) for d in state.module.decls):
        return None     # an agent's edit may change its instances' agents: all of it anew
    shifts = state.shifts
    found = _edited_agent(sd, shifts, old, a, old_end)
    if found is None:
        return None
    chosen, chunk_start, close = found
    new_close = close + d_chars
    if not _next_line_follows(text, new_close):
        return None
    # the whole text blanked, from the old one's: only the edited part is blanked anew
    blank_old = state.masked if state.masked is not None else _mask(old)
    blank = blank_old[:a] + _mask(text[a:len(text) - b]) + blank_old[len(old) - b:]
    masked = _masked_frame(sd, shifts, old, text, blank, chunk_start, new_close, d_chars)
    if masked is None:
        return None
    pseudo = f"{display}#{next(_serial)}"
    source = SourceFile(pseudo, masked)
    result = parse(source)
    if result.module is None or len(result.module.decls) != 1:
        return None
    [frame] = result.module.decls
    if not isinstance(frame, ast.SystemDecl) or len(frame.agents) != 1:
        return None
    # syntax errors are kept when the parser recovered inside the agent
    if any(not (chunk_start <= d.span.offset <= new_close) for d in result.diagnostics):
        return None
    agents = list(sd.agents)
    replaced = agents[chosen]
    agents[chosen] = frame.agents[0]
    broken = tuple(x for x in state.broken if x[0] is not replaced)
    if result.diagnostics:
        broken += ((frame.agents[0], result.diagnostics),)
    system = dataclasses.replace(sd, agents=tuple(agents))   # the properties are kept
    module = ast.Module(state.module.span, state.module.path, state.module.imports,
                        tuple(system if d is sd else d for d in state.module.decls))
    new_shifts = shifts.after_edit(old_end, d_chars, d_lines).with_file(pseudo)
    prog = state.program
    modules = [m for m in prog.modules if m is not state.module] + [module]
    sources = dict(prog.sources)
    sources[pseudo] = source
    program = Program(root=module, modules=modules, sources=sources,
                      imports=dict(prog.imports))
    return Reparsed(State(text, module, new_shifts, program, state.steps + 1, broken,
                          state.memo, blank), program, system, replaced, frame.agents[0], d_chars,
                    d_lines)


def _common_ends(old: str, text: str) -> tuple[int, int]:
    """The lengths of the common prefix and of the common suffix (not overlapping it),
    compared in blocks first (string comparison runs in C)."""
    n0, n1 = len(old), len(text)
    limit = min(n0, n1)
    step = 2048
    a = 0
    while a + step <= limit and old[a:a + step] == text[a:a + step]:
        a += step
    while a < limit and old[a] == text[a]:
        a += 1
    b = 0
    while b + step <= limit - a and old[n0 - b - step:n0 - b] == text[n1 - b - step:n1 - b]:
        b += step
    while b < limit - a and old[n0 - b - 1] == text[n1 - b - 1]:
        b += 1
    return a, b


def _edited_agent(sd: ast.SystemDecl, shifts: ShiftMap, old: str, a: int,
                  old_end: int) -> tuple[int, int, int] | None:
    """The agent the edit [a, old_end) of the old text lies in: (its position in the
    system, the offset of its `agent` keyword, the offset after its `}`), or None.

    The agents are in text order: the candidate is the last one whose name starts before
    the edit (found by bisection), and only its block is scanned for its `}`."""
    names = [shifts.span(agent.name_span) for agent in sd.agents]
    k = bisect.bisect_left([n.offset for n in names], a) - 1
    if k < 0:
        return None
    start = _keyword_before(old, "agent", names[k].offset)
    if start is None or start >= a:
        return None
    end = block_close(old, names[k].end_offset)
    if end <= start or old[end - 1] != "}":
        return None
    if old_end <= end - 1:
        return k, start, end
    return None


def _masked_frame(sd: ast.SystemDecl, shifts: ShiftMap, old: str, text: str, blank: str,
                  chunk_start: int, new_close: int, d_chars: int) -> str | None:
    """The new text with everything blanked but the system's frame (`system NAME {` ...
    `}`) and the agent in [chunk_start, new_close), or None when the frame is not found
    (`blank`: all of the new text blanked)."""
    sys_name = shifts.span(sd.name_span)
    sys_start = _keyword_before(old, "system", sys_name.offset)
    if sys_start is None:
        return None
    body = text.find("{", sys_name.end_offset) + 1
    last_end = block_close(old, shifts.span(sd.agents[-1].name_span).end_offset)
    sys_close = block_end(old, last_end) - 1 + d_chars
    if body <= 0 or not (body <= chunk_start < new_close <= sys_close) \
            or text[sys_close] != "}":
        return None
    return (blank[:sys_start] + text[sys_start:body] + blank[body:chunk_start]
            + text[chunk_start:new_close] + blank[new_close:sys_close] + "}"
            + blank[sys_close + 1:])


# ---------------------------------------------------------------------- mapping spans out
def map_diagnostic(d: Diagnostic, shifts: ShiftMap) -> Diagnostic:
    related = tuple(Related(shifts.span(r.span), r.message) for r in d.related)
    return Diagnostic(d.code, d.message, shifts.span(d.span), d.hint, related)


_FIELDS: dict[type, tuple[str, ...]] = {}


def _fields(cls: type) -> tuple[str, ...]:
    names = _FIELDS.get(cls)
    if names is None:
        names = _FIELDS[cls] = tuple(f.name for f in dataclasses.fields(cls))
    return names


def map_module(module: ast.Module, shifts: ShiftMap) -> ast.Module:
    """A copy of the module with real spans (an iterative rebuild: no recursion limit)."""
    memo: dict[int, Any] = {}
    # post-order over the object graph of AST nodes and tuples
    stack: list[tuple[Any, bool]] = [(module, False)]
    while stack:
        node, done = stack.pop()
        key = id(node)
        if key in memo:
            continue
        t = type(node)
        if t is Span:
            memo[key] = shifts.span(node)
            continue
        if t is tuple:
            if done:
                memo[key] = tuple(memo.get(id(x), x) for x in node)
            else:
                stack.append((node, True))
                stack.extend((x, False) for x in node if _composite(x))
            continue
        if not dataclasses.is_dataclass(node):
            continue
        values = [getattr(node, f) for f in _fields(t)]
        if done:
            memo[key] = t(*[memo.get(id(v), v) if _composite(v) else v for v in values])
        else:
            stack.append((node, True))
            stack.extend((v, False) for v in values if _composite(v))
    mapped: ast.Module = memo[id(module)]
    return mapped


def _composite(x: object) -> bool:
    return type(x) is tuple or type(x) is Span or (
        dataclasses.is_dataclass(x) and not isinstance(x, type | Enum))
