"""The server under bad input: malformed JSON-RPC, unknown methods, huge and binary files,
positions out of range. It answers with errors and stays up."""

from __future__ import annotations

import json
import subprocess
import time
from pathlib import Path
from typing import Any

import pytest

from tests.lsp.conftest import SERVER
from tests.lsp.specs import GOOD

TIMEOUT = 60.0


class RawClient:
    """JSON-RPC over the server's stdio, byte by byte, to send what no library would."""

    def __init__(self) -> None:
        self.proc = subprocess.Popen(SERVER, stdin=subprocess.PIPE, stdout=subprocess.PIPE,
                                     stderr=subprocess.DEVNULL)
        self.next_id = 0
        self.notifications: list[dict[str, Any]] = []

    def send_raw(self, body: bytes) -> None:
        assert self.proc.stdin is not None
        self.proc.stdin.write(f"Content-Length: {len(body)}\r\n\r\n".encode() + body)
        self.proc.stdin.flush()

    def send(self, message: dict[str, Any]) -> None:
        self.send_raw(json.dumps(message).encode())

    def read(self) -> dict[str, Any]:
        assert self.proc.stdout is not None
        length = 0
        while True:
            line = self.proc.stdout.readline()
            if not line:
                raise AssertionError("the server closed its output")
            if line in (b"\r\n", b"\n"):
                break
            if line.lower().startswith(b"content-length:"):
                length = int(line.split(b":")[1])
        message: dict[str, Any] = json.loads(self.proc.stdout.read(length))
        return message

    def request(self, method: str, params: Any) -> dict[str, Any]:
        self.next_id += 1
        self.send({"jsonrpc": "2.0", "id": self.next_id, "method": method, "params": params})
        return self.response(self.next_id)

    def response(self, msg_id: int | None) -> dict[str, Any]:
        end = time.monotonic() + TIMEOUT
        while time.monotonic() < end:
            msg = self.read()
            if "method" in msg and "id" not in msg:
                self.notifications.append(msg)
                continue
            if "method" in msg:   # a request from the server: answer it
                self.send({"jsonrpc": "2.0", "id": msg["id"], "result": None})
                continue
            if msg.get("id") == msg_id:
                return msg
        raise AssertionError(f"no response to {msg_id}")

    def notify(self, method: str, params: Any) -> None:
        self.send({"jsonrpc": "2.0", "method": method, "params": params})

    def diagnostics(self, uri: str) -> list[dict[str, Any]]:
        end = time.monotonic() + TIMEOUT
        while time.monotonic() < end:
            for msg in self.notifications:
                if msg["method"] == "textDocument/publishDiagnostics" \
                        and msg["params"]["uri"] == uri:
                    self.notifications.remove(msg)
                    return list(msg["params"]["diagnostics"])
            msg = self.read()
            if "method" in msg and "id" not in msg:
                self.notifications.append(msg)
        raise AssertionError(f"no diagnostics for {uri}")

    def open(self, uri: str, text: str) -> None:
        self.notify("textDocument/didOpen", {"textDocument": {
            "uri": uri, "languageId": "rssm", "version": 1, "text": text}})

    def alive(self) -> None:
        """The server answers a request (hover on nothing) after whatever came before."""
        reply = self.request("textDocument/hover", {
            "textDocument": {"uri": "file:///nowhere.rssm"},
            "position": {"line": 0, "character": 0}})
        assert "result" in reply or "error" in reply
        assert self.proc.poll() is None

    def close(self) -> None:
        self.request("shutdown", None)
        self.notify("exit", None)
        self.proc.wait(timeout=TIMEOUT)


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



