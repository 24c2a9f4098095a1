"""The real server (over stdio) with documents whose URIs are hostile: a symbolic link loop, a
NUL (%00), another scheme, %2F and `..` segments, a directory, 100 kB, a host the URL parser
refuses. Each one is analysed from the editor's text, and none of them stops the analysis
of the other documents (issue 33). Also: a Content-Length of any size or form is refused as
a framing error and serving goes on; and a seeded fuzz of document messages with random and
malformed params leaves a well-formed document analysed."""

from __future__ import annotations

import json
import random
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest

from rssm_dsl.lsp.framing import INVALID_REQUEST, PARSE_ERROR, Framer, FramingError, Message
from tests.lsp.raw import RawClient
from tests.lsp.specs import GOOD

AGENT = "a1"        # the agent of the paper's example (tests/lsp/data/circle.rssm)


@pytest.fixture(scope="module")
def server(tmp_path_factory: pytest.TempPathFactory) -> Iterator[tuple[RawClient, Path]]:
    log = tmp_path_factory.mktemp("hostile-documents") / "stderr.txt"
    c = RawClient(stderr=log)
    c.initialize()
    yield c, log
    c.close()
    assert c.proc.returncode == 0


def _names(symbols: Any) -> set[str]:
    """The names in an outline (DocumentSymbol JSON), at every depth."""
    out: set[str] = set()
    for s in symbols or []:
        out.add(s["name"])
        out |= _names(s.get("children"))
    return out


def _outline(c: RawClient, uri: str) -> Any:
    reply = c.request("textDocument/documentSymbol", {"textDocument": {"uri": uri}},
                      timeout=30)
    assert "error" not in reply, reply
    return reply["result"]


def _no_traceback(log: Path) -> None:
    assert "Traceback" not in log.read_text(errors="replace")


def _analysed(c: RawClient, uri: str, version: int = 1) -> None:
    """The document (the paper's example) gets its diagnostics (none) and its outline."""
    assert c.diagnostics(uri, version=version, timeout=30) == []
    assert AGENT in _names(_outline(c, uri))


def _close(c: RawClient, uri: str) -> None:
    c.notify("textDocument/didClose", {"textDocument": {"uri": uri}})


# ---------------------------------------------------------------------- hostile URIs
def _bad_uri(kind: str, tmp: Path) -> str:
    """A document URI of the given kind (the files it names are made in `tmp`)."""
    base = tmp.as_uri()
    if kind == "symlink loop":
        (tmp / "loop.rssm").symlink_to("loop.rssm")
        return base + "/loop.rssm"
    if kind == "inside a symlink loop":
        (tmp / "dirloop").symlink_to("dirloop")
        return base + "/dirloop/inner.rssm"
    return {
        "NUL": base + "/a%00b.rssm",
        "NUL in an untitled URI": "untitled:a%00b",
        "untitled": "untitled:Untitled-1",
        "other scheme": "vscode-notebook-cell:/x/cell.rssm#W0sZmlsZQ%3D%3D",
        "%2F": base + "/a%2Fb.rssm",
        "dot-dot": base + "/sub/../../" + tmp.name + "/dots.rssm",
        "directory": base + "/",
        "100 kB": base + "/" + "a" * 100_000 + ".rssm",
        "100 kB untitled": "untitled:" + "b" * 100_000,
        "invalid IPv6 host": "file://[x/a.rssm",
        "lone surrogate": base + "/\ud800.rssm",
        "empty file URI": "file:",
    }[kind]


KINDS = ["symlink loop", "inside a symlink loop", "NUL", "NUL in an untitled URI", "untitled",
         "other scheme", "%2F", "dot-dot", "directory", "100 kB", "100 kB untitled",
         "invalid IPv6 host", "lone surrogate", "empty file URI"]


