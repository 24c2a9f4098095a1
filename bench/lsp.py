"""Language-server latency: time from a didChange to the diagnostics published for
that version, on a generated specification of about 5,000 lines. Goal: under 100 ms median.

The server runs as a subprocess (`python -m rssm_dsl lsp`) and is driven over stdio like an
editor would: open the spec, then edit it many times (incremental changes: a parameter value,
a new comment line, a keystroke that breaks a statement and the one that repairs it), each
time waiting for the diagnostics of the new version. The baseline, measured in the same run,
is one in-process `compile_file` of the same text (the work an edit needs without a server);
the ratio shows what the server adds (debounce, JSON-RPC, index, conversion).

    python bench/lsp.py [--agents 75] [--edits 40]
"""

from __future__ import annotations

import argparse
import json
import re
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

from rssm_dsl.pipeline import compile_file

EXAMPLE = Path(__file__).resolve().parents[1] / "examples" / "lwr4_circle.rssm"
GOAL_MS = 100.0


def spec(agents: int) -> str:
    """The paper's agent, repeated: imports, then one system with `agents` agents."""
    text = EXAMPLE.read_text(encoding="utf-8")
    head, _, rest = text.partition("system lwr4_circle {\n")
    agent = rest[: rest.rindex("}")]           # the text of agent a1, up to the system's }
    body = "".join(agent.replace("agent a1 {", f"agent a{i} {{") for i in range(1, agents + 1))
    return f"{head}system big {{\n{body}}}\n"


class Server:
    def __init__(self) -> None:
        self.proc = subprocess.Popen([sys.executable, "-m", "rssm_dsl", "lsp"],
                                     stdin=subprocess.PIPE, stdout=subprocess.PIPE)
        self.next_id = 0

    def send(self, message: dict[str, Any]) -> None:
        body = json.dumps(message).encode()
        assert self.proc.stdin is not None
        self.proc.stdin.write(f"Content-Length: {len(body)}\r\n\r\n".encode() + body)
        self.proc.stdin.flush()

    def read(self) -> dict[str, Any]:
        assert self.proc.stdout is not None
        length = 0
        while True:
            line = self.proc.stdout.readline()
            if not line:
                raise RuntimeError("the server stopped")
            if line in (b"\r\n", b"\n"):
                break
            if line.lower().startswith(b"content-length:"):
                length = int(line.split(b":")[1])
        message: dict[str, Any] = json.loads(self.proc.stdout.read(length))
        return message

    def request(self, method: str, params: Any) -> Any:
        self.next_id += 1
        self.send({"jsonrpc": "2.0", "id": self.next_id, "method": method, "params": params})
        while True:
            msg = self.read()
            if msg.get("id") == self.next_id and "method" not in msg:
                return msg.get("result")

    def notify(self, method: str, params: Any) -> None:
        self.send({"jsonrpc": "2.0", "method": method, "params": params})

    def diagnostics(self, uri: str, version: int) -> list[dict[str, Any]]:
        while True:
            msg = self.read()
            if msg.get("method") == "textDocument/publishDiagnostics":
                p = msg["params"]
                if p["uri"] == uri and p.get("version") == version:
                    return list(p["diagnostics"])

    def close(self) -> None:
        self.request("shutdown", None)
        self.notify("exit", None)
        self.proc.wait(timeout=30)


def _edits(text: str, count: int) -> list[tuple[int, int, str, str]]:
    """(line, character, removed, inserted) edits spread over the file."""
    lines = text.splitlines()
    params = [i for i, line in enumerate(lines) if re.search(r"param \w+: float = 0\.05", line)]
    stmts = [i for i, line in enumerate(lines) if ":=" in line and " + " in line]
    assert params and stmts, "the example has no `param ...: float = 0.05` or `x := a + b`"
    out: list[tuple[int, int, str, str]] = []
    for k in range(count):
        kind = k % 4
        if kind == 0:      # change a parameter value
            n = params[(k * 7) % len(params)]
            col = lines[n].index("0.05")
            out.append((n, col, "0.05", "0.06"))
            out.append((n, col, "0.06", "0.05"))
        elif kind == 1:    # add a comment line, then remove it
            n = params[(k * 11) % len(params)]
            out.append((n, 0, "", "      // tuned on the robot\n"))
            out.append((n, 0, "      // tuned on the robot\n", ""))
        else:              # break a statement mid-typing (a syntax error), then repair it
            n = stmts[(k * 13) % len(stmts)]
            col = lines[n].index("+ ")
            out.append((n, col, "", "* "))
            out.append((n, col, "* ", ""))
    return out[:count]


def _apply(text: str, line: int, col: int, removed: str, inserted: str) -> str:
    starts = [0]
    for i, ch in enumerate(text):
        if ch == "\n":
            starts.append(i + 1)
    at = starts[line] + col
    assert text[at:at + len(removed)] == removed
    return text[:at] + inserted + text[at + len(removed):]


def _end(line: int, col: int, removed: str) -> tuple[int, int]:
    parts = removed.split("\n")
    if len(parts) == 1:
        return line, col + len(removed)
    return line + len(parts) - 1, len(parts[-1])


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--agents", type=int, default=75)
    ap.add_argument("--edits", type=int, default=40)
    args = ap.parse_args()
    text = spec(args.agents)
    nlines = text.count("\n")
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "big.rssm"
        path.write_text(text, encoding="utf-8")
        uri = path.as_uri()
        # baseline: the compiler's own work for one version of the text
        compile_file(path, build=False)
        base = []
        for _ in range(5):
            t0 = time.perf_counter()
            comp = compile_file(path, {path.resolve(): text}, build=False)
            base.append(time.perf_counter() - t0)
        assert comp.ok, comp.diagnostics[:3]
        server = Server()
        server.request("initialize", {"processId": None, "rootUri": Path(tmp).as_uri(),
                                      "capabilities": {}})
        server.notify("initialized", {})
        t0 = time.perf_counter()
        server.notify("textDocument/didOpen", {"textDocument": {
            "uri": uri, "languageId": "rssm", "version": 1, "text": text}})
        first = server.diagnostics(uri, 1)
        opened = time.perf_counter() - t0
        assert first == [], first[:3]
        times: list[float] = []
        version = 1
        current = text
        for line, col, removed, inserted in _edits(text, args.edits):
            version += 1
            end_line, end_col = _end(line, col, removed)
            current = _apply(current, line, col, removed, inserted)
            t0 = time.perf_counter()
            server.notify("textDocument/didChange", {
                "textDocument": {"uri": uri, "version": version},
                "contentChanges": [{"range": {"start": {"line": line, "character": col},
                                              "end": {"line": end_line, "character": end_col}},
                                    "text": inserted}]})
            server.diagnostics(uri, version)
            times.append(time.perf_counter() - t0)
        assert current == text
        server.close()
    med = statistics.median(times) * 1000
    worst = max(times) * 1000
    p90 = sorted(times)[int(0.9 * (len(times) - 1))] * 1000
    baseline = statistics.median(base) * 1000
    print(f"spec: {nlines} lines, {args.agents} agents; {len(times)} edits")
    print(f"baseline compile_file (in-process, same text): {baseline:.0f} ms median")
    print(f"didOpen -> diagnostics: {opened * 1000:.0f} ms")
    print(f"didChange -> diagnostics: median {med:.0f} ms, p90 {p90:.0f} ms, worst {worst:.0f} ms")
    print(f"ratio median/baseline: {med / baseline:.2f}")
    verdict = "met" if med < GOAL_MS else "NOT met"
    print(f"goal: median under {GOAL_MS:.0f} ms: {verdict}")


if __name__ == "__main__":
    main()
