"""The language server: pygls 2 on stdio, the compiler's front end and checks underneath.

Hostile input does not stop it:

- Framing (framing.py): a message announced larger than MAX_MESSAGE_BYTES (64 MiB), a wrong
  Content-Length, a malformed header or a body that is not JSON is answered with a JSON-RPC
  error (id null) and the reader resynchronises on the next `Content-Length:` header.
- Lifecycle (LSP): a request before `initialize` gets ServerNotInitialized (-32002), one after
  `shutdown` InvalidRequest (-32600); notifications then are dropped (but `exit`); `exit`
  ends the process with 0 after `shutdown`, 1 without (also at end of input).
- Long analyses: each document is analysed in a thread of its own (jobs.py), after a short
  debounce on every change; a newer version cancels the running analysis of the older one.
  Requests never queue behind an analysis: those that need a document's analysis wait for
  the current text's at most WAIT_SECONDS, then answer from the last finished analysis (or
  with nothing); other blocking work (symbol index, formatting, outline) runs in job threads
  too, and what a 1 MB one-line file can make huge is capped (MAX_DIAGNOSTICS, the outline's
  MAX_SYMBOLS).

The newest analysis of each document is kept, with the last good semantic model for hover.
"""

from __future__ import annotations

import asyncio
import contextlib
import inspect
import json
import logging
import os
import re
import sys
import threading
import time
from pathlib import Path
from typing import Any, BinaryIO
from urllib.parse import unquote

from cattrs.errors import ClassValidationError
from lsprotocol import types as lsp
from lsprotocol.types import ResponseErrorMessage
from pygls.exceptions import JsonRpcException, JsonRpcInternalError, JsonRpcInvalidParams
from pygls.io_ import StdoutWriter
from pygls.lsp.server import LanguageServer
from pygls.protocol import LanguageServerProtocol
from pygls.protocol.json_rpc import (
    JsonRPCNotification,
    JsonRPCRequestMessage,
    JsonRPCResponseMessage,
)

from rssm_dsl import __version__
from rssm_dsl.lsp import framing, memory
from rssm_dsl.lsp.actions import Fixer
from rssm_dsl.lsp.analysis import Analysis, ModuleView, analyze_text
from rssm_dsl.lsp.completion import complete
from rssm_dsl.lsp.convert import SOURCE, to_lsp
from rssm_dsl.lsp.documents import use_lsp_lines
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
from rssm_dsl.lsp.jobs import Job, run_job
from rssm_dsl.lsp.paths import (
    file_path_of_uri,
    is_stdlib,
    path_of_display,
    path_of_uri,
    resolved,
    uri_of_path,
)
from rssm_dsl.lsp.positions import UTF16, LineIndex
from rssm_dsl.lsp.symbols import outline_json
from rssm_dsl.semantics.loader import display_path
from rssm_dsl.source import Span
from rssm_dsl.syntax import ast
from rssm_dsl.syntax.format import FormatterBug, format_text, keywords

log = logging.getLogger("rssmc.lsp")

WATCHED_GLOBS = ("**/*.rssm", "**/*.py")
WARM_SECONDS = 0.05  # idle time after an analysis before its index is built unasked
DEBOUNCE_SECONDS = float(os.environ.get("RSSMC_LSP_DEBOUNCE_MS", "10")) / 1000
# How long a request waits for the analysis of the text it was made on.
WAIT_SECONDS = 1.0
MAX_WORKSPACE_FILES = 500
MAX_DIAGNOSTICS = 1000     # published per document (a generated file can have 80,000)
# The interval at which a thread that wants the GIL makes the running one hand it over
# (Python's default: 5 ms). An analysis of a small document reads its imports: each read
# releases the GIL and waits a whole interval to get it back from a long analysis running
# beside it (an edit then took 130 ms instead of 7). Switches only happen between threads
# that compete, so a lone analysis is not slowed.
SWITCH_INTERVAL = 0.001
_NAME_RE = re.compile(r"^[A-Za-z_][A-Za-z0-9_]*$")
FIXABLE = frozenset({"E501", "E603", "E304"})
SERVER_NOT_INITIALIZED = -32002
INVALID_REQUEST = -32600


class _Answered(Exception):
    """A malformed request that was already answered with an error."""


def _valid_id(x: object) -> bool:
    """A JSON-RPC request id: a string or an integer (JSON's true is no number)."""
    return isinstance(x, int | str) and not isinstance(x, bool)


class RawJson(str):
    """A result already in JSON (sent as it is, not converted again)."""