@pytest.mark.parametrize("kind", KINDS)
def test_a_hostile_uri_stops_no_analysis(server: tuple[RawClient, Path], tmp_path: Path,
                                         kind: str) -> None:
    c, log = server
    bad = _bad_uri(kind, tmp_path)
    c.open(bad, GOOD)
    # a document opened after the bad one is analysed...
    good = (tmp_path / "good.rssm").as_uri()
    c.open(good, GOOD)
    _analysed(c, good)
    # ...and so is the bad one, from the editor's text
    _analysed(c, bad)
    # an edit of either is analysed again
    for uri in (bad, good):
        c.notify("textDocument/didChange", {
            "textDocument": {"uri": uri, "version": 2},
            "contentChanges": [{"text": GOOD.replace("= 0.05", "= 0.05 + nowhere", 1)}]})
        assert [d["code"] for d in c.diagnostics(uri, version=2, timeout=30)] == ["E102"]
    _close(c, bad)
    _close(c, good)
    # and a document opened after both closed too
    later = (tmp_path / "later.rssm").as_uri()
    c.open(later, GOOD)
    _analysed(c, later)
    _close(c, later)
    c.alive()
    _no_traceback(log)


def test_every_hostile_uri_open_at_once(server: tuple[RawClient, Path],
                                        tmp_path: Path) -> None:
    """All of them open together (each one's path is resolved for every analysis)."""
    c, log = server
    bad = []
    for i, kind in enumerate(KINDS):
        folder = tmp_path / f"k{i}"
        folder.mkdir()
        uri = _bad_uri(kind, folder)
        if uri.startswith("untitled:"):
            uri += f"-{i}"
        bad.append(uri)
        c.open(uri, GOOD)
    good = (tmp_path / "good.rssm").as_uri()
    c.open(good, GOOD)
    _analysed(c, good)
    for uri in bad:
        assert AGENT in _names(_outline(c, uri)), uri[:100]
    for uri in [*bad, good]:
        _close(c, uri)
    c.alive()
    _no_traceback(log)


def test_a_file_that_becomes_a_symlink_loop(server: tuple[RawClient, Path],
                                            tmp_path: Path) -> None:
    """A document whose file turns into a loop while it is open (and whose importer is
    told by the editor's file watcher) stops nothing either."""
    c, log = server
    doc = tmp_path / "turns.rssm"
    doc.write_text(GOOD, encoding="utf-8")
    c.open(doc.as_uri(), GOOD)
    _analysed(c, doc.as_uri())
    doc.unlink()
    doc.symlink_to(doc.name)
    c.notify("workspace/didChangeWatchedFiles",
             {"changes": [{"uri": doc.as_uri(), "type": 2}]})
    c.notify("textDocument/didChange", {
        "textDocument": {"uri": doc.as_uri(), "version": 2},
        "contentChanges": [{"text": GOOD + "\n"}]})
    assert c.diagnostics(doc.as_uri(), version=2, timeout=30) == []
    good = (tmp_path / "good.rssm").as_uri()
    c.open(good, GOOD)
    _analysed(c, good)
    for uri in (doc.as_uri(), good):
        _close(c, uri)
    c.alive()
    _no_traceback(log)


def test_a_symlink_loop_in_the_workspace_fails_no_reference_search(tmp_path: Path) -> None:
    """Find references reads the workspace's other .rssm files: a loop among them is
    skipped, and the open document's references are found."""
    (tmp_path / "loop.rssm").symlink_to("loop.rssm")
    (tmp_path / "other.rssm").write_text(GOOD, encoding="utf-8")
    log = tmp_path / "stderr.txt"
    c = RawClient(stderr=log)
    try:
        c.request("initialize", {"processId": None, "rootUri": tmp_path.as_uri(),
                                 "capabilities": {}})
        c.notify("initialized", {})
        uri = (tmp_path / "doc.rssm").as_uri()
        c.open(uri, GOOD)
        _analysed(c, uri)
        lines = GOOD.split("\n")
        line = next(i for i, text in enumerate(lines) if "param radius" in text)
        at = {"line": line, "character": lines[line].index("radius")}
        reply = c.request("textDocument/references", {
            "textDocument": {"uri": uri}, "position": at,
            "context": {"includeDeclaration": True}})
        assert "error" not in reply, reply
        assert {loc["uri"] for loc in reply["result"]} >= {uri}
        assert len([loc for loc in reply["result"] if loc["uri"] == uri]) == 3
        c.alive()
        c.close()
    finally:
        c.kill()
    assert c.proc.returncode == 0
    _no_traceback(log)


