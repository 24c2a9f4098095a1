"""The language server: pygls 2 on stdio, the compiler's front end and checks underneath.

Documents are analysed in a worker thread (the server keeps answering meanwhile), after a
short debounce on every change; the newest analysis of each document is kept, with the last
good semantic model for hover. Requests that depend on positions wait (briefly) for the
analysis of the text they were made on.
"""

from __future__ import annotations

import asyncio
import contextlib
import logging
import os
import re
import sys
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path
from typing import Any

from lsprotocol import types as lsp
from pygls.exceptions import JsonRpcException
from pygls.lsp.server import LanguageServer
from pygls.protocol import LanguageServerProtocol

from rssm_dsl import __version__
from rssm_dsl.lsp.actions import Fixer
from rssm_dsl.lsp.analysis import Analysis, analyze_text
from rssm_dsl.lsp.completion import complete
from rssm_dsl.lsp.convert import to_lsp
from rssm_dsl.lsp.hover import hover_text, update_hover
from rssm_dsl.lsp.index import (
    BUILTIN_NAMES,
    Definition,
    Occurrence,
    SymbolIndex,
    build_index,
    subsystem_key,
    system_id,
)
from rssm_dsl.lsp.paths import is_stdlib, path_of_display, path_of_uri, uri_of_path
from rssm_dsl.lsp.positions import UTF16, LineIndex
from rssm_dsl.lsp.symbols import document_symbols
from rssm_dsl.semantics.loader import display_path
from rssm_dsl.source import Span
from rssm_dsl.syntax import ast
from rssm_dsl.syntax.format import FormatterBug, format_text, keywords

log = logging.getLogger("rssmc.lsp")

DEBOUNCE_SECONDS = float(os.environ.get("RSSMC_LSP_DEBOUNCE_MS", "10")) / 1000
WAIT_SECONDS = 10.0
MAX_WORKSPACE_FILES = 500
_NAME_RE = re.compile(r"^[A-Za-z_][A-Za-z0-9_]*$")
FIXABLE = frozenset({"E501", "E603", "E304"})


class _Answered(Exception):
    """A malformed request that was already answered with an error."""


class RssmProtocol(LanguageServerProtocol):
    """Answers a request whose params do not fit its method with an error carrying the
    request's id (pygls would only log it)."""

    def structure_message(self, data: dict[str, Any]) -> Any:
        try:
            return super().structure_message(data)
        except JsonRpcException as e:
            if isinstance(data, dict) and "method" in data and isinstance(
                    data.get("id"), int | str):
                self._send_data({"jsonrpc": "2.0", "id": data["id"], "error": {
                    "code": e.code, "message": f"{e.message}: the params of "
                    f"{data['method']} do not fit the protocol"}})
                raise _Answered from e
            raise


