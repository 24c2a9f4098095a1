"""Language server under a hostile document: the latency of a hover on a small document while
a 1 MB one-line document is being analysed, against the same hover with no large document
open (the ratio shows how much the long analysis delays other requests), and the server's
peak resident memory (VmHWM of /proc/<pid>/status).

Two 1 MB lines: `const c = [1,1,...]` (a literal of 500,000 elements: seconds of analysis)
and `system s { agent a { } agent a { } ... }` (83,332 agents: as many duplicate-name
diagnostics, of which the server publishes the first 1,000). (`1+1+...`, the other classic,
no longer makes a long analysis: the parser refuses expressions nested deeper than 64 levels
at once.) The server runs as a subprocess (`python -m rssm_dsl lsp`), driven over stdio like
an editor.

    python bench/lsp_hostile.py [--samples 20] [--kind array|agents|both]
"""

from __future__ import annotations

import argparse
import json
import queue
import statistics
import subprocess
import sys
import threading
import time
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parents[1]
SMALL = ROOT / "examples" / "lwr4_circle.rssm"
BIG = {
    "array": "const c = [" + "1," * 499_990 + "1]",
    "agents": "system s { " + "agent a { } " * 83_332 + "}",
}


class Server:
    def __init__(self) -> None:
        self.proc = subprocess.Popen([sys.executable, "-m", "rssm_dsl", "lsp"], cwd=ROOT,
                                     stdin=subprocess.PIPE, stdout=subprocess.PIPE)
        self.next_id = 0
        self.inbox: queue.Queue[dict[str, Any]] = queue.Queue()
        self.published: dict[tuple[str, int | None], float] = {}
        threading.Thread(target=self._reader, daemon=True).start()

    def _reader(self) -> None:
        out = self.proc.stdout
        assert out is not None
        while True:
            length = 0
            while True:
                line = out.readline()
                if not line:
                    return
                if line in (b"\r\n", b"\n"):
                    break
                if line.lower().startswith(b"content-length:"):
                    length = int(line.split(b":")[1])
            msg = json.loads(out.read(length))
            if msg.get("method") == "textDocument/publishDiagnostics":
                p = msg["params"]
                self.published[(p["uri"], p.get("version"))] = time.monotonic()
            else:
                self.inbox.put(msg)

    def send(self, message: dict[str, Any]) -> None:
        body = json.dumps(message).encode()
        assert self.proc.stdin is not None
        self.proc.stdin.write(f"Content-Length: {len(body)}\r\n\r\n".encode() + body)
        self.proc.stdin.flush()

    def request(self, method: str, params: Any) -> Any:
        self.next_id += 1
        self.send({"jsonrpc": "2.0", "id": self.next_id, "method": method, "params": params})
        while True:
            msg = self.inbox.get(timeout=300)
            if msg.get("id") == self.next_id:
                return msg.get("result")

    def notify(self, method: str, params: Any) -> None:
        self.send({"jsonrpc": "2.0", "method": method, "params": params})

    def open(self, uri: str, text: str) -> None:
        self.notify("textDocument/didOpen", {"textDocument": {
            "uri": uri, "languageId": "rssm", "version": 1, "text": text}})

    def wait_published(self, uri: str, timeout: float = 600) -> float:
        end = time.monotonic() + timeout
        while (uri, 1) not in self.published:
            if time.monotonic() > end:
                raise RuntimeError(f"no diagnostics for {uri}")
            time.sleep(0.01)
        return self.published[(uri, 1)]

    def peak_rss_mb(self) -> float:
        for line in Path(f"/proc/{self.proc.pid}/status").read_text().splitlines():
            if line.startswith("VmHWM:"):
                return int(line.split()[1]) / 1024
        return float("nan")

    def close(self) -> None:
        self.request("shutdown", None)
        self.notify("exit", None)
        self.proc.wait(timeout=30)


def _hover_params(text: str, uri: str) -> dict[str, Any]:
    lines = text.split("\n")
    n = next(i for i, line in enumerate(lines) if "radius" in line and "param" not in line)
    return {"textDocument": {"uri": uri},
            "position": {"line": n, "character": lines[n].index("radius") + 1}}


class Small:
    """The small document: hovers on it, as it is or just after an edit (then the hover
    needs the analysis of the new text and its symbol index)."""

    def __init__(self, server: Server) -> None:
        self.server = server
        self.text = SMALL.read_text(encoding="utf-8")
        self.uri = Path("/tmp/rssm-bench-small.rssm").as_uri()
        self.version = 1
        self.params = _hover_params(self.text, self.uri)
        server.open(self.uri, self.text)
        server.wait_published(self.uri)

    def hover_ms(self) -> float:
        start = time.perf_counter()
        result = self.server.request("textDocument/hover", self.params)
        assert result is not None, "the hover found nothing"
        return (time.perf_counter() - start) * 1000

    def edit_and_hover_ms(self) -> float:
        self.version += 1
        old, new = ("0.05", "0.06") if self.version % 2 == 0 else ("0.06", "0.05")
        self.text = self.text.replace(f"radius: float = {old}", f"radius: float = {new}", 1)
        self.server.notify("textDocument/didChange", {
            "textDocument": {"uri": self.uri, "version": self.version},
            "contentChanges": [{"text": self.text}]})
        return self.hover_ms()


def _summary(samples: list[float]) -> str:
    return (f"median {statistics.median(samples):8.1f} ms, max {max(samples):8.1f} ms "
            f"({len(samples)} hovers)")


def measure(kind: str, samples: int) -> None:
    """Hover latencies on the small document without, then while, the 1 MB document of
    `kind` is analysed."""
    server = Server()
    server.request("initialize", {"processId": None, "rootUri": None, "capabilities": {}})
    server.notify("initialized", {})
    small = Small(server)
    small.hover_ms()   # the symbol index is built on the first hover
    quiet = [small.hover_ms() for _ in range(samples)]
    quiet_edit = [small.edit_and_hover_ms() for _ in range(samples)]
    big = Path("/tmp/rssm-bench-big.rssm").as_uri()
    opened = time.monotonic()
    server.open(big, BIG[kind])
    during: list[float] = []
    during_edit: list[float] = []
    while len(during_edit) < samples and (big, 1) not in server.published:
        during_edit.append(small.edit_and_hover_ms())
        if (big, 1) not in server.published:
            during.append(small.hover_ms())
    analysis = server.wait_published(big) - opened
    print(f"[{kind}] 1 MB one-line document ({len(BIG[kind]):,} characters), analysed in "
          f"{analysis:.1f} s")
    for what, a, b in (("hover", quiet, during),
                       ("hover just after an edit", quiet_edit, during_edit)):
        if not b:
            continue
        print(f"  {what}:")
        print(f"    no large document:    {_summary(a)}")
        print(f"    while it is analysed: {_summary(b)}")
        print(f"    ratio of the medians: {statistics.median(b) / statistics.median(a):.2f}")
    print(f"  server's peak RSS (VmHWM): {server.peak_rss_mb():.0f} MB")
    server.close()


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--samples", type=int, default=20)
    ap.add_argument("--kind", choices=["array", "agents", "both"], default="both")
    args = ap.parse_args()
    for kind in (["array", "agents"] if args.kind == "both" else [args.kind]):
        measure(kind, args.samples)


if __name__ == "__main__":
    main()