class RssmProtocol(LanguageServerProtocol):
    """Answers a request whose params do not fit its method with an error carrying the
    request's id (pygls would only log it), and enforces the LSP lifecycle."""

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        super().__init__(*args, **kwargs)
        self.initialize_seen = False
        self.shutdown_seen = False
        self._writes: set[asyncio.Future[Any]] = set()

    def _send_response(self, msg_id: Any, result: Any | None = None,
                       error: Any | None = None) -> None:
        if error is None and isinstance(result, RawJson):
            self._result_types.pop(msg_id, None)
            body = f'{{"id": {json.dumps(msg_id)}, "jsonrpc": "2.0", "result": {result}}}'
            if self.writer is not None:
                header = (f"Content-Length: {len(body.encode())}\r\n"
                          f"Content-Type: {self.CONTENT_TYPE}; charset={self.CHARSET}\r\n\r\n")
                res = self.writer.write((header + body).encode())
                if inspect.isawaitable(res):   # an async writer (not over stdio)
                    task = asyncio.ensure_future(res)
                    self._writes.add(task)
                    task.add_done_callback(self._writes.discard)
            return
        super()._send_response(msg_id, result, error)

    def structure_message(self, data: dict[str, Any]) -> Any:
        try:
            return self._structure(data)
        except JsonRpcException as e:
            if isinstance(data, dict) and "method" in data and _valid_id(data.get("id")):
                self._send_data({"jsonrpc": "2.0", "id": data["id"], "error": {
                    "code": e.code, "message": f"{e.message}: the params of "
                    f"{data['method']} do not fit the protocol"}})
                raise _Answered from e
            raise

    def _structure(self, data: dict[str, Any]) -> Any:
        """pygls's structure_message, without logging a traceback for the client's mistake
        (it is answered with an error)."""
        if "jsonrpc" not in data:
            return data
        try:
            return self._converter.structure(data, self._message_type(data))
        except ClassValidationError as e:
            log.info("the message does not fit the protocol: %s", e)
            raise JsonRpcInvalidParams() from e
        except Exception as e:
            log.info("the message does not fit the protocol: %s: %s", type(e).__name__, e)
            raise JsonRpcInternalError() from e

    def _message_type(self, data: dict[str, Any]) -> Any:
        if "id" not in data:
            return self.get_message_type(data.get("method", "")) or JsonRPCNotification
        if "error" in data:
            return ResponseErrorMessage
        if "method" in data:
            return self.get_message_type(data["method"]) or JsonRPCRequestMessage
        return self._result_types.pop(data["id"], None) or JsonRPCResponseMessage

    def reject(self, msg_id: Any, code: int, message: str) -> None:
        self._send_data({"jsonrpc": "2.0", "id": msg_id,
                         "error": {"code": code, "message": message}})

    def handle_message(self, message: Any) -> None:
        method = getattr(message, "method", None)
        msg_id = getattr(message, "id", None)
        request = method is not None and _valid_id(msg_id)
        refusal = self._refusal(message, method)
        if refusal is None:
            if method == lsp.INITIALIZE:
                self.initialize_seen = True
            elif method == lsp.SHUTDOWN:
                self.shutdown_seen = True
            super().handle_message(message)
        elif request:
            self.reject(msg_id, *refusal)
        else:
            log.info("dropped %s: %s", method, refusal[1])

    def _refusal(self, message: Any, method: str | None) -> tuple[int, str] | None:
        """Why the message must not be handled now (None: handle it)."""
        if method is None:   # a response, or no message at all (pygls answers that)
            return None
        if getattr(message, "jsonrpc", None) != self.VERSION:
            return INVALID_REQUEST, 'Invalid request: "jsonrpc" must be "2.0"'
        if method == lsp.EXIT:
            return None
        if not self.initialize_seen and method != lsp.INITIALIZE:
            return SERVER_NOT_INITIALIZED, f"{method}: the server is not initialized yet"
        if self.shutdown_seen:
            return INVALID_REQUEST, f"{method}: the server is shutting down"
        if self.initialize_seen and method == lsp.INITIALIZE:
            return INVALID_REQUEST, "initialize: the server is already initialized"
        if method == lsp.TEXT_DOCUMENT_DID_CHANGE and unquote(
                message.params.text_document.uri) not in self.workspace.text_documents:
            return INVALID_REQUEST, "the document is not open"
        return None