# ---------------------------------------------------------------------- Content-Length
OVER_THE_LIMIT = ["99999999999999", str(2**63 - 1), str(2**63), str(2**64), "9" * 20,
                  "9" * 25, "9" * 5000, "0" * 30 + "1" + "0" * 30]
NOT_A_NUMBER = ["-1", "-" + str(2**63), "+5", "+" + str(2**63), "0x10", "abc", "1e9", "5 5",
                "\u0663".encode().decode("latin-1"), ""]


@pytest.mark.parametrize("length", OVER_THE_LIMIT)
def test_any_length_over_the_limit_is_refused_as_14_digits_are(
        server: tuple[RawClient, Path], tmp_path: Path, length: str) -> None:
    c, log = server
    c.others.clear()
    c.send_bytes(f"Content-Length: {length}\r\n\r\n{{}}".encode())
    c.alive()
    [error] = [m for m in c.others if m.get("id") is None]
    assert error["error"]["code"] == INVALID_REQUEST
    uri = (tmp_path / "after.rssm").as_uri()
    c.open(uri, GOOD)
    _analysed(c, uri)
    _close(c, uri)
    _no_traceback(log)


@pytest.mark.parametrize("length", NOT_A_NUMBER)
def test_a_length_that_is_no_number_is_refused(server: tuple[RawClient, Path],
                                               tmp_path: Path, length: str) -> None:
    c, log = server
    c.others.clear()
    c.send_bytes(f"Content-Length: {length}\r\n\r\n{{}}".encode("latin-1"))
    c.alive()
    errors = [m for m in c.others if m.get("id") is None]
    assert errors and all(e["error"]["code"] == PARSE_ERROR for e in errors), c.others
    uri = (tmp_path / "after.rssm").as_uri()
    c.open(uri, GOOD)
    _analysed(c, uri)
    _close(c, uri)
    _no_traceback(log)


def test_a_huge_length_glued_to_the_next_message(server: tuple[RawClient, Path]) -> None:
    """The announced body would swallow the next message: that one is found all the same."""
    c, log = server
    c.others.clear()
    request = json.dumps({"jsonrpc": "2.0", "id": 4242, "method": "shutdown_not",
                          "params": None}).encode()
    c.send_bytes(f"Content-Length: {2**63}\r\n\r\n".encode()
                 + f"Content-Length: {len(request)}\r\n\r\n".encode() + request)
    assert c.response(4242)["error"]["code"] == -32601    # answered: method not found
    c.alive()
    _no_traceback(log)


@pytest.mark.parametrize("step", [0, 1])
@pytest.mark.parametrize("length", OVER_THE_LIMIT + NOT_A_NUMBER)
def test_the_framer_refuses_any_bad_length_and_finds_the_next_message(length: str,
                                                                      step: int) -> None:
    body = json.dumps({"jsonrpc": "2.0", "id": 1, "method": "shutdown"}).encode()
    data = f"Content-Length: {length}\r\n\r\n{{}}".encode("latin-1") \
        + f"Content-Length: {len(body)}\r\n\r\n".encode() + body
    framer = Framer()
    events = framer.feed(data) if not step else \
        [e for i in range(len(data)) for e in framer.feed(data[i:i + 1])]
    assert events[-1] == Message(body)
    errors = events[:-1]
    assert errors and all(isinstance(e, FramingError) for e in errors)
    assert {e.code for e in errors if isinstance(e, FramingError)} == \
        {INVALID_REQUEST if length in OVER_THE_LIMIT else PARSE_ERROR}


# ---------------------------------------------------------------------- fuzz
SEED = 33
MESSAGES = 250


