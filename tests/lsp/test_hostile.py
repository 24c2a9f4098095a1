"""The real server under hostile input: broken framing, a huge announced length, requests out
of the LSP lifecycle, 1 MB one-line documents, and line terminators other than `\\n`. It
answers what must be answered, with the right codes, and keeps serving."""

from __future__ import annotations

import os
import re
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest

from rssm_dsl.lsp.server import MAX_DIAGNOSTICS
from rssm_dsl.lsp.symbols import MAX_SYMBOLS
from tests.lsp.raw import HOVER_NOWHERE, RawClient
from tests.lsp.specs import GOOD

PROMPT = 2.0      # seconds: "promptly" for a request while a long analysis runs
PING = {"jsonrpc": "2.0", "method": "textDocument/hover", "params": HOVER_NOWHERE}


@pytest.fixture(scope="module")
def raw() -> Iterator[RawClient]:
    c = RawClient()
    c.initialize()
    yield c
    c.close()
    assert c.proc.returncode == 0


def _uri(tmp_path: Path, name: str) -> str:
    return (tmp_path / name).as_uri()


# ---------------------------------------------------------------------- framing
BROKEN_FRAMES = {
    "length too short": b"Content-Length: 5\r\n\r\n" + b'{"jsonrpc": "2.0", "id": 1}',
    "length too long": b"Content-Length: 500\r\n\r\n{}",
    "length not a number": b"Content-Length: abc\r\n\r\n{}",
    "headers ended by bare LF": b"Content-Length: 2\n\n{}",
    "body not JSON": b"Content-Length: 5\r\n\r\nhello",
    "body not UTF-8": b"Content-Length: 2\r\n\r\n\xff\xfe",
}


@pytest.mark.parametrize("kind", sorted(BROKEN_FRAMES))
def test_after_a_broken_frame_the_next_request_is_answered(raw: RawClient, kind: str) -> None:
    raw.others.clear()
    raw.send_bytes(BROKEN_FRAMES[kind])
    raw.alive(timeout=10)
    errors = [m for m in raw.others if m.get("id") is None and "error" in m]
    assert errors and all(e["error"]["code"] == -32700 for e in errors), raw.others


def test_a_huge_content_length_is_refused_and_serving_goes_on(raw: RawClient) -> None:
    raw.others.clear()
    raw.send_bytes(b"Content-Length: 99999999999999\r\n\r\n{}")
    raw.alive(timeout=10)
    [error] = [m for m in raw.others if m.get("id") is None]
    assert error["error"]["code"] in (-32600, -32700)
    assert "limit" in error["error"]["message"]


def test_a_uri_is_never_read_from_disk(raw: RawClient) -> None:
    """A request for a document that is not open does not read it (here: the server's own
    stdin, which would swallow the protocol)."""
    for uri in ("file:///dev/stdin", "file:///proc/self/fd/0"):
        reply = raw.request("textDocument/documentSymbol", {"textDocument": {"uri": uri}},
                            timeout=10)
        assert reply["result"] is None
    raw.alive(timeout=10)


# ---------------------------------------------------------------------- lifecycle
def test_before_initialize_requests_get_server_not_initialized() -> None:
    c = RawClient()
    try:
        uri = "file:///tmp/rssm-early.rssm"
        reply = c.request("textDocument/hover", HOVER_NOWHERE, timeout=10)
        assert reply["error"]["code"] == -32002
        c.open(uri, GOOD)                       # a notification: dropped
        assert c.request("shutdown", None, timeout=10)["error"]["code"] == -32002
        assert c.initialize()["result"]["capabilities"]["hoverProvider"]
        reply = c.request("textDocument/documentSymbol", {"textDocument": {"uri": uri}})
        assert reply["result"] is None          # never opened
        assert c.request("initialize", {"capabilities": {}})["error"]["code"] == -32600
        c.alive()
    finally:
        c.close()
    assert c.proc.returncode == 0