class RssmServer(LanguageServer):
    def __init__(self) -> None:
        super().__init__("rssmc", __version__,
                         text_document_sync_kind=lsp.TextDocumentSyncKind.Incremental,
                         protocol_cls=RssmProtocol)
        self.analyses: dict[str, Analysis] = {}
        self.timers: dict[str, asyncio.TimerHandle] = {}
        self.last_change: dict[str, float] = {}   # uri -> when its last change came
        self.jobs: dict[str, Job[Analysis]] = {}     # the running analysis of each document
        self.waiters: dict[str, list[asyncio.Future[None]]] = {}
        self.workspace_cache: dict[Path, tuple[float, SymbolIndex]] = {}
        self.warming: dict[str, Job[object]] = {}    # building the index of an analysis
        self.warm_timers: dict[str, asyncio.TimerHandle] = {}
        self.collect_timer: asyncio.TimerHandle | None = None

    @property
    def rssm_protocol(self) -> RssmProtocol:
        assert isinstance(self.protocol, RssmProtocol)
        return self.protocol

    # ------------------------------------------------------------------ helpers
    @property
    def encoding(self) -> str:
        try:
            enc = self.workspace.position_encoding
        except RuntimeError:
            return UTF16
        return str(getattr(enc, "value", enc) or UTF16)

    def doc_text(self, uri: str) -> tuple[str, int | None] | None:
        """The text and version of an open document (None for any other: a URI is never
        read from disk here, be it /dev/zero or the server's own stdin)."""
        try:
            doc = self.workspace.text_documents.get(unquote(uri))
        except RuntimeError:
            return None
        if doc is None:
            return None
        return doc.source, doc.version

    def open_uris(self) -> list[str]:
        try:
            return list(self.workspace.text_documents.keys())
        except RuntimeError:
            return []

    def overrides(self) -> dict[Path, str]:
        """The open documents' texts by resolved path (paths.py gives every document one
        that resolves; one that stopped resolving meanwhile is left out)."""
        out: dict[Path, str] = {}
        for uri in self.open_uris():
            got = self.doc_text(uri)
            path = resolved(path_of_uri(uri)) if got is not None else None
            if got is not None and path is not None:
                out[path] = got[0]
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
        except (OSError, ValueError):   # ValueError: not UTF-8, a NUL in the path
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
        self._cool(uri)
        timer = self.timers.pop(uri, None)
        if timer is not None:
            timer.cancel()
        loop = asyncio.get_running_loop()
        self.timers[uri] = loop.call_later(delay, self._start, uri)

    def change_delay(self, uri: str) -> float:
        """The debounce of a change (leading edge): the first change after a pause (no
        analysis pending or running, no change for DEBOUNCE_SECONDS) is analysed at once;
        a change within a burst waits DEBOUNCE_SECONDS, so a burst of typing is analysed at
        its end (each change cancels what the one before started)."""
        now = time.monotonic()
        last = self.last_change.get(uri)
        self.last_change[uri] = now
        job = self.jobs.get(uri)
        busy = uri in self.timers or (job is not None and job.running)
        if busy or (last is not None and now - last < DEBOUNCE_SECONDS):
            return DEBOUNCE_SECONDS
        return 0.0

    def _start(self, uri: str) -> None:
        """Analyse the document's current text; an analysis of an older text is stopped."""
        self.timers.pop(uri, None)
        self._stop(uri)
        got = self.doc_text(uri)
        if got is None:
            return
        text, version = got
        try:
            path = path_of_uri(uri)
            display = display_path(path)
            overrides = self.overrides()
        except Exception as e:   # a path that stopped resolving since path_of_uri checked
            self._failed(uri, e)
            return
        previous = self.analyses.get(uri)
        job = Job(lambda: analyze_text(uri, path, display, text, version, overrides, previous),
                  asyncio.get_running_loop(), "rssm-analysis")
        self.jobs[uri] = job
        job.future.add_done_callback(lambda f: self._finished(uri, job))

    def _stop(self, uri: str) -> None:
        job = self.jobs.pop(uri, None)
        if job is not None:
            job.cancel()

    def stop_all(self) -> None:
        for uri in set(self.warming) | set(self.warm_timers):
            self._cool(uri)
        for timer in self.timers.values():
            timer.cancel()
        self.timers.clear()
        for uri in list(self.jobs):
            self._stop(uri)

    def _finished(self, uri: str, job: Job[Analysis]) -> None:
        if self.jobs.get(uri) is job:
            del self.jobs[uri]
        future = job.future
        if future.cancelled():   # superseded (a newer analysis runs) or closed
            return
        error = future.exception()
        if error is not None:
            self._failed(uri, error)
            return
        analysis = future.result()
        got = self.doc_text(uri)
        if got is None:  # closed meanwhile
            self._wake(uri)
            return
        old = self.analyses.get(uri)
        self.analyses[uri] = analysis
        if got[1] == analysis.version:
            self.publish(analysis)
            self._wake(uri)
            self._warm(uri, analysis)
            self._settle()
        if got[1] != analysis.version:
            if uri not in self.timers and uri not in self.jobs:
                self.schedule(uri, 0)
        elif old is None or old.text != analysis.text:
            self._dependents(analysis)

    def _warm(self, uri: str, a: Analysis) -> None:
        """Once the editor has been idle for WARM_SECONDS after publishing an analysis, build
        its outline and its symbol index, so that hover and the outline find them ready
        (and the next edit's index is made from this one). Not at once: the requests that
        follow an edit at once (completion) would share the processor with it. An edit
        stops it: the next analysis makes them stale. The AST with real spans is not built:
        the requests made while typing read the agent under the cursor (view_at); the
        others (references, rename, code actions) build it when asked."""
        if a.lazy_index.ready and a.outlines.get(self.encoding) is not None:
            return
        self._cool(uri)
        encoding = self.encoding

        def build() -> object:
            outline(a, encoding)
            return a.lazy_index.get()

        def start() -> None:
            self.warm_timers.pop(uri, None)
            job: Job[object] = Job(build, asyncio.get_running_loop(), "rssm-warm")
            self.warming[uri] = job
            job.future.add_done_callback(
                lambda f: self.warming.pop(uri, None) if self.warming.get(uri) is job else None)

        self.warm_timers[uri] = asyncio.get_running_loop().call_later(WARM_SECONDS, start)

    def _settle(self) -> None:
        """The objects of the analysis just published out of the collector's way, and a
        full collection once the server is idle (rssm_dsl/lsp/memory.py)."""
        memory.settle()
        if self.collect_timer is not None:
            self.collect_timer.cancel()
        self.collect_timer = asyncio.get_running_loop().call_later(memory.IDLE_SECONDS,
                                                                   memory.collect)

    def _cool(self, uri: str) -> None:
        timer = self.warm_timers.pop(uri, None)
        if timer is not None:
            timer.cancel()
        job = self.warming.pop(uri, None)
        if job is not None:
            job.cancel()

    def _failed(self, uri: str, e: BaseException) -> None:
        log.error("analysis of %s failed", uri, exc_info=e)
        self.text_document_publish_diagnostics(lsp.PublishDiagnosticsParams(
            uri=uri, diagnostics=[lsp.Diagnostic(
                range=lsp.Range(start=lsp.Position(line=0, character=0),
                                end=lsp.Position(line=0, character=0)),
                message=f"internal error of the language server: {type(e).__name__}: {e}"
                "\nhelp: this is a bug in rssmc; please report it with the input file",
                severity=lsp.DiagnosticSeverity.Error, code="E900", source=SOURCE)]))
        self._wake(uri)

    def _dependents(self, changed: Analysis) -> None:
        """Re-analyse the open documents that import the one that changed."""
        for uri, a in list(self.analyses.items()):
            if uri != changed.uri and a.program is not None \
                    and changed.display in a.program.sources:
                self.schedule(uri, DEBOUNCE_SECONDS)

    def files_changed(self, changes: list[tuple[Path, lsp.FileChangeType]]) -> None:
        """Files changed on disk (the editor's file watcher): the open documents that read
        one of them are analysed again, after the usual debounce. A file created or deleted,
        or a Python module changed, may change what any import or extern binding resolves
        to: then every open document is."""
        changed: set[str] = set()
        everything = False
        for path, kind in changes:
            real = resolved(path)
            if real is None:   # e.g. a symbolic link loop now: what read it must look again
                everything = True
                continue
            self.workspace_cache.pop(real, None)
            changed.add(display_path(real))
            if real.suffix != ".rssm" or kind is not lsp.FileChangeType.Changed:
                everything = True
        for uri, a in list(self.analyses.items()):
            if everything or a.program is None or not changed.isdisjoint(a.program.sources):
                self.schedule(uri, DEBOUNCE_SECONDS)

    def _wake(self, uri: str) -> None:
        for w in self.waiters.pop(uri, []):
            if not w.done():
                w.set_result(None)

    async def current(self, uri: str) -> Analysis | None:
        """The analysis of the document's current text; after WAIT_SECONDS without it, the
        last finished analysis (maybe of an older text, maybe None)."""
        got = self.doc_text(uri)
        a = self.analyses.get(uri)
        if got is None:
            return a
        busy = uri in self.timers or uri in self.jobs
        if a is not None and a.version == got[1] and not busy:
            return a
        if not busy:
            self.schedule(uri, 0)
        waiter: asyncio.Future[None] = asyncio.get_running_loop().create_future()
        waiting = self.waiters.setdefault(uri, [])
        waiting.append(waiter)
        try:
            await asyncio.wait_for(waiter, WAIT_SECONDS)
        except TimeoutError:
            with contextlib.suppress(ValueError):
                waiting.remove(waiter)
        return self.analyses.get(uri)

    async def indexed(self, uri: str) -> Analysis | None:
        """The current analysis, with its AST and symbol index built (in a job's thread)."""
        a = await self.current(uri)
        if a is not None and not (a.lazy_module.ready and a.lazy_index.ready):
            await run_job(lambda: (a.lazy_module.get(), a.lazy_index.get()), "rssm-index")
        return a

    async def with_index(self, uri: str) -> Analysis | None:
        """The current analysis, with its symbol index built (in a job's thread); its AST
        is read through `LazyModule.view_at`, which needs nothing built."""
        a = await self.current(uri)
        if a is not None and not a.lazy_index.ready:
            await run_job(a.lazy_index.get, "rssm-index")
        return a

    async def ensure_index(self, a: Analysis) -> None:
        if not a.lazy_index.ready:
            await run_job(a.lazy_index.get, "rssm-index")

    async def ensure_module(self, a: Analysis) -> None:
        """The AST with real spans (mapped after an incremental analysis: long for a huge
        text, so not on the event loop)."""
        if not a.lazy_module.ready:
            await run_job(a.lazy_module.get, "rssm-module")

    def publish(self, a: Analysis) -> None:
        enc = self.encoding
        shown = a.diagnostics[:MAX_DIAGNOSTICS]
        diags = [to_lsp(d, a.lines, enc, lambda s: self.location(s, a)) for d in shown]
        if len(a.diagnostics) > len(shown):
            diags.append(_more(len(a.diagnostics) - len(shown), diags[-1].range))
        self.text_document_publish_diagnostics(
            lsp.PublishDiagnosticsParams(uri=a.uri, version=a.version, diagnostics=diags))

    # ------------------------------------------------------------------ symbols
    def occurrence(self, a: Analysis, pos: lsp.Position) -> Occurrence | None:
        return a.index.at(a.display, a.lines.offset(pos, self.encoding))

    def workspace_indexes(self, root: str | None, overrides: dict[Path, str]
                          ) -> list[SymbolIndex]:
        """Indexes of the .rssm files of the workspace that are not open (cached by mtime).
        Runs in a job's thread: it gets the open documents' texts as arguments."""
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
            rp = resolved(p)
            if rp is None or rp in open_paths:   # None: e.g. a symbolic link loop
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
        overrides = self.overrides()
        others = await run_job(lambda: self.workspace_indexes(root, overrides),
                               "rssm-workspace")
        indexes = [a.index for a in self.analyses.values()] + others
        for ix in indexes:
            for o in ix.references(key):
                k = (o.span.file, o.span.offset, o.span.end_offset)
                if k not in seen:
                    seen.add(k)
                    out.append(o)
        return out