class RssmServer(LanguageServer):
    def __init__(self) -> None:
        super().__init__("rssmc", __version__,
                         text_document_sync_kind=lsp.TextDocumentSyncKind.Incremental,
                         protocol_cls=RssmProtocol)
        self.analyses: dict[str, Analysis] = {}
        self.timers: dict[str, asyncio.TimerHandle] = {}
        self.running: set[str] = set()
        self.dirty: set[str] = set()
        self.waiters: dict[str, list[asyncio.Future[None]]] = {}
        self.executor = ThreadPoolExecutor(max_workers=1, thread_name_prefix="rssm-analysis")
        self.workspace_cache: dict[Path, tuple[float, SymbolIndex]] = {}

    # ------------------------------------------------------------------ helpers
    @property
    def encoding(self) -> str:
        try:
            enc = self.workspace.position_encoding
        except RuntimeError:
            return UTF16
        return str(getattr(enc, "value", enc) or UTF16)

    def doc_text(self, uri: str) -> tuple[str, int | None] | None:
        try:
            doc = self.workspace.get_text_document(uri)
            return doc.source, doc.version
        except Exception:
            return None

    def open_uris(self) -> list[str]:
        try:
            return list(self.workspace.text_documents.keys())
        except RuntimeError:
            return []

    def overrides(self) -> dict[Path, str]:
        out: dict[Path, str] = {}
        for uri in self.open_uris():
            got = self.doc_text(uri)
            if got is not None:
                out[path_of_uri(uri).resolve()] = got[0]
        return out

    def lines_of(self, file: str, analysis: Analysis | None = None) -> LineIndex | None:
        """The text of a file the compiler named `file` (open document, or as loaded)."""
        for a in self.analyses.values():
            if a.display == file:
                return a.lines
        if analysis is not None and analysis.program is not None:
            src = analysis.program.sources.get(file)
            if src is not None:
                return LineIndex(src.text)
        try:
            return LineIndex(path_of_display(file).read_text(encoding="utf-8"))
        except (OSError, UnicodeDecodeError):
            return None

    def location(self, span: Span, analysis: Analysis | None = None) -> lsp.Location | None:
        lines = self.lines_of(span.file, analysis)
        if lines is None:
            return None
        uri = next((a.uri for a in self.analyses.values() if a.display == span.file), None)
        if uri is None:
            uri = uri_of_path(path_of_display(span.file))
        return lsp.Location(uri=uri, range=lines.range(span, self.encoding))

    # ------------------------------------------------------------------ analysis
    def schedule(self, uri: str, delay: float) -> None:
        timer = self.timers.pop(uri, None)
        if timer is not None:
            timer.cancel()
        loop = asyncio.get_running_loop()
        self.timers[uri] = loop.call_later(delay, self._start, uri)

    def _start(self, uri: str) -> None:
        self.timers.pop(uri, None)
        if uri in self.running:
            self.dirty.add(uri)
            return
        got = self.doc_text(uri)
        if got is None:
            return
        text, version = got
        path = path_of_uri(uri)
        display = display_path(path)
        overrides = self.overrides()
        previous = self.analyses.get(uri)
        self.running.add(uri)
        loop = asyncio.get_running_loop()
        future = loop.run_in_executor(self.executor, analyze_text, uri, path, display, text,
                                      version, overrides, previous)
        future.add_done_callback(lambda f: self._finished(uri, f))

    def _finished(self, uri: str, future: asyncio.Future[Analysis]) -> None:
        self.running.discard(uri)
        try:
            analysis = future.result()
        except Exception as e:
            log.exception("analysis of %s failed", uri)
            self.text_document_publish_diagnostics(lsp.PublishDiagnosticsParams(
                uri=uri, diagnostics=[lsp.Diagnostic(
                    range=lsp.Range(start=lsp.Position(line=0, character=0),
                                    end=lsp.Position(line=0, character=0)),
                    message=f"internal error of the language server: {type(e).__name__}: {e}"
                    "\nhelp: this is a bug in rssmc; please report it with the input file",
                    severity=lsp.DiagnosticSeverity.Error, code="E900", source="rssmc")]))
            self._wake(uri)
            return
        got = self.doc_text(uri)
        if got is None:  # closed meanwhile
            self._wake(uri)
            return
        old = self.analyses.get(uri)
        self.analyses[uri] = analysis
        if got[1] == analysis.version:
            self.publish(analysis)
            self._wake(uri)
        if uri in self.dirty or got[1] != analysis.version:
            self.dirty.discard(uri)
            self.schedule(uri, 0)
        elif old is None or old.text != analysis.text:
            self._dependents(analysis)

    def _dependents(self, changed: Analysis) -> None:
        """Re-analyse the open documents that import the one that changed."""
        for uri, a in list(self.analyses.items()):
            if uri != changed.uri and a.program is not None \
                    and changed.display in a.program.sources:
                self.schedule(uri, DEBOUNCE_SECONDS)

    def _wake(self, uri: str) -> None:
        for w in self.waiters.pop(uri, []):
            if not w.done():
                w.set_result(None)

    async def current(self, uri: str) -> Analysis | None:
        """The analysis of the document's current text (waits for it, briefly)."""
        got = self.doc_text(uri)
        a = self.analyses.get(uri)
        if got is None:
            return a
        if a is not None and a.version == got[1] and uri not in self.timers \
                and uri not in self.running:
            return a
        if uri not in self.timers and uri not in self.running:
            self.schedule(uri, 0)
        waiter: asyncio.Future[None] = asyncio.get_running_loop().create_future()
        self.waiters.setdefault(uri, []).append(waiter)
        with contextlib.suppress(TimeoutError):
            await asyncio.wait_for(waiter, WAIT_SECONDS)
        return self.analyses.get(uri)

    async def indexed(self, uri: str) -> Analysis | None:
        """The current analysis, with its symbol index built (in the worker thread)."""
        a = await self.current(uri)
        if a is not None:
            await self.ensure_index(a)
        return a

    async def ensure_index(self, a: Analysis) -> None:
        if not a.lazy_index.ready:
            await asyncio.get_running_loop().run_in_executor(self.executor, a.lazy_index.get)

    def publish(self, a: Analysis) -> None:
        enc = self.encoding
        diags = [to_lsp(d, a.lines, enc, lambda s: self.location(s, a)) for d in a.diagnostics]
        self.text_document_publish_diagnostics(
            lsp.PublishDiagnosticsParams(uri=a.uri, version=a.version, diagnostics=diags))

    # ------------------------------------------------------------------ symbols
    def occurrence(self, a: Analysis, pos: lsp.Position) -> Occurrence | None:
        return a.index.at(a.display, a.lines.offset(pos, self.encoding))

    def workspace_indexes(self, root: str | None, overrides: dict[Path, str]
                          ) -> list[SymbolIndex]:
        """Indexes of the .rssm files of the workspace that are not open (cached by mtime).
        Runs in the worker thread: it gets the open documents' texts as arguments."""
        if not root:
            return []
        from rssm_dsl.pipeline import compile_file

        open_paths = set(overrides)
        out: list[SymbolIndex] = []
        files = []
        for p in Path(root).rglob("*.rssm"):
            if any(part in ("node_modules", ".git", ".venv", "venv") for part in p.parts):
                continue
            files.append(p)
            if len(files) >= MAX_WORKSPACE_FILES:
                break
        for p in files:
            rp = p.resolve()
            if rp in open_paths:
                continue
            try:
                mtime = rp.stat().st_mtime
            except OSError:
                continue
            cached = self.workspace_cache.get(rp)
            if cached is None or cached[0] != mtime:
                comp = compile_file(rp, overrides, build=False)
                cached = (mtime, build_index(comp.program))
                self.workspace_cache[rp] = cached
            out.append(cached[1])
        return out

    async def all_references(self, key: str) -> list[Occurrence]:
        seen: set[tuple[str, int, int]] = set()
        out: list[Occurrence] = []
        for a in list(self.analyses.values()):
            await self.ensure_index(a)
        try:
            root = self.workspace.root_path
        except RuntimeError:
            root = None
        loop = asyncio.get_running_loop()
        others = await loop.run_in_executor(self.executor, self.workspace_indexes, root,
                                            self.overrides())
        indexes = [a.index for a in self.analyses.values()] + others
        for ix in indexes:
            for o in ix.references(key):
                k = (o.span.file, o.span.offset, o.span.end_offset)
                if k not in seen:
                    seen.add(k)
                    out.append(o)
        return out


