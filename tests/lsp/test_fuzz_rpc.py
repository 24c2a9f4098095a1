"""JSON-RPC fuzzing of the real server: sequences of well-formed and malformed frames (random
headers, wrong lengths, bodies that are not JSON, JSON that is no request, unknown methods,
params of the wrong types, huge ids, random bytes) interleaved with valid requests. After
every sequence the same server process answers a valid request correctly, and it never
prints a Python traceback.

One server serves every example (starting one takes a second); the examples are few and
small enough for the file to run in well under a minute."""

from __future__ import annotations

import json
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from tests.lsp.raw import HOVER_NOWHERE, RawClient
from tests.lsp.specs import GOOD

DOC = "file:///tmp/rssm-fuzz/doc.rssm"
# real methods (but those ending the session): with random params, they test the params check
METHODS = ["textDocument/hover", "textDocument/completion", "textDocument/definition",
           "textDocument/references", "textDocument/documentSymbol", "textDocument/formatting",
           "textDocument/rename", "textDocument/prepareRename", "textDocument/codeAction",
           "textDocument/didOpen", "textDocument/didChange", "textDocument/didClose",
           "textDocument/didSave", "$/cancelRequest", "$/setTrace", "initialize",
           "initialized", "workspace/executeCommand", "workspace/didChangeConfiguration"]
ENDING = {"shutdown", "exit"}


@pytest.fixture(scope="module")
def server(tmp_path_factory: pytest.TempPathFactory) -> Iterator[tuple[RawClient, Path]]:
    log = tmp_path_factory.mktemp("fuzz") / "stderr.txt"
    c = RawClient(stderr=log)
    c.initialize()
    c.open(DOC, GOOD)
    c.diagnostics(DOC)
    yield c, log
    c.close()
    assert c.proc.returncode == 0


# ---------------------------------------------------------------------- strategies
json_values = st.recursive(
    st.none() | st.booleans() | st.integers(-2**70, 2**70)
    | st.floats(allow_nan=False, allow_infinity=False) | st.text(max_size=20),
    lambda inner: st.lists(inner, max_size=4) | st.dictionaries(st.text(max_size=10), inner,
                                                                max_size=4),
    max_leaves=12)
# never small non-negative integers: those are the ids of the checking requests
ids = (st.integers(10**6, 10**40) | st.integers(-10**40, -1) | st.text(max_size=40)
       | st.just(2**63) | st.just(1e308) | st.none() | st.booleans() | st.just([1]))
positions = st.fixed_dictionaries({"line": st.integers(-5, 2**31), "character":
                                   st.integers(-5, 2**31)})
methods = st.sampled_from(METHODS) | st.text(max_size=30).filter(lambda m: m not in ENDING)
uris = st.sampled_from([DOC, "file:///nowhere.rssm", "file:///dev/stdin", "untitled:x"])


def _frame(body: bytes) -> bytes:
    return f"Content-Length: {len(body)}\r\n\r\n".encode() + body


def _json(value: Any) -> bytes:
    return json.dumps(value).encode()


valid_requests = st.builds(
    lambda i, uri, pos: _frame(_json({"jsonrpc": "2.0", "id": i, "method": "textDocument/hover",
                                      "params": {"textDocument": {"uri": uri},
                                                 "position": pos}})),
    st.integers(10**6, 10**9), uris, positions)
messages = st.builds(
    lambda version, i, method, params, with_id: _frame(_json(
        {"jsonrpc": version, "method": method, "params": params}
        | ({"id": i} if with_id else {}))),
    st.sampled_from(["2.0", "2.0", "2.0", "1.0", 2]), ids, methods, json_values,
    st.booleans())
not_requests = json_values.map(lambda v: _frame(_json(v)))
not_json = st.binary(max_size=200).map(_frame)
wrong_lengths = st.builds(
    lambda body, delta: f"Content-Length: {max(0, len(body) + delta)}\r\n\r\n".encode() + body,
    st.sampled_from([_json({"jsonrpc": "2.0", "id": 10**7, "method": "textDocument/hover",
                            "params": HOVER_NOWHERE}), b"{}", b"[]"]),
    st.integers(-60, 300).filter(lambda d: d != 0))
random_headers = st.builds(
    lambda lines, body: b"".join(lines) + b"\r\n" + body,
    st.lists(st.sampled_from([b"Content-Length: 2\r\n", b"Content-Type: text\r\n",
                              b"X-Foo: bar\r\n", b"content-length:7\r\n",
                              b"Content-Length: -1\r\n", b"Content-Length: 99999999999999\r\n",
                              b"Content-Length 3\r\n", b"\xff\xfe: x\r\n", b": \r\n"])
             | st.binary(max_size=30), max_size=4),
    st.sampled_from([b"{}", b"", b"[1]", b"\x00"]))
random_bytes = st.binary(max_size=300)
frames = st.one_of(valid_requests, messages, not_requests, not_json, wrong_lengths,
                   random_headers, random_bytes)


# ---------------------------------------------------------------------- the test
@settings(max_examples=300, deadline=None,
          suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large])
@given(sequence=st.lists(frames, min_size=1, max_size=8))
def test_the_server_survives_any_sequence(server: tuple[RawClient, Path],
                                          sequence: list[bytes]) -> None:
    c, log = server
    for data in sequence:
        c.send_bytes(data)
    c.others.clear()
    c.notifications.clear()
    reply = c.request("textDocument/hover", HOVER_NOWHERE, timeout=20)
    assert reply.get("result", "missing") is None and "error" not in reply, reply
    assert c.proc.poll() is None
    assert "Traceback" not in log.read_text(errors="replace")
