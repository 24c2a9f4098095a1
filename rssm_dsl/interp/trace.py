"""The trace of a run of the interpreter: JSON lines, one event per line, written in batches
and flushed at the end of the run whatever ends it (limit, termination, deadlock, error,
Ctrl-C).

The format (the event kinds and their fields, the header, how values are encoded) is defined
once, in :mod:`rssm_core.trace`, with the writer used here and the one reader; the events of
the interpreter are those of source ``"interpreter"`` there (``start`` with the format
version, ``fire``, ``enter``, ``switch``, ``send``, ``receive``, ``error``, ``deadlock``,
``end``). A ``fire`` line is what `rssmc render`'s playback and `simulate --replay` read back.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

from rssm_core.trace import BATCH, TraceFormatError, TraceWriter
from rssm_core.trace import read_trace as read_events

__all__ = ["BATCH", "TraceFormatError", "TraceWriter", "read_events", "read_trace"]


def read_trace(path: Path) -> list[dict[str, Any]]:
    """The events of a trace file as JSON objects, validated by the core reader (for tests
    and tools; :func:`read_events` gives the typed events)."""
    return [e.to_json() for e in read_events(path).events]