def test_after_shutdown_requests_are_invalid_and_exit_returns_0() -> None:
    c = RawClient()
    c.initialize()
    assert c.request("shutdown", None, timeout=10)["result"] is None
    reply = c.request("textDocument/hover", HOVER_NOWHERE, timeout=10)
    assert reply["error"]["code"] == -32600
    c.notify("exit", None)
    assert c.proc.wait(timeout=10) == 0


@pytest.mark.parametrize("initialized", [False, True])
def test_exit_without_shutdown_returns_1(initialized: bool) -> None:
    c = RawClient()
    if initialized:
        c.initialize()
    c.notify("exit", None)
    assert c.proc.wait(timeout=10) == 1


def test_end_of_input_without_shutdown_returns_1() -> None:
    c = RawClient()
    c.initialize()
    assert c.proc.stdin is not None
    c.proc.stdin.close()
    assert c.proc.wait(timeout=10) == 1


# ---------------------------------------------------------------------- huge documents
HUGE = {
    # several seconds of analysis (a literal of 500,000 elements)
    "array": "const c = [" + "1," * 499_990 + "1]",
    # 83,332 diagnostics (duplicate agents): conversions and messages stay bounded
    "agents": "system s { " + "agent a { } " * 83_332 + "}",
}


def _cpu_seconds(pid: int) -> float:
    fields = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")


def _timed(c: RawClient, method: str, params: dict[str, Any]) -> dict[str, Any]:
    start = time.monotonic()
    reply = c.request(method, params, timeout=30)
    took = time.monotonic() - start
    assert took < PROMPT, f"{method} took {took:.1f} s"
    assert "error" not in reply, reply
    return reply


def _published(c: RawClient, uri: str) -> bool:
    return any(m["method"] == "textDocument/publishDiagnostics" and m["params"]["uri"] == uri
               for m in c.notifications)


@pytest.mark.slow
@pytest.mark.parametrize("kind", sorted(HUGE))
def test_a_1mb_line_does_not_block_requests(kind: str, tmp_path: Path) -> None:
    c = RawClient()
    try:
        c.initialize()
        small, big = _uri(tmp_path, "small.rssm"), _uri(tmp_path, "big.rssm")
        c.open(small, GOOD)
        assert c.diagnostics(small) == []
        c.open(big, HUGE[kind])
        at = {"line": 0, "character": 5}
        # another document: a full answer (hover on a parameter's use), during the analysis
        line, col = _position(GOOD, "radius", 1)
        reply = _timed(c, "textDocument/hover", {"textDocument": {"uri": small},
                                                  "position": {"line": line,
                                                               "character": col}})
        assert "radius" in reply["result"]["contents"]["value"]
        assert not _published(c, big)
        # the document being analysed: what was known before (nothing yet), promptly
        _timed(c, "textDocument/hover", {"textDocument": {"uri": big}, "position": at})
        _timed(c, "textDocument/completion", {"textDocument": {"uri": big}, "position": at})
        _timed(c, "textDocument/documentSymbol", {"textDocument": {"uri": big}})
        if kind == "agents":   # then the diagnostics, capped, and an outline, capped
            diags = c.diagnostics(big, timeout=120)
            assert len(diags) == MAX_DIAGNOSTICS + 1
            assert "82332 more problems" in diags[-1]["message"]   # 83,332 in all
            [system] = _timed(c, "textDocument/documentSymbol",
                              {"textDocument": {"uri": big}})["result"]
            assert len(system["children"]) == MAX_SYMBOLS
        _timed(c, "shutdown", {})
        c.notify("exit", None)
        assert c.proc.wait(timeout=PROMPT) == 0
    finally:
        c.kill()


@pytest.mark.slow
def test_a_new_version_stops_the_analysis_of_the_old_one(tmp_path: Path) -> None:
    c = RawClient()
    try:
        c.initialize()
        uri = _uri(tmp_path, "array.rssm")
        c.open(uri, HUGE["array"])                 # seconds of analysis
        c.alive()
        c.notify("textDocument/didChange", {
            "textDocument": {"uri": uri, "version": 2},
            "contentChanges": [{"text": "system s { agent a { } }"}]})
        start = time.monotonic()
        diags = c.diagnostics(uri, version=2, timeout=30)
        assert time.monotonic() - start < PROMPT
        assert [d["code"] for d in diags] == ["E301"]   # the new text's problem
        assert not _published(c, uri)                  # nothing for version 1
        # and the old analysis is not running on: the server is idle
        before = _cpu_seconds(c.proc.pid)
        time.sleep(1.0)
        assert _cpu_seconds(c.proc.pid) - before < 0.3
    finally:
        c.kill()


