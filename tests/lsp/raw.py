"""A JSON-RPC client over the server's stdio that can send what no library would: arbitrary
bytes, broken frames, requests before `initialize`. Every wait has a timeout, so a server
that stops answering fails a test instead of hanging it."""

from __future__ import annotations

import json
import queue
import subprocess
import threading
import time
from pathlib import Path
from typing import IO, Any

from tests.lsp.conftest import ROOT, SERVER

TIMEOUT = 60.0
HOVER_NOWHERE = {"textDocument": {"uri": "file:///nowhere.rssm"},
                 "position": {"line": 0, "character": 0}}


class RawClient:
    """The real `rssmc lsp` process, spoken to byte by byte."""

    def __init__(self, stderr: IO[bytes] | Path | None = None) -> None:
        err: Any = subprocess.DEVNULL
        if isinstance(stderr, Path):
            err = stderr.open("wb")
        elif stderr is not None:
            err = stderr
        self.proc = subprocess.Popen(SERVER, stdin=subprocess.PIPE, stdout=subprocess.PIPE,
                                     stderr=err, cwd=ROOT)
        self.next_id = 0
        self.notifications: list[dict[str, Any]] = []
        self.others: list[dict[str, Any]] = []   # responses that no wait asked for
        self.inbox: queue.Queue[dict[str, Any] | None] = queue.Queue()
        threading.Thread(target=self._reader, daemon=True).start()

    # ------------------------------------------------------------------ input
    def _reader(self) -> None:
        out = self.proc.stdout
        assert out is not None
        while True:
            length = 0
            while True:
                line = out.readline()
                if not line:
                    self.inbox.put(None)
                    return
                if line in (b"\r\n", b"\n"):
                    break
                if line.lower().startswith(b"content-length:"):
                    length = int(line.split(b":")[1])
            self.inbox.put(json.loads(out.read(length)))

    def read(self, timeout: float = TIMEOUT) -> dict[str, Any]:
        try:
            msg = self.inbox.get(timeout=timeout)
        except queue.Empty:
            raise AssertionError(f"the server sent nothing for {timeout} s") from None
        if msg is None:
            raise AssertionError("the server closed its output")
        return msg

    def response(self, msg_id: int | str | None, timeout: float = TIMEOUT) -> dict[str, Any]:
        """The response to `msg_id` (None: the next error response with id null)."""
        end = time.monotonic() + timeout
        while True:
            msg = self.read(max(0.01, end - time.monotonic()))
            if "method" in msg and "id" not in msg:
                self.notifications.append(msg)
            elif "method" in msg:   # a request from the server: answer it
                self.send({"jsonrpc": "2.0", "id": msg["id"], "result": None})
            elif msg.get("id") == msg_id:
                return msg
            else:
                self.others.append(msg)

    # ------------------------------------------------------------------ output
    def send_bytes(self, data: bytes) -> None:
        assert self.proc.stdin is not None
        self.proc.stdin.write(data)
        self.proc.stdin.flush()

    def send_raw(self, body: bytes) -> None:
        self.send_bytes(f"Content-Length: {len(body)}\r\n\r\n".encode() + body)

    def send(self, message: dict[str, Any]) -> None:
        self.send_raw(json.dumps(message).encode())

    def request(self, method: str, params: Any, timeout: float = TIMEOUT) -> dict[str, Any]:
        self.next_id += 1
        self.send({"jsonrpc": "2.0", "id": self.next_id, "method": method, "params": params})
        return self.response(self.next_id, timeout)

    def notify(self, method: str, params: Any) -> None:
        self.send({"jsonrpc": "2.0", "method": method, "params": params})

    # ------------------------------------------------------------------ sessions
    def initialize(self, capabilities: dict[str, Any] | None = None) -> dict[str, Any]:
        reply = self.request("initialize", {"processId": None, "rootUri": None,
                                            "capabilities": capabilities or {}})
        self.notify("initialized", {})
        return reply

    def diagnostics(self, uri: str, version: int | None = None,
                    timeout: float = TIMEOUT) -> list[dict[str, Any]]:
        """The next diagnostics published for `uri` (for `version`, if given)."""
        end = time.monotonic() + timeout
        while True:
            for msg in self.notifications:
                params = msg.get("params") or {}
                if msg["method"] == "textDocument/publishDiagnostics" \
                        and params.get("uri") == uri \
                        and (version is None or params.get("version") == version):
                    self.notifications.remove(msg)
                    return list(params["diagnostics"])
            msg = self.read(max(0.01, end - time.monotonic()))
            if "method" in msg and "id" not in msg:
                self.notifications.append(msg)
            else:
                self.others.append(msg)

    def open(self, uri: str, text: str, version: int = 1) -> None:
        self.notify("textDocument/didOpen", {"textDocument": {
            "uri": uri, "languageId": "rssm", "version": version, "text": text}})

    def alive(self, timeout: float = TIMEOUT) -> None:
        """The server answers a request (hover on nothing) after whatever came before."""
        reply = self.request("textDocument/hover", HOVER_NOWHERE, timeout)
        assert reply.get("result", "missing") is None, reply
        assert self.proc.poll() is None

    def close(self) -> None:
        self.request("shutdown", None)
        self.notify("exit", None)
        self.proc.wait(timeout=TIMEOUT)

    def kill(self) -> None:
        if self.proc.poll() is None:
            self.proc.kill()
            self.proc.wait(timeout=TIMEOUT)