def _more(count: int, at: lsp.Range) -> lsp.Diagnostic:
    """The note that stands for the diagnostics beyond MAX_DIAGNOSTICS."""
    return lsp.Diagnostic(
        range=at, severity=lsp.DiagnosticSeverity.Information, source=SOURCE,
        message=f"{count} more problems in this file are not shown (the editor shows the "
        f"first {MAX_DIAGNOSTICS})\nhelp: run `rssmc check` on the file to see them all")


server = RssmServer()


def classify(error: Exception) -> tuple[int, str] | None:
    """The JSON-RPC error (id null) for a message that could not be handled: a parse error
    for text that is not JSON, an invalid request for JSON that is no message."""
    if isinstance(error, _Answered):
        return None
    if isinstance(error, ValueError):   # json.JSONDecodeError, a body that is not UTF-8
        return framing.PARSE_ERROR, f"Parse error: {error}"
    if isinstance(error, RecursionError):
        return framing.PARSE_ERROR, "Parse error: the JSON is nested too deeply"
    return INVALID_REQUEST, f"Invalid request: {error}"


# ---------------------------------------------------------------------- lifecycle
@server.feature(lsp.INITIALIZE)
def initialize(ls: RssmServer, params: lsp.InitializeParams) -> None:
    use_lsp_lines(ls.workspace)


