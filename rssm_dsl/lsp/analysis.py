"""Analysis of one open document: the compiler's front end and checks on the editor's
(unsaved) text, the symbol index, and the last good semantic model.

While the text has syntax errors the compiler stops before the semantic passes; here they
are run on the parser's partial module all the same, and their diagnostics are kept except
inside the declarations that hold a syntax error (those would be echoes of it), so that a
broken edit does not hide the diagnostics of the rest of the file.

An edit inside one agent is reparsed alone (incremental.py); the symbol index and the
real-span AST are built on first use (hover, outline...), not before the diagnostics.
"""

from __future__ import annotations

import logging
import threading
from collections.abc import Callable
from dataclasses import field, replace
from pathlib import Path

from rssm_core.records import dataclass
from rssm_dsl.diagnostics import Diagnostic, DiagnosticBag, Severity
from rssm_dsl.gcpause import collector_paused
from rssm_dsl.lsp.incremental import Reparsed, ShiftMap, State, map_diagnostic, map_module, reparse
from rssm_dsl.lsp.index import Occurrence, SymbolIndex, build_index, system_id
from rssm_dsl.lsp.paths import path_of_display, resolved
from rssm_dsl.lsp.positions import LineIndex
from rssm_dsl.lsp.reindex import AgentEdit, reindex
from rssm_dsl.lsp.symbols import AgentOutlines
from rssm_dsl.pipeline import compile_file
from rssm_dsl.semantics.analyze import AgentMemo, analyze
from rssm_dsl.semantics.loader import (
    LINE_SEPARATORS,
    Program,
    check_file_names,
    check_line_separators,
)
from rssm_dsl.semantics.model import System
from rssm_dsl.source import SourceFile, Span
from rssm_dsl.syntax import ast

log = logging.getLogger("rssmc.lsp")

# Larger texts are not analyzed live (the compiler itself accepts up to 8 MB).
MAX_LIVE_CHARS = 2_000_000
MAX_REINDEX = 64       # agent edits applied to the last index built, at most (then: all)
SYNTAX_CODES = frozenset({"E005", "E006", "E007", "E008", "E013"})


@dataclass
class LazyIndex:
    """The symbol index of a program, built on first use (diagnostics do not need it)."""

    program: Program | None
    fallback: LazyIndex | None = None
    shifts: ShiftMap | None = None          # stale spans of an incremental parse
    # after an incremental analysis: the index of an earlier text whose declarations outside
    # the system are the same (an incremental analysis reparses one agent only)
    outside_from: LazyIndex | None = None
    # after an incremental analysis: the last index built before it, and the agent edits
    # since, to make this one from it (rssm_dsl.lsp.reindex)
    base: LazyIndex | None = None
    edits: tuple[AgentEdit, ...] = ()
    value: SymbolIndex | None = None
    lock: threading.Lock = field(default_factory=threading.Lock, repr=False)

    @property
    def ready(self) -> bool:
        return self.value is not None

    def after(self, edit: AgentEdit) -> tuple[LazyIndex | None, tuple[AgentEdit, ...]]:
        """What the index of the text after `edit` (an edit of this text) is made from."""
        if self.value is not None:
            return self, (edit,)
        if self.base is not None and len(self.edits) < MAX_REINDEX:
            both = self.edits[-1].then(edit) if self.edits else None
            if both is not None:       # the same agent edited again: one edit
                return self.base, (*self.edits[:-1], both)
            return self.base, (*self.edits, edit)
        return None, ()

    def outside(self) -> SymbolIndex | None:
        """An index whose definitions outside the system (types, record fields, enum
        members, constants, externs, devices) are this text's, if one is built: this one, or
        that of the earlier text it was made from. Its positions may be stale."""
        if self.value is not None:
            return self.value
        if self.outside_from is not None:
            return self.outside_from.value
        return None

    def get(self) -> SymbolIndex:
        with self.lock:
            if self.value is None and self.base is not None and self.shifts is not None:
                with collector_paused():
                    self.value = self._reindexed(self.base, self.shifts.display)
                self.base, self.edits = None, ()
            if self.value is None:
                if self.program is not None:
                    with collector_paused():
                        index = build_index(self.program)
                        if self.shifts is not None:
                            index = _map_index(index, self.shifts)
                        self.value = index
                elif self.fallback is not None:
                    self.value = self.fallback.get()
                else:
                    self.value = SymbolIndex()
            return self.value


    def _reindexed(self, base: LazyIndex, display: str) -> SymbolIndex | None:
        return None if base.value is None else reindex(base.value, self.edits, display)