server = RssmServer()


def _report_parse_error(error: Exception, source: Any) -> None:
    """Malformed JSON-RPC: answer with a JSON-RPC error (id null) and keep serving: a parse
    error for text that is not JSON, an invalid request for JSON that is no message."""
    if isinstance(error, _Answered):
        return
    if source is JsonRpcException:
        if isinstance(error, ValueError):  # json.JSONDecodeError, a body that is not UTF-8
            code, what = -32700, "Parse error"
        else:
            code, what = -32600, "Invalid request"
        server.protocol._send_data({
            "jsonrpc": "2.0", "id": None, "error": {"code": code, "message": f"{what}: {error}"},
        })
        return
    LanguageServer.report_server_error(server, error, source)


server.report_server_error = _report_parse_error  # type: ignore[method-assign]


# ---------------------------------------------------------------------- documents
@server.feature(lsp.TEXT_DOCUMENT_DID_OPEN)
def did_open(ls: RssmServer, params: lsp.DidOpenTextDocumentParams) -> None:
    ls.schedule(params.text_document.uri, 0)


@server.feature(lsp.TEXT_DOCUMENT_DID_CHANGE)
def did_change(ls: RssmServer, params: lsp.DidChangeTextDocumentParams) -> None:
    ls.schedule(params.text_document.uri, DEBOUNCE_SECONDS)


