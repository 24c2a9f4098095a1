"""The trace of a run of the interpreter: JSON lines, one event per line, written in batches
and flushed at the end of the run whatever ends it (limit, termination, deadlock, error,
Ctrl-C).

The format (the event kinds and their fields, the header, how values are encoded) is defined
once, in :mod:`rssm_core.trace`, with the writer used here and the one reader; the events of
the interpreter are those of source ``"interpreter"`` there (``start`` with the format
version, ``fire``, ``enter``, ``switch``, ``send``, ``receive``, ``error``, ``deadlock``,
``end``). A ``fire`` line is what `rssmc render`'s playback and `simulate --replay` read back.

Reading a trace or counterexample file someone gives (``render --trace``, ``simulate
--replay``) is bounded here: the file must be a regular file (a FIFO or ``/dev/zero`` would be
read without end), no line of it may be longer than :data:`MAX_FILE_BYTES` (the one limit of
what the compiler reads as one piece of text, rssm_dsl/source.py), and a JSON value nested too
deeply for the decoder (a ``RecursionError``) or an integer of more digits than Python
converts (a ``ValueError``) is a malformed line, not a crash (:func:`json_problem`). A problem is a
:class:`TraceFileError` with the 1-based line it is at (the callers report it as E852).
"""

from __future__ import annotations

import json
import os
import stat
import sys
from collections.abc import Iterator
from pathlib import Path
from typing import IO, Any

from rssm_core.trace import BATCH, TraceFormatError, TraceWriter
from rssm_core.trace import read_trace as read_events
from rssm_dsl.source import MAX_FILE_BYTES, file_kind

__all__ = ["BATCH", "MAX_FILE_BYTES", "TraceFileError", "TraceFormatError", "TraceWriter",
           "bounded_lines", "check_trace_file", "json_problem",
           "read_events", "read_trace", "scan_trace_file", "starts_with_event", "too_large"]

_CHUNK = 1 << 20
TOO_DEEP = "a JSON value nested too deeply to read"


class TraceFileError(Exception):
    """A trace or counterexample file that cannot be read as one: ``message`` says why,
    ``line`` (1-based) where; ``hint`` what to do."""

    def __init__(self, message: str, line: int = 1, hint: str | None = None) -> None:
        super().__init__(message)
        self.message = message
        self.line = line
        self.hint = hint


def json_problem(e: BaseException) -> str | None:
    """What an exception of the JSON decoder that is no syntax error says of the text: a
    value nested too deeply (``RecursionError``), an integer of more digits than Python
    converts (a ``ValueError``); None for any other exception (it is not the text's)."""
    if isinstance(e, RecursionError):
        return TOO_DEEP
    if isinstance(e, ValueError) and "integer string conversion" in str(e):
        return (f"an integer of more than {sys.get_int_max_str_digits()} digits, more than "
                "rssmc reads")
    return None


def _mb(n: int) -> str:
    return f"{n / (1 << 20):g} MB"


def check_trace_file(path: Path) -> int:
    """The size of the trace or counterexample file ``path``, which must be a regular file;
    else :class:`TraceFileError` (it is not there, cannot be looked up, or is a folder, a
    FIFO, a device: nothing is opened, so a FIFO does not block)."""
    try:
        info = os.stat(path)
    except (OSError, ValueError) as e:        # ValueError: a NUL in the path
        reason = "no such file" if isinstance(e, ValueError | FileNotFoundError) \
            else (e.strerror or str(e))
        raise TraceFileError(f"cannot read '{path}': {reason}",
                             hint="check the path of the file") from None
    if not stat.S_ISREG(info.st_mode):
        raise TraceFileError(f"'{path}' is not a regular file{file_kind(info.st_mode)}",
                             hint="give a trace file of `rssmc simulate --trace` or a report "
                             "of `rssmc verify --format json`")
    return info.st_size


def _too_long(line: int, limit: int) -> TraceFileError:
    return TraceFileError(f"line {line} is longer than {_mb(limit)}, more than a trace line "
                          "or a counterexample holds", line,
                          "give a trace file of `rssmc simulate --trace` or a report of "
                          "`rssmc verify --format json`")


def bounded_lines(f: IO[bytes], limit: int = MAX_FILE_BYTES) -> Iterator[bytes]:
    """The lines of a binary file, each at most ``limit`` bytes (else
    :class:`TraceFileError` at the line, before more than ``limit`` bytes are held)."""
    n = 0
    while True:
        raw = f.readline(limit + 1)
        if not raw:
            return
        n += 1
        if len(raw) > limit and not (len(raw) == limit + 1 and raw.endswith(b"\n")):
            raise _too_long(n, limit)
        yield raw


def starts_with_event(f: IO[bytes]) -> bool:
    """Whether the first non-blank line of the file is a JSON object with ``"event"``: the
    file is a trace of JSON lines (read a line at a time, any length), not one JSON
    document (read whole). Reads from the file's position; each line read is bounded."""
    try:
        head = next((raw for raw in bounded_lines(f) if raw.strip()), b"")
    except TraceFileError:
        return False
    try:
        first = json.loads(head) if head else None
    except (ValueError, RecursionError):    # not JSON, not UTF-8, too deep, too many digits
        return False
    return isinstance(first, dict) and "event" in first


def too_large(path: Path, size: int, limit: int = MAX_FILE_BYTES) -> TraceFileError:
    """The problem of a JSON document (no trace of JSON lines) larger than ``limit``."""
    return TraceFileError(f"'{path}' is {size / 1e6:.1f} MB, larger than a counterexample "
                          f"can be ({limit / 1e6:.1f} MB), and is no trace of JSON lines",
                          hint="give a trace of `rssmc simulate --trace` (JSON lines) or a "
                          "report of `rssmc verify --format json`")


def scan_trace_file(path: Path, limit: int = MAX_FILE_BYTES) -> None:
    """Check a trace or counterexample file before a reader that trusts it reads it: a
    regular file (:func:`check_trace_file`); a trace of JSON lines whose lines are each at
    most ``limit`` bytes, or a JSON document of at most ``limit`` bytes in all. Reads the
    file once in chunks: memory stays bounded whatever the file holds."""
    size = check_trace_file(path)
    try:
        with path.open("rb") as f:
            if size > limit and not starts_with_event(f):
                raise too_large(path, size, limit)
            f.seek(0)
            line, run = 1, 0                   # the line at the chunk's start; its bytes so far
            while chunk := f.read(_CHUNK):
                parts = chunk.split(b"\n")
                for k, part in enumerate(parts):
                    length = run + len(part) if k == 0 else len(part)
                    if length > limit:
                        raise _too_long(line + k, limit)
                run = length
                line += len(parts) - 1
    except OSError as e:
        raise TraceFileError(f"cannot read '{path}': {e.strerror or e}") from None


def read_trace(path: Path) -> list[dict[str, Any]]:
    """The events of a trace file as JSON objects, validated by the core reader (for tests
    and tools; :func:`read_events` gives the typed events)."""
    return [e.to_json() for e in read_events(path).events]