@server.feature(lsp.INITIALIZED)
def initialized(ls: RssmServer, params: lsp.InitializedParams) -> None:
    """Ask the editor to tell which .rssm and .py files change on disk (imported specs and
    the Python modules of extern bindings), if it can be asked; VS Code's extension says so
    in its own configuration."""
    workspace = ls.client_capabilities.workspace
    watched = workspace.did_change_watched_files if workspace is not None else None
    if watched is None or not watched.dynamic_registration:
        return
    ls.client_register_capability(lsp.RegistrationParams(registrations=[lsp.Registration(
        id="rssmc-watched-files", method=lsp.WORKSPACE_DID_CHANGE_WATCHED_FILES,
        register_options=lsp.DidChangeWatchedFilesRegistrationOptions(watchers=[
            lsp.FileSystemWatcher(glob_pattern=glob) for glob in WATCHED_GLOBS]))]))


@server.feature(lsp.WORKSPACE_DID_CHANGE_WATCHED_FILES)
def did_change_watched_files(ls: RssmServer, params: lsp.DidChangeWatchedFilesParams) -> None:
    changes = [(file_path_of_uri(c.uri), c.type) for c in params.changes]
    ls.files_changed([(path, kind) for path, kind in changes if path is not None])


@server.feature(lsp.SHUTDOWN)
def shutdown(ls: RssmServer, *args: Any) -> None:
    ls.stop_all()