def _map_index(ix: SymbolIndex, shifts: ShiftMap) -> SymbolIndex:
    out = SymbolIndex()
    for key, d in ix.definitions.items():
        out.definitions[key] = replace(d, span=shifts.span(d.span), full=shifts.span(d.full))
    for occs in ix.occurrences.values():
        for o in occs:
            span = shifts.span(o.span)
            out.occurrences.setdefault(span.file, []).append(
                Occurrence(span, o.key, o.definition))
    for occs in out.occurrences.values():
        occs.sort(key=lambda o: (o.span.offset, o.span.end_offset))
    out.scopes = [(shifts.span(span), scope) for span, scope in ix.scopes]
    out.links = dict(ix.links)
    return out


def _same_span(span: Span) -> Span:
    return span


@dataclass(frozen=True)
class ModuleView:
    """An AST (maybe a part) and the cursor in its positions: a real offset is
    `delta` more than the offset of the same place in the view."""

    module: ast.Module | None
    offset: int
    delta: int

    def real(self, start: int, end: int) -> tuple[int, int]:
        return start + self.delta, end + self.delta

    def local(self, offset: int) -> int:
        return offset - self.delta


@dataclass
class LazyModule:
    """The AST of the text; after an incremental parse, mapped to real spans on first use."""

    stale: ast.Module | None
    shifts: ShiftMap | None = None
    value: ast.Module | None = None
    lock: threading.Lock = field(default_factory=threading.Lock, repr=False)

    @property
    def ready(self) -> bool:
        return self.value is not None or self.stale is None

    def names(self) -> ast.Module | None:
        """The AST for what needs its names, not its positions: the mapped one if it is
        built, the stale one otherwise (same names, stale spans)."""
        return self.value if self.value is not None else self.stale

    def outline_view(self) -> tuple[ast.Module | None, Callable[[Span], Span]]:
        """The AST and how to map its spans to the text's: the mapped AST when it is built,
        the stale one and its shifts otherwise (for what needs few of its spans)."""
        with self.lock:
            if self.value is not None or self.stale is None or self.shifts is None:
                return (self.value if self.value is not None else self.stale), _same_span
            return self.stale, self.shifts.span

    def view_at(self, offset: int) -> ModuleView:
        """What a query at the real offset `offset` reads of the AST. When the mapped AST is
        not built (after an incremental analysis) and the offset is inside an agent: that
        agent alone in its system, its spans stale but all moved by the same amount (an
        edit reparses one agent: nothing inside another moves apart), so the query needs
        neither the whole AST mapped nor more than one span converted."""
        with self.lock:
            stale, shifts = self.stale, self.shifts
            if self.value is not None or stale is None or shifts is None:
                return ModuleView(self.value if self.value is not None else stale, offset, 0)
        systems = [d for d in stale.decls if isinstance(d, ast.SystemDecl)]
        if len(systems) == 1:
            sd = systems[0]
            for agent in sd.agents:
                real = shifts.span(agent.span)
                if real.offset <= offset <= real.end_offset:
                    delta = real.offset - agent.span.offset
                    alone = replace(sd, agents=(agent,))
                    module = ast.Module(stale.span, stale.path, stale.imports, (alone,))
                    return ModuleView(module, offset - delta, delta)
        return ModuleView(self.get(), offset, 0)

    def get(self) -> ast.Module | None:
        with self.lock:
            if self.value is None and self.stale is not None:
                if self.shifts is None:
                    self.value = self.stale
                else:
                    with collector_paused():
                        self.value = map_module(self.stale, self.shifts)
            return self.value


@dataclass(frozen=True)
class Analysis:
    uri: str
    version: int | None
    path: Path
    display: str                      # the file's name in spans
    text: str
    lines: LineIndex
    lazy_module: LazyModule           # this text's AST (partial when it has syntax errors)
    program: Program | None
    diagnostics: tuple[Diagnostic, ...]   # located in this file
    lazy_index: LazyIndex
    system: System | None             # the last good semantic model (maybe of an older text)
    incremental: State | None = None  # for reparsing the next edit alone
    how: str = "full"                 # "full" or "incremental" (for tests and figures)
    # the outline of this text in JSON, by position encoding, made once (server.outline)
    outlines: dict[str, str] = field(default_factory=dict, compare=False, repr=False)
    outline_lock: threading.Lock = field(default_factory=threading.Lock, compare=False,
                                         repr=False)
    # the agents outlined for the document's texts so far, by encoding (shared by its
    # analyses: an incremental analysis keeps the AST of the agents it did not reparse)
    agent_outlines: dict[str, AgentOutlines] = field(default_factory=dict, compare=False,
                                                     repr=False)

    @property
    def module(self) -> ast.Module | None:
        return self.lazy_module.get()

    @property
    def analyzable(self) -> bool:
        return self.program is not None

    @property
    def index(self) -> SymbolIndex:
        return self.lazy_index.get()


