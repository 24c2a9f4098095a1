"""The server under bad input: malformed JSON-RPC, unknown methods, huge and binary files,
positions out of range. It answers with errors and stays up."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import pytest

from tests.lsp.raw import RawClient
from tests.lsp.specs import GOOD


@pytest.fixture(scope="module")
def raw() -> Any:
    c = RawClient()
    reply = c.request("initialize", {"processId": None, "rootUri": None, "capabilities": {}})
    assert reply["result"]["capabilities"]["positionEncoding"] == "utf-16"
    c.notify("initialized", {})
    yield c
    c.close()
    assert c.proc.returncode == 0


def test_malformed_json_gets_a_parse_error(raw: RawClient) -> None:
    raw.send_raw(b'{"jsonrpc": "2.0", "id": 99, "method": "textDoc')
    reply = raw.response(None)
    assert reply["error"]["code"] == -32700
    raw.alive()


def test_not_json_rpc_and_bad_params(raw: RawClient) -> None:
    raw.send_raw(b"[1, 2, 3]")
    assert raw.response(None)["error"]["code"] == -32600
    raw.alive()
    reply = raw.request("textDocument/hover", {"textDocument": 5})
    assert reply["error"]["code"] == -32602
    raw.alive()


def test_unknown_method_gets_method_not_found(raw: RawClient) -> None:
    reply = raw.request("rssm/doesNotExist", {"x": 1})
    assert reply["error"]["code"] == -32601
    raw.notify("rssm/unknownNotification", {})
    raw.alive()


def test_a_5mb_file_is_refused_with_a_diagnostic(raw: RawClient) -> None:
    text = GOOD + ("// " + "x" * 97 + "\n") * 52_000
    assert len(text.encode()) > 5_000_000
    uri = "file:///tmp/rssm-huge.rssm"
    raw.open(uri, text)
    [diag] = raw.diagnostics(uri)
    assert diag["code"] == "E004"
    reply = raw.request("textDocument/documentSymbol", {"textDocument": {"uri": uri}})
    assert reply["result"] == []
    raw.alive()


def test_a_binary_file_is_refused_with_a_diagnostic(raw: RawClient) -> None:
    uri = "file:///tmp/rssm-binary.rssm"
    raw.open(uri, "\x00\x01\x02ELF\x00\xff" * 100)
    [diag] = raw.diagnostics(uri)
    assert diag["code"] == "E003"
    for method in ("textDocument/hover", "textDocument/definition",
                   "textDocument/completion", "textDocument/formatting"):
        params: dict[str, Any] = {"textDocument": {"uri": uri},
                                  "position": {"line": 0, "character": 3}}
        if method == "textDocument/formatting":
            params = {"textDocument": {"uri": uri},
                      "options": {"tabSize": 2, "insertSpaces": True}}
        reply = raw.request(method, params)
        assert "error" not in reply
    raw.alive()


def test_positions_out_of_range(raw: RawClient, tmp_path: Path) -> None:
    uri = (tmp_path / "range.rssm").as_uri()
    raw.open(uri, GOOD)
    assert raw.diagnostics(uri) == []
    for line, character in ((10_000, 0), (3, 10_000), (-1, -5), (2**31 - 1, 2**31 - 1)):
        for method in ("textDocument/hover", "textDocument/definition",
                       "textDocument/completion", "textDocument/references",
                       "textDocument/prepareRename"):
            params: dict[str, Any] = {"textDocument": {"uri": uri},
                                      "position": {"line": line, "character": character}}
            if method == "textDocument/references":
                params["context"] = {"includeDeclaration": True}
            reply = raw.request(method, params)
            assert "result" in reply or reply["error"]["code"] in (-32602, -32600), reply
    raw.alive()


def test_requests_for_documents_never_opened(raw: RawClient) -> None:
    for method in ("textDocument/documentSymbol", "textDocument/formatting"):
        params: dict[str, Any] = {"textDocument": {"uri": "file:///never/opened.rssm"}}
        if method == "textDocument/formatting":
            params["options"] = {"tabSize": 2, "insertSpaces": True}
        reply = raw.request(method, params)
        assert "result" in reply
    raw.alive()


def test_utf8_is_used_when_the_client_prefers_it() -> None:
    c = RawClient()
    try:
        reply = c.request("initialize", {"processId": None, "rootUri": None, "capabilities": {
            "general": {"positionEncodings": ["utf-8", "utf-16"]}}})
        assert reply["result"]["capabilities"]["positionEncoding"] == "utf-8"
        c.notify("initialized", {})
        text = GOOD.replace("param radius: float = 0.05",
                            "param radius: float = /* 😀 é */ 0.05 + nowhere", 1)
        uri = "file:///tmp/rssm-utf8.rssm"
        c.open(uri, text)
        [d] = [d for d in c.diagnostics(uri) if d["code"] == "E102"]
        line = text.splitlines()[d["range"]["start"]["line"]]
        col = line.index("nowhere")
        assert d["range"]["start"]["character"] == len(line[:col].encode("utf-8"))
    finally:
        c.close()
    assert c.proc.returncode == 0