def _fuzz_uris(tmp: Path) -> list[Any]:
    """Well-formed documents (most messages are about them), hostile URIs, and no URIs."""
    docs = [(tmp / f"doc{i}.rssm").as_uri() for i in range(3)]
    (tmp / "loop.rssm").symlink_to("loop.rssm")
    hostile = [tmp.as_uri() + "/loop.rssm", tmp.as_uri() + "/x%00y.rssm", "untitled:U-1",
               tmp.as_uri() + "/a%2Fb/../c.rssm", tmp.as_uri() + "/", "file://[x/a.rssm",
               "file:", "", "untitled:" + "z" * 10_000, tmp.as_uri() + "/\ud800.rssm",
               "file:///dev/stdin", "file:///nowhere/never.rssm"]
    return docs * 4 + hostile + [None, 5, [], {}, True]


def _text(rng: random.Random) -> Any:
    cut = rng.randrange(len(GOOD) + 1)
    return rng.choice([
        GOOD, GOOD, GOOD[:cut], GOOD[cut:], GOOD.replace("= 0.05", "= nowhere", 1), "",
        "".join(chr(rng.randrange(1, 0x3000)) for _ in range(rng.randrange(50))),
        "\x00binary\x00", "system s { agent a { } }", None, 7, ["text"]])


def _position(rng: random.Random) -> Any:
    def coordinate() -> Any:
        return rng.choice([0, 1, 5, rng.randrange(60), -1, 2**31 - 1, 2**40, "3", None])
    if rng.random() < 0.1:
        return rng.choice([None, 3, "here", [], {}])
    return {"line": coordinate(), "character": coordinate()}


def _change(rng: random.Random) -> Any:
    if rng.random() < 0.4:
        return {"text": _text(rng)}
    return {"range": {"start": _position(rng), "end": _position(rng)},
            "text": rng.choice(["", "x", "agent", "\n", "}", "{", "\r\n\u2028", "😀"])}


def _message(rng: random.Random, uris: list[Any], versions: dict[str, int],
             next_id: int) -> dict[str, Any]:
    method = rng.choice(["didOpen", "didChange", "didClose", "documentSymbol", "hover",
                         "completion"])
    uri = rng.choice(uris)
    version = 1
    if isinstance(uri, str):
        version = versions[uri] = versions.get(uri, 0) + 1
    doc: Any = {"uri": uri}
    params: Any
    if method == "didOpen":
        doc |= {"languageId": rng.choice(["rssm", "", None]),
                "version": rng.choice([version, version, -1, "1", None]), "text": _text(rng)}
        params = {"textDocument": doc}
    elif method == "didChange":
        doc["version"] = rng.choice([version, version, None, -5, "2"])
        params = {"textDocument": doc,
                  "contentChanges": [_change(rng) for _ in range(rng.randrange(3))]}
    elif method in ("didClose", "documentSymbol"):
        params = {"textDocument": doc}
    else:
        params = {"textDocument": doc, "position": _position(rng)}
    # malformed params: a key dropped, a value of another type, no params at all
    roll = rng.random()
    if roll < 0.1:
        params.pop(rng.choice(sorted(params)))
    elif roll < 0.2:
        params[rng.choice(sorted(params))] = rng.choice([None, 0, "x", [], {}, [{}]])
    elif roll < 0.25:
        params = rng.choice([None, [], "params", 3])
    message: dict[str, Any] = {"jsonrpc": "2.0", "method": "textDocument/" + method,
                               "params": params}
    if method in ("documentSymbol", "hover", "completion"):
        message["id"] = next_id
    return message


def test_fuzzed_document_messages_leave_a_good_document_analysed(tmp_path: Path) -> None:
    rng = random.Random(SEED)
    log = tmp_path / "stderr.txt"
    c = RawClient(stderr=log)
    try:
        c.initialize()
        uris = _fuzz_uris(tmp_path)
        versions: dict[str, int] = {}
        for i in range(MESSAGES):
            c.send(_message(rng, uris, versions, 10**6 + i))
        c.alive()
        good = (tmp_path / "good.rssm").as_uri()
        c.open(good, GOOD)
        _analysed(c, good)
        for uri in uris[:3]:     # the fuzzed documents, opened again as they should be
            c.open(uri, GOOD, version=10**6)
            _analysed(c, uri, version=10**6)
        c.alive()
        c.close()
    finally:
        c.kill()
    assert c.proc.returncode == 0
    _no_traceback(log)