@server.feature(lsp.EXIT)
def exit_(ls: RssmServer, *args: Any) -> None:
    _terminate(0 if ls.rssm_protocol.shutdown_seen else 1)


class _ClientErrors(logging.Filter):
    """pygls logs the traceback of every error it answers; for the JSON-RPC errors raised on
    purpose (invalid params of a request...) the one-line message is enough."""

    def filter(self, record: logging.LogRecord) -> bool:
        if record.exc_info and isinstance(record.exc_info[1], JsonRpcException):
            record.exc_info = None
            record.levelno, record.levelname = logging.INFO, "INFO"
            return log.isEnabledFor(logging.INFO)
        return True


def _terminate(code: int) -> None:
    """End the process now: analyses still running in their threads are abandoned."""
    logging.shutdown()
    for stream in (sys.stdout, sys.stderr, sys.__stdout__):
        with contextlib.suppress(Exception):
            if stream is not None:
                stream.flush()
    os._exit(code)


# ---------------------------------------------------------------------- documents
@server.feature(lsp.TEXT_DOCUMENT_DID_OPEN)
def did_open(ls: RssmServer, params: lsp.DidOpenTextDocumentParams) -> None:
    ls.schedule(params.text_document.uri, 0)


@server.feature(lsp.TEXT_DOCUMENT_DID_CHANGE)
def did_change(ls: RssmServer, params: lsp.DidChangeTextDocumentParams) -> None:
    ls.schedule(params.text_document.uri, ls.change_delay(params.text_document.uri))


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
    ls.last_change.pop(uri, None)
    ls._stop(uri)
    ls._wake(uri)
    a = ls.analyses.pop(uri, None)
    ls.text_document_publish_diagnostics(lsp.PublishDiagnosticsParams(uri=uri, diagnostics=[]))
    if a is not None:
        ls._dependents(a)


# ---------------------------------------------------------------------- features
@server.feature(lsp.TEXT_DOCUMENT_HOVER)
async def hover(ls: RssmServer, params: lsp.HoverParams) -> lsp.Hover | None:
    a = await ls.with_index(params.text_document.uri)
    if a is None or not a.analyzable:
        return None
    from rssm_dsl.lsp.hover import field_hover
    from rssm_dsl.lsp.scope import env_of, field_at, field_span, local_type

    offset = a.lines.offset(params.position, ls.encoding)
    view = a.lazy_module.view_at(offset)
    text = _update_hover(a, view)
    occ = a.index.at(a.display, offset)
    env = env_of(a.program)
    rng: lsp.Range | None = None
    if text is None and occ is not None:
        d = a.index.definitions.get(occ.key)
        if d is not None:
            local = local_type(env, view.module, d.name, view.local(d.full.offset)) \
                if d.key.startswith("local:") and view.module is not None else None
            text = hover_text(d, a.system, env=env, local=local)
            rng = a.lines.range(occ.span, ls.encoding)
    elif text is None and view.module is not None:     # `x.field`, x a record
        found = field_at(env, view.module, view.offset)
        if found is not None:
            x, record = found
            text = field_hover(a.index.definitions.get(f"field:{record.name}.{x.field}"),
                               record, x.field)
            start, end = view.real(*field_span(x))
            rng = a.lines.range(Span(a.display, 1, 1, 1, 1, start, end), ls.encoding)
    if text is None:
        return None
    return lsp.Hover(contents=lsp.MarkupContent(kind=lsp.MarkupKind.Markdown, value=text),
                     range=rng)


