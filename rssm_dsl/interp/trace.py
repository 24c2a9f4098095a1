"""The trace of a run: JSON lines, one event per line, written in batches and flushed at the
end of the run whatever ends it (limit, termination, deadlock, error, Ctrl-C).

Every line has ``"event"``; run events have ``"step"`` (firings so far) and ``"time"``
(seconds, simulated or wall-clock). Names are the paper's notation (``t[1,c,cw,4]``,
``p[1,lwr,move,rcv,2,op]``), spans are ``file:line:column`` of the specification.

| event     | fields                                                                        |
|-----------|-------------------------------------------------------------------------------|
| start     | system, spec, mode, seed, places, transitions                                |
| fire      | transition, role, label, span [, subsystem] [, forced]                        |
| enter     | subsystem, behaviour (the initial behaviour starts)                           |
| switch    | subsystem, from, to (null: the subsystem ends), condition, conditions, span   |
| send      | subsystem, buffer, channel, value, overwrote, place, span                     |
| receive   | subsystem, buffer, channel, value, place, span                                |
| error     | code, message, span, subsystem, handled (the error condition path is taken)  |
| deadlock  | marking (place names), waiting (per subsystem: what it waits for)             |
| end       | reason, steps, time, and the final summary                                   |

A ``fire`` line is what `rssmc render`'s playback and `simulate --replay` read back.
"""

from __future__ import annotations

import json
import threading
from pathlib import Path
from typing import Any, TextIO

from rssm_dsl.interp.values import to_json

BATCH = 4096


class TraceWriter:
    """Buffered JSON-lines writer; thread-safe (operations run in workers in concurrent mode)."""

    def __init__(self, path: Path) -> None:
        self.path = path
        self._file: TextIO = path.open("w", encoding="utf-8")
        self._lines: list[str] = []
        self._lock = threading.Lock()
        self.count = 0

    def emit(self, event: dict[str, Any]) -> None:
        line = json.dumps(event, separators=(",", ":"), default=to_json)
        with self._lock:
            self._lines.append(line)
            self.count += 1
            if len(self._lines) >= BATCH:
                self._write()

    def _write(self) -> None:
        if self._lines:
            self._file.write("\n".join(self._lines) + "\n")
            self._lines = []

    def flush(self) -> None:
        with self._lock:
            self._write()
            self._file.flush()

    def close(self) -> None:
        with self._lock:
            self._write()
            self._file.close()


def read_trace(path: Path) -> list[dict[str, Any]]:
    """The events of a trace file (for tests and tools)."""
    with path.open(encoding="utf-8") as f:
        return [json.loads(line) for line in f if line.strip()]