@server.feature(lsp.TEXT_DOCUMENT_DID_SAVE)
def did_save(ls: RssmServer, params: lsp.DidSaveTextDocumentParams) -> None:
    a = ls.analyses.get(params.text_document.uri)
    if a is not None:
        ls._dependents(a)


@server.feature(lsp.TEXT_DOCUMENT_DID_CLOSE)
def did_close(ls: RssmServer, params: lsp.DidCloseTextDocumentParams) -> None:
    uri = params.text_document.uri
    timer = ls.timers.pop(uri, None)
    if timer is not None:
        timer.cancel()
    a = ls.analyses.pop(uri, None)
    ls.text_document_publish_diagnostics(lsp.PublishDiagnosticsParams(uri=uri, diagnostics=[]))
    if a is not None:
        ls._dependents(a)


# ---------------------------------------------------------------------- features
@server.feature(lsp.TEXT_DOCUMENT_HOVER)
async def hover(ls: RssmServer, params: lsp.HoverParams) -> lsp.Hover | None:
    a = await ls.indexed(params.text_document.uri)
    if a is None or not a.analyzable:
        return None
    offset = a.lines.offset(params.position, ls.encoding)
    text = _update_hover(a, offset)
    occ = a.index.at(a.display, offset)
    if text is None and occ is not None:
        d = a.index.definitions.get(occ.key)
        if d is not None:
            text = hover_text(d, a.system)
            rng = a.lines.range(occ.span, ls.encoding)
            return lsp.Hover(contents=lsp.MarkupContent(kind=lsp.MarkupKind.Markdown,
                                                        value=text), range=rng)
    if text is None:
        return None
    return lsp.Hover(contents=lsp.MarkupContent(kind=lsp.MarkupKind.Markdown, value=text))


def _update_hover(a: Analysis, offset: int) -> str | None:
    module = a.module
    if module is None:
        return None
    for d in module.decls:
        if not isinstance(d, ast.SystemDecl):
            continue
        for ag in d.agents:
            for s in ag.subsystems:
                for bd in s.behaviours:
                    for u in bd.updates:
                        t = u.target_span
                        if t.offset <= offset <= t.end_offset:
                            key = f"beh:{subsystem_key(system_id(d), ag.name, s)[4:]}.{bd.name}"
                            beh = a.index.definitions.get(key)
                            if beh is None:
                                return None
                            return update_hover(beh, bd.name, u.target, a.system)
    return None


@server.feature(lsp.TEXT_DOCUMENT_DEFINITION)
async def definition(ls: RssmServer, params: lsp.DefinitionParams) -> list[lsp.Location] | None:
    a = await ls.indexed(params.text_document.uri)
    if a is None or not a.analyzable:
        return None
    occ = ls.occurrence(a, params.position)
    if occ is None:
        return None
    d = a.index.definitions.get(occ.key)
    if d is None:
        return None
    loc = ls.location(d.span, a)
    return [loc] if loc is not None else None


@server.feature(lsp.TEXT_DOCUMENT_REFERENCES)
async def references(ls: RssmServer, params: lsp.ReferenceParams) -> list[lsp.Location] | None:
    a = await ls.indexed(params.text_document.uri)
    if a is None or not a.analyzable:
        return None
    occ = ls.occurrence(a, params.position)
    if occ is None:
        return None
    include = params.context.include_declaration
    out: list[lsp.Location] = []
    for o in await ls.all_references(occ.key):
        if o.definition and not include:
            continue
        loc = ls.location(o.span, a)
        if loc is not None:
            out.append(loc)
    return out


@server.feature(lsp.TEXT_DOCUMENT_DOCUMENT_SYMBOL)
async def symbols(ls: RssmServer, params: lsp.DocumentSymbolParams
                  ) -> list[lsp.DocumentSymbol] | None:
    a = await ls.current(params.text_document.uri)
    if a is None:
        return None
    return document_symbols(a.module, a.lines, ls.encoding)


@server.feature(lsp.TEXT_DOCUMENT_COMPLETION,
                lsp.CompletionOptions(trigger_characters=[".", ":", "(", ">"]))