def _update_hover(a: Analysis, view: ModuleView) -> str | None:
    module = view.module
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
                        if t.offset <= view.offset <= t.end_offset:
                            key = f"beh:{subsystem_key(system_id(d), ag.name, s)[4:]}.{bd.name}"
                            beh = a.index.definitions.get(key)
                            if beh is None:
                                return None
                            return update_hover(beh, bd.name, u.target, a.system)
    return None


def _field_key(a: Analysis, offset: int) -> str | None:
    """The key of the record field whose name is under the cursor (`x.field`)."""
    from rssm_dsl.lsp.scope import env_of, field_at

    view = a.lazy_module.view_at(offset)
    if view.module is None:
        return None
    found = field_at(env_of(a.program), view.module, view.offset)
    return f"field:{found[1].name}.{found[0].field}" if found is not None else None


@server.feature(lsp.TEXT_DOCUMENT_DEFINITION)
async def definition(ls: RssmServer, params: lsp.DefinitionParams) -> list[lsp.Location] | None:
    a = await ls.with_index(params.text_document.uri)
    if a is None or not a.analyzable:
        return None
    occ = ls.occurrence(a, params.position)
    key = occ.key if occ is not None else \
        _field_key(a, a.lines.offset(params.position, ls.encoding))
    d = a.index.definitions.get(key) if key is not None else None
    if d is None:
        return None
    loc = ls.location(d.span, a)
    return [loc] if loc is not None else None


@server.feature(lsp.TEXT_DOCUMENT_REFERENCES)
async def references(ls: RssmServer, params: lsp.ReferenceParams) -> list[lsp.Location] | None:
    a = await ls.indexed(params.text_document.uri)
    if a is None or not a.analyzable:
        return None
    from rssm_dsl.lsp.scope import env_of, field_uses

    occ = ls.occurrence(a, params.position)
    key = occ.key if occ is not None else \
        _field_key(a, a.lines.offset(params.position, ls.encoding))
    if key is None:
        return None
    include = params.context.include_declaration
    out: list[lsp.Location] = []
    indexed = await ls.all_references(key)
    spans = [o.span for o in indexed if include or not o.definition]
    if key.startswith("field:") and all(o.definition for o in indexed):
        # no use of the field in the indexes: its uses `x.field` in the open documents'
        # programs, by the type of x
        for b in list(ls.analyses.values()):
            if b.program is None or b.module is None:
                continue
            modules = [m for m in b.program.modules if m.path != b.display] + [b.module]
            spans += field_uses(env_of(b.program), modules, key)
    seen: set[tuple[str, int, int]] = set()
    for span in spans:
        if (span.file, span.offset, span.end_offset) in seen:
            continue
        seen.add((span.file, span.offset, span.end_offset))
        loc = ls.location(span, a)
        if loc is not None:
            out.append(loc)
    return out


@server.feature(lsp.TEXT_DOCUMENT_DOCUMENT_SYMBOL)
async def symbols(ls: RssmServer, params: lsp.DocumentSymbolParams) -> RawJson | None:
    a = await ls.current(params.text_document.uri)
    if a is None:
        return None
    enc = ls.encoding
    cached = a.outlines.get(enc)
    if cached is not None:
        return RawJson(cached)
    return await run_job(lambda: outline(a, enc), "rssm-outline")



def outline(a: Analysis, encoding: str) -> RawJson:
    """The document symbols of an analysis in JSON (made once per analysis: the outline of
    a large file is asked for again and again while nothing changes)."""
    with a.outline_lock:     # a request and the idle-time build: one makes it, once
        got = a.outlines.get(encoding)
        if got is None:
            module, real = a.lazy_module.outline_view()
            got, outlined = outline_json(module, a.lines, encoding, real,
                                         a.agent_outlines.get(encoding, {}))
            a.agent_outlines[encoding] = outlined
            a.outlines[encoding] = got
    return RawJson(got)


@server.feature(lsp.TEXT_DOCUMENT_COMPLETION,
                lsp.CompletionOptions(trigger_characters=[".", ":", "(", ">"]))