def _at_start(display: str) -> Span:
    return Span(display, 1, 1, 1, 1, 0, 0)


def _blocks(module: ast.Module) -> list[Span]:
    """Spans of the declarations that can contain an error, innermost ones included."""
    out: list[Span] = []
    for d in module.decls:
        out.append(d.span)
        if isinstance(d, ast.SystemDecl):
            for a in d.agents:
                out.append(a.span)
                for s in a.subsystems:
                    out.append(s.span)
                    out.extend(b.span for b in s.behaviours)
                    out.extend(b.span for b in s.buffers)
                    out.extend(x.span for x in s.params)
                    out.extend(x.span for x in s.memory)
                    out.extend(x.span for x in s.switches)
                out.extend(x.span for x in a.devices)
    return out


def _echo_regions(module: ast.Module, syntax: list[Diagnostic]) -> list[tuple[int, int]]:
    blocks = _blocks(module)
    regions: list[tuple[int, int]] = []
    for d in syntax:
        at = d.span.offset
        inner = [b for b in blocks if b.offset <= at <= b.end_offset]
        if inner:
            best = min(inner, key=lambda b: b.end_offset - b.offset)
            regions.append((best.offset, best.end_offset))
        else:
            regions.append((at, at))
    return regions


def _semantic_despite_syntax(program: Program, display: str,
                             syntax: list[Diagnostic]) -> list[Diagnostic]:
    """Semantic diagnostics of a partial module, without those near a syntax error."""
    root = program.root
    if root is None:
        return []
    bag = DiagnosticBag()
    try:
        analyze(program, bag)
    except Exception:
        return []
    regions = _echo_regions(root, syntax)
    out: list[Diagnostic] = []
    for d in bag.sorted():
        if d.span.file != display or "'_'" in d.message:
            continue
        if any(a <= d.span.offset <= b or a <= d.span.end_offset <= b for a, b in regions):
            continue
        out.append(d)
    return out


def _is_library(module: ast.Module | None) -> bool:
    return module is not None and not any(isinstance(d, ast.SystemDecl) for d in module.decls)


def analyze_text(uri: str, path: Path, display: str, text: str, version: int | None,
                 overrides: dict[Path, str], previous: Analysis | None) -> Analysis:
    """Analyze one document's text; never raises on bad input."""
    got = _analyze_text(uri, path, display, text, version, overrides, previous)
    if previous is not None:
        got = replace(got, agent_outlines=previous.agent_outlines)
    return got


def _analyze_text(uri: str, path: Path, display: str, text: str, version: int | None,
                  overrides: dict[Path, str], previous: Analysis | None) -> Analysis:
    lines = LineIndex(text)
    kept_system = previous.system if previous is not None else None
    if "\x00" in text:
        diag = Diagnostic("E003", "this file is binary, not RSSM text", _at_start(display),
                          "open a .rssm text file")
        return Analysis(uri, version, path, display, text, lines, LazyModule(None), None,
                        (diag,), LazyIndex(None), kept_system)
    if len(text) > MAX_LIVE_CHARS:
        diag = Diagnostic("E004", f"this file has {len(text) / 1e6:.1f} million characters; "
                          f"the editor analyses at most {MAX_LIVE_CHARS / 1e6:.1f} million",
                          _at_start(display),
                          "split the specification into imported files, or run `rssmc check`")
        return Analysis(uri, version, path, display, text, lines, LazyModule(None), None,
                        (diag,), LazyIndex(None), kept_system)
    overrides = dict(overrides)
    overrides[resolved(path) or path] = text
    state = previous.incremental if previous is not None else None
    if state is not None and previous is not None:
        try:
            got = reparse(state, text, display,
                          lambda p: _imports_unchanged(p, display, overrides))
            step = None if got is None else _incremental(uri, path, display, text, version,
                                                         lines, got, kept_system,
                                                         previous.lazy_index)
            if step is not None:
                return step
        except Exception:
            log.exception("incremental analysis failed; analysing the whole text")
    memo = state.memo if state is not None else AgentMemo()
    comp = compile_file(path, overrides, build=False, memo=memo)
    program = comp.program
    mine = [d for d in comp.diagnostics if d.span.file == display]
    syntax = [d for d in mine if d.code in SYNTAX_CODES]
    root = program.root
    if syntax and root is not None:
        mine += _semantic_despite_syntax(program, display, syntax)
    mine = _finish(mine, root)
    index = LazyIndex(program)
    if previous is not None and root is None and previous.module is not None:
        # nothing usable was recovered: keep the outline and names of the last text
        index = LazyIndex(None, previous.lazy_index)
    loading = any(d.code < "E100" for d in comp.diagnostics)
    systems = [d for d in root.decls if isinstance(d, ast.SystemDecl)] if root else []
    new_state = None
    if root is not None and not loading and len(systems) == 1:
        new_state = State(text, root, ShiftMap.identity(display, display), program,
                          memo=memo)
    return Analysis(
        uri, version, path, display, text, lines,
        LazyModule(root if root is not None else (previous.module if previous else None)),
        program, tuple(mine), index,
        comp.system if comp.system is not None else kept_system, new_state,
    )