async def completion(ls: RssmServer, params: lsp.CompletionParams) -> lsp.CompletionList | None:
    uri = params.text_document.uri
    got = ls.doc_text(uri)
    a = ls.analyses.get(uri) or await ls.current(uri)
    if a is None or got is None or not a.analyzable:
        return None
    await ls.ensure_index(a)
    lines = LineIndex(got[0])
    offset = lines.offset(params.position, ls.encoding)
    items = complete(a.module, a.index, got[0], offset)
    return lsp.CompletionList(is_incomplete=False, items=items)


def _rename_target(ls: RssmServer, a: Analysis, pos: lsp.Position
                   ) -> tuple[Occurrence, Definition] | None:
    occ = ls.occurrence(a, pos)
    if occ is None:
        return None
    d = a.index.definitions.get(occ.key)
    if d is None or not d.renameable or is_stdlib(d.span.file):
        return None
    return occ, d


@server.feature(lsp.TEXT_DOCUMENT_PREPARE_RENAME)
async def prepare_rename(ls: RssmServer, params: lsp.PrepareRenameParams
                         ) -> lsp.PrepareRenamePlaceholder | None:
    a = await ls.indexed(params.text_document.uri)
    if a is None or not a.analyzable:
        return None
    found = _rename_target(ls, a, params.position)
    if found is None:
        return None
    occ, d = found
    return lsp.PrepareRenamePlaceholder(range=a.lines.range(occ.span, ls.encoding),
                                        placeholder=d.name)


@server.feature(lsp.TEXT_DOCUMENT_RENAME)
async def rename(ls: RssmServer, params: lsp.RenameParams) -> lsp.WorkspaceEdit | None:
    from pygls.exceptions import JsonRpcInvalidParams

    a = await ls.indexed(params.text_document.uri)
    if a is None or not a.analyzable:
        return None
    new = params.new_name
    if not _NAME_RE.match(new) or new in keywords() or new in BUILTIN_NAMES:
        raise JsonRpcInvalidParams(f"'{new}' is not a name that can be declared "
                                   "(a keyword, a built-in, or not a name)")
    found = _rename_target(ls, a, params.position)
    if found is None:
        raise JsonRpcInvalidParams("this is not a name that can be renamed here")
    occ, _ = found
    changes: dict[str, list[lsp.TextEdit]] = {}
    for o in await ls.all_references(occ.key):
        if is_stdlib(o.span.file):
            continue
        loc = ls.location(o.span, a)
        if loc is not None:
            changes.setdefault(loc.uri, []).append(lsp.TextEdit(range=loc.range, new_text=new))
    return lsp.WorkspaceEdit(changes=changes)


@server.feature(lsp.TEXT_DOCUMENT_FORMATTING)
async def formatting(ls: RssmServer, params: lsp.DocumentFormattingParams
                     ) -> list[lsp.TextEdit] | None:
    got = ls.doc_text(params.text_document.uri)
    if got is None or "\x00" in got[0]:
        return None
    text = got[0]
    loop = asyncio.get_running_loop()
    try:
        result = await loop.run_in_executor(ls.executor, format_text, text, "<document>")
    except FormatterBug:
        log.exception("formatter")
        return None
    if result.text is None or result.text == text:
        return []
    lines = LineIndex(text)
    return [lsp.TextEdit(range=lines.whole(ls.encoding), new_text=result.text)]


@server.feature(lsp.TEXT_DOCUMENT_CODE_ACTION,
                lsp.CodeActionOptions(code_action_kinds=[lsp.CodeActionKind.QuickFix]))
async def code_action(ls: RssmServer, params: lsp.CodeActionParams
                      ) -> list[lsp.CodeAction] | None:
    wanted = [d for d in params.context.diagnostics if d.code in FIXABLE]
    if not wanted:
        return []
    a = await ls.current(params.text_document.uri)
    if a is None or a.module is None:
        return []
    fixer = Fixer(a.uri, a.module, a.text, a.lines, ls.encoding)
    out: list[lsp.CodeAction] = []
    for d in wanted:
        out.extend(fixer.fixes(d))
    return out


def serve() -> None:
    """Run on stdio. Anything printed by mistake goes to stderr, never into the protocol."""
    logging.basicConfig(level=os.environ.get("RSSMC_LSP_LOG", "WARNING"), stream=sys.stderr)
    stdin, stdout = sys.stdin.buffer, sys.stdout.buffer
    sys.stdout = sys.stderr
    server.start_io(stdin, stdout)