def _position(text: str, needle: str, nth: int = 0, sep: str = "\n") -> tuple[int, int]:
    """(line, UTF-16 character) of the nth `needle`, lines split on `sep` only."""
    return _position_at(text, [m.start() for m in re.finditer(re.escape(needle), text)][nth],
                        sep)


def _position_at(text: str, offset: int, sep: str = "\n") -> tuple[int, int]:
    before = text[:offset].split(sep)
    return len(before) - 1, len(before[-1].encode("utf-16-le")) // 2


# ---------------------------------------------------------------------- line terminators
def _no_comments(text: str) -> str:
    return re.sub(r"//[^\n]*", "", text)


def test_bare_cr_line_ends_place_diagnostics_hover_and_definition(raw: RawClient,
                                                                  tmp_path: Path) -> None:
    text = _no_comments(GOOD).replace("param radius: float = 0.05",
                                      "param radius: float = 0.05 + nowhere", 1)
    text = text.replace("\n", "\r")
    uri = _uri(tmp_path, "cr.rssm")
    raw.open(uri, text)
    [d] = [d for d in raw.diagnostics(uri) if d["code"] == "E102"]
    line, col = _position(text, "nowhere", sep="\r")
    assert line == 9   # the file's 10th line: lines are counted at CR
    assert d["range"]["start"] == {"line": line, "character": col}
    # hover and definition of `radius` where it is used: the declaration's line
    use_line, use_col = _position(text, "radius", 1, sep="\r")
    where = {"textDocument": {"uri": uri}, "position": {"line": use_line, "character": use_col}}
    hover = raw.request("textDocument/hover", where)["result"]
    assert "radius" in hover["contents"]["value"]
    [loc] = raw.request("textDocument/definition", where)["result"]
    assert loc["range"]["start"] == dict(zip(("line", "character"),
                                             _position(text, "radius", 0, sep="\r"),
                                             strict=True))


def test_u2028_is_no_line_end(raw: RawClient, tmp_path: Path) -> None:
    """U+2028 (and U+2029, U+0085) in comments: one UTF-16 unit, no new line, also for an
    incremental edit below them. (The compiler warns of them in a `//` comment: W012.)"""
    text = GOOD.replace("param radius: float = 0.05",
                        "param radius: float = /* \u2028 */ 0.05", 1)
    first_line_end = text.index("\n")
    text = text[:first_line_end] + " // a\u2028b\u2029c\x85d" + text[first_line_end:]
    uri = _uri(tmp_path, "u2028.rssm")
    raw.open(uri, text)
    [w012] = raw.diagnostics(uri, version=1)
    separator = _position(text, "\u2028")
    assert separator[0] == 0
    assert (w012["code"], w012["range"]) == ("W012", {
        "start": {"line": 0, "character": separator[1]},
        "end": {"line": 0, "character": separator[1] + 1}})
    line, end = _position_at(text, text.index("*/ 0.05") + len("*/ 0.05"))
    raw.notify("textDocument/didChange", {
        "textDocument": {"uri": uri, "version": 2},
        "contentChanges": [{"range": {"start": {"line": line, "character": end},
                                      "end": {"line": line, "character": end}},
                            "text": " + nowhere"}]})
    new = text.replace("*/ 0.05", "*/ 0.05 + nowhere", 1)
    diags = {d["code"]: d for d in raw.diagnostics(uri, version=2)}
    assert sorted(diags) == ["E102", "W012"]
    assert diags["E102"]["range"]["start"] == dict(
        zip(("line", "character"), _position(new, "nowhere"), strict=True))
    assert diags["E102"]["range"]["start"]["character"] == \
        new.split("\n")[line].index("nowhere")