def _finish(mine: list[Diagnostic], root: ast.Module | None) -> list[Diagnostic]:
    if _is_library(root):
        mine = [d for d in mine if not (d.code == "E104" and "no system" in d.message)]
    mine.sort(key=Diagnostic.sort_key)
    return mine


def _imports_unchanged(program: Program, display: str, overrides: dict[Path, str]) -> bool:
    """Do the files the program imported still have the text they were parsed from?"""
    for shown, source in program.sources.items():
        if shown == display or shown.startswith(display + "#"):
            continue
        path = path_of_display(shown)
        if path in overrides:
            now = overrides[path]
        else:
            try:
                now = path.read_text(encoding="utf-8").removeprefix("\ufeff")
            except (OSError, ValueError):   # ValueError: not UTF-8, a NUL in the path
                return False
        if now != source.text:
            return False
    return True


def _agent_blocks(agent: ast.AgentDecl) -> list[Span]:
    out = [agent.span]
    for s in agent.subsystems:
        out.append(s.span)
        out.extend(b.span for b in s.behaviours)
        out.extend(b.span for b in s.buffers)
        out.extend(x.span for x in s.params)
        out.extend(x.span for x in s.memory)
        out.extend(x.span for x in s.switches)
    out.extend(x.span for x in agent.devices)
    return out


def _loader_checks(module: ast.Module, display: str, text: str,
                   shifts: ShiftMap) -> list[Diagnostic]:
    """What the loader checks in a file it reads (an incremental analysis reads none): the
    names that become file names (E011, on the module's stale spans) and the line separators
    in comments (W012, on the text)."""
    stale = DiagnosticBag()
    check_file_names(module, stale)
    out = [map_diagnostic(d, shifts) for d in stale.sorted()]
    if any(c in text for c in LINE_SEPARATORS):
        real = DiagnosticBag()
        check_line_separators(SourceFile(display, text), real)
        out += real.sorted()
    return [d for d in out if d.span.file == display]


def _incremental(uri: str, path: Path, display: str, text: str, version: int | None,
                 lines: LineIndex, got: Reparsed, kept_system: System | None,
                 previous_index: LazyIndex) -> Analysis | None:
    """The analysis of a reparsed text, or None when the whole text must be analysed (an
    error of the loader's checks stops the compiler before the semantic passes)."""
    edit = AgentEdit(got.program, got.system,
                     f"agent:{system_id(got.system)}/{got.replaced.name}", got.replaced,
                     got.agent, got.state.shifts, got.chars, got.lines)
    base, edits = previous_index.after(edit)
    loader = _loader_checks(got.state.module, display, text, got.state.shifts)
    if any(d.severity is Severity.ERROR for d in loader):
        return None
    bag = DiagnosticBag()
    try:
        with collector_paused():
            system = analyze(got.program, bag, got.state.memo)
    except Exception:
        if not got.state.broken:
            raise
        system = None
    shifts = got.state.shifts
    semantic = [d for d in (map_diagnostic(d, shifts) for d in bag.sorted())
                if d.span.file == display]
    mine: list[Diagnostic] = []
    regions: list[tuple[int, int]] = []
    for agent, errors in got.state.broken:
        # semantic diagnostics of a broken agent's declarations would be echoes of it
        blocks = [shifts.span(b) for b in _agent_blocks(agent)]
        for d in (map_diagnostic(e, shifts) for e in errors):
            mine.append(d)
            inner = [b for b in blocks if b.offset <= d.span.offset <= b.end_offset]
            best = min(inner, key=lambda b: b.end_offset - b.offset) if inner else d.span
            regions.append((best.offset, best.end_offset))
    if got.state.broken:
        semantic = [d for d in semantic if "'_'" not in d.message and not any(
            a <= d.span.offset <= b or a <= d.span.end_offset <= b for a, b in regions)]
        system = None
    mine = _finish(mine + semantic + loader, got.state.module)
    return Analysis(
        uri, version, path, display, text, lines, LazyModule(got.state.module, shifts),
        got.program, tuple(mine), LazyIndex(got.program, shifts=shifts, outside_from=(
            previous_index if previous_index.ready else previous_index.outside_from),
            base=base, edits=edits),
        system if system is not None else kept_system, got.state,
        "incremental",
    )
