"""Language-server latency, measured from a real client over stdio, on generated
specifications of about 5,700 and 20,000 lines (the paper's agent, repeated):

- edit: from a didChange to the diagnostics published for that version. Goal (issue 32):
  median under 20 ms at about 5,000 lines and under 50 ms at 20,000, with incremental
  changes and with the whole text sent at each change alike;
- hover, completion, document symbols: from the request to its answer, each asked right
  after an edit's diagnostics (so it pays for whatever the edit left to do), and again
  after 0.3 s without typing ("idle": VS Code's hover delay). Goal: median under 20 ms.

The server runs as a subprocess (`python -m rssm_dsl lsp`) and is driven over stdio like an
editor would: open the spec, then edit it many times (incremental changes: a parameter value,
a new comment line, a keystroke that breaks a statement and the one that repairs it), each
time waiting for the diagnostics of the new version, then asking for one of hover,
completion, symbols in turn. The baseline, measured in the same run, is one in-process
`compile_file` of the same text (the work an edit needs without a server); the ratio shows
what the incremental analysis saves.

    python bench/lsp.py [--agents 75 262] [--edits 60] [--changes incremental|full|both]
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
GOALS_MS = {"edit": (50.0, 100.0), "hover": (20.0, None), "completion": (20.0, None),
            "symbols": (20.0, None), "hover (idle)": (20.0, None),
            "completion (idle)": (20.0, None), "symbols (idle)": (20.0, None)}  # median, p90
IDLE_SECONDS = 0.3   # VS Code asks for a hover after the mouse rests 300 ms (editor.hover.delay)


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


def _pct(times: list[float], q: float) -> float:
    return sorted(times)[int(q * (len(times) - 1))] * 1000


def _position(text: str, pattern: str, nth: int) -> dict[str, int]:
    """The line and character just inside the nth match of `pattern` (ASCII text)."""
    found = [m.start() for m in re.finditer(pattern, text)]
    at = found[nth % len(found)] + 1
    line = text.count("\n", 0, at)
    return {"line": line, "character": at - (text.rfind("\n", 0, at) + 1)}


def run(agents: int, edits: int, full: bool = False) -> dict[str, list[float]]:
    """Latencies (seconds) by kind, and the baseline, for a spec of `agents` agents; with
    ``full``, each change is sent as the whole text (as some clients do)."""
    text = spec(agents)
    nlines = text.count("\n")
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "big.rssm"
        path.write_text(text, encoding="utf-8")
        uri = path.as_uri()
        # baseline: the compiler's own work for one version of the text
        compile_file(path, build=False)
        base = []
        for _ in range(3):
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
        doc = {"uri": uri}
        times: dict[str, list[float]] = {"edit": [], "hover": [], "completion": [],
                                         "symbols": [], "hover (idle)": [],
                                         "completion (idle)": [], "symbols (idle)": []}
        version = 1
        current = text
        for k, (line, col, removed, inserted) in enumerate(_edits(text, edits)):
            version += 1
            end_line, end_col = _end(line, col, removed)
            current = _apply(current, line, col, removed, inserted)
            t0 = time.perf_counter()
            change: dict[str, Any] = {"text": current} if full else {
                "range": {"start": {"line": line, "character": col},
                          "end": {"line": end_line, "character": end_col}},
                "text": inserted}
            server.notify("textDocument/didChange", {
                "textDocument": {"uri": uri, "version": version}, "contentChanges": [change]})
            server.diagnostics(uri, version)
            times["edit"].append(time.perf_counter() - t0)
            kind = ("hover", "completion", "symbols")[k % 3]
            if kind == "hover":     # a buffer's name where it is used
                params: dict[str, Any] = {"textDocument": doc,
                                          "position": _position(current, r"\bsend ", k)}
                params["position"]["character"] += 5
                method = "textDocument/hover"
            elif kind == "completion":   # at the start of an expression
                params = {"textDocument": doc, "position": _position(current, r":= ", k)}
                params["position"]["character"] += 2
                method = "textDocument/completion"
            else:
                params = {"textDocument": doc}
                method = "textDocument/documentSymbol"
            t0 = time.perf_counter()
            answer = server.request(method, params)
            times[kind].append(time.perf_counter() - t0)
            assert answer, (method, params)
            if k % 2 == 0:   # the same after a pause in typing (the index is built meanwhile)
                time.sleep(IDLE_SECONDS)
                t0 = time.perf_counter()
                server.request(method, params)
                times[f"{kind} (idle)"].append(time.perf_counter() - t0)
        assert current == text
        server.close()
    print(f"spec: {nlines} lines, {agents} agents; {len(times['edit'])} edits, "
          f"{'the whole text' if full else 'incremental changes'}")
    print(f"  baseline compile_file (in-process, same text): "
          f"{statistics.median(base) * 1000:.0f} ms median")
    print(f"  didOpen -> diagnostics: {opened * 1000:.0f} ms")
    for kind, ts in times.items():
        med, p90 = _pct(ts, 0.5), _pct(ts, 0.9)
        goal_med, goal_p90 = GOALS_MS[kind]
        if kind == "edit":
            goal_med, goal_p90 = (20.0, None) if nlines <= 6_000 else (50.0, None)
        met = med < goal_med and (goal_p90 is None or p90 < goal_p90)
        goal = f"median < {goal_med:.0f}" + (f", p90 < {goal_p90:.0f}" if goal_p90 else "")
        print(f"  {kind:<17} median {med:5.1f} ms  p90 {p90:5.1f} ms  worst "
              f"{max(ts) * 1000:5.1f} ms  ({len(ts)} runs; goal {goal}: "
              f"{'met' if met else 'NOT met'})")
    print(f"  edit median / baseline: {_pct(times['edit'], 0.5) / 1000 / statistics.median(base):.2f}")
    return times


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--agents", type=int, nargs="+", default=[75, 262])
    ap.add_argument("--edits", type=int, default=60)
    ap.add_argument("--changes", choices=["incremental", "full", "both"], default="both",
                    help="send each edit as a range (incremental), as the whole text (full, as "
                         "some clients do), or both in turn")
    args = ap.parse_args()
    for agents in args.agents:
        for full in {"incremental": [False], "full": [True], "both": [False, True]}[args.changes]:
            run(agents, args.edits, full)


if __name__ == "__main__":
    main()