async def completion(ls: RssmServer, params: lsp.CompletionParams) -> lsp.CompletionList | None:
    uri = params.text_document.uri
    got = ls.doc_text(uri)
    a = ls.analyses.get(uri) or await ls.current(uri)
    if a is None or got is None or not a.analyzable:
        return None
    # completion reads names, not positions: the stale AST of an incremental analysis and
    # the index of an earlier text with the same declarations outside the system will do
    # (right after an edit nothing has to be built)
    index = a.lazy_index.outside()
    if index is None:
        await ls.ensure_index(a)
        index = a.index
    lines = LineIndex(got[0])
    offset = lines.offset(params.position, ls.encoding)
    items = complete(a.lazy_module.names(), index, got[0], offset, a.program, a.system)
    return lsp.CompletionList(is_incomplete=False, items=items)


def _rename_target(ls: RssmServer, a: Analysis, pos: lsp.Position
                   ) -> tuple[Occurrence, Definition] | None:
    """The renameable name at a position (what prepareRename offers; rename.target is the
    same for the in-process tests)."""
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
    """The declaration and its uses in every file (rename.py plans and checks the edits in a
    job's thread). A new name that would clash, or change what the specification means, is
    refused with a RequestFailed error that names the clash."""
    from rssm_dsl.lsp import rename as renaming

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
    indexes = [x.lazy_index for x in ls.analyses.values()]
    try:
        root = ls.workspace.root_path
    except RuntimeError:
        root = None
    overrides = ls.overrides()
    workspace: list[SymbolIndex] = []

    def references(d: Definition) -> list[Occurrence]:
        """Those of the open documents and of the workspace's files (in the job's thread)."""
        if not workspace:
            workspace.extend([x.get() for x in indexes] + ls.workspace_indexes(root, overrides))
        seen: dict[tuple[str, int, int], Occurrence] = {}
        for ix in workspace:
            if renaming.same_declaration(ix, d):
                for o in ix.references(d.key):
                    seen.setdefault((o.span.file, o.span.offset, o.span.end_offset), o)
        return list(seen.values())

    try:
        edits = await run_job(lambda: renaming.plan(a.path, overrides, a.display,
                                                    occ.span.offset, new, references),
                              "rssm-rename")
    except renaming.RenameRefused as e:
        raise JsonRpcException(str(e), code=renaming.REQUEST_FAILED) from None
    changes: dict[str, list[lsp.TextEdit]] = {}
    for file, file_edits in edits.items():
        for start, end, text in file_edits:
            loc = ls.location(Span(file, 1, 1, 1, 1, start, end), a)
            if loc is not None:
                changes.setdefault(loc.uri, []).append(lsp.TextEdit(range=loc.range,
                                                                    new_text=text))
    return lsp.WorkspaceEdit(changes=changes)


@server.feature(lsp.TEXT_DOCUMENT_FORMATTING)
async def formatting(ls: RssmServer, params: lsp.DocumentFormattingParams
                     ) -> list[lsp.TextEdit] | None:
    got = ls.doc_text(params.text_document.uri)
    if got is None or "\x00" in got[0]:
        return None
    text = got[0]
    try:
        result = await run_job(lambda: format_text(text, "<document>"), "rssm-format")
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
    if a is None:
        return []
    await ls.ensure_module(a)
    if a.module is None:
        return []
    fixer = Fixer(a.uri, a.module, a.text, a.lines, ls.encoding)
    out: list[lsp.CodeAction] = []
    for d in wanted:
        out.extend(fixer.fixes(d))
    return out


def serve() -> None:
    """Run on stdio until `exit` (or the end of the input), then end the process with the
    LSP's exit code. Anything printed by mistake goes to stderr, never into the protocol."""
    logging.basicConfig(level=os.environ.get("RSSMC_LSP_LOG", "WARNING"), stream=sys.stderr)
    logging.getLogger("pygls.protocol.json_rpc").addFilter(_ClientErrors())
    sys.setswitchinterval(SWITCH_INTERVAL)
    stdin, stdout = sys.stdin.buffer, sys.stdout.buffer
    sys.stdout = sys.stderr
    _terminate(run(stdin, stdout))


def run(stdin: BinaryIO, stdout: BinaryIO) -> int:
    """Serve until the end of the input: the exit code (0 if `shutdown` was requested)."""
    server._stop_event = threading.Event()
    server.protocol.set_writer(StdoutWriter(stdout))
    read = getattr(stdin, "read1", stdin.read)
    try:
        asyncio.run(framing.serve(read, server.rssm_protocol, classify, server._stop_event))
    except BrokenPipeError:
        log.error("the client closed the connection")
        return 1
    return 0 if server.rssm_protocol.shutdown_seen else 1
