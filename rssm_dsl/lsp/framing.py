"""The LSP base protocol on a byte stream: `Content-Length: N\\r\\n` (and maybe a
`Content-Type` header, the only other one the protocol defines), an empty line, then N bytes
of JSON. pygls's reader gives up on the first framing error
(a wrong length, a header ended by a bare `\\n`...) and dies of a huge announced length; this
one reports the error and resynchronises on the next `Content-Length:` header.

Any other header is a framing error too: it is how junk glued to the next message's header
looks (`XContent-Length: 150`), and taking it for a header would lose that message.

Resynchronising is safe because a header line (`Content-Length: 12` then CR LF) can never
occur inside a valid JSON body: outside strings the text is not JSON, and JSON strings cannot
hold a raw CR or LF. So a body that contains one is broken (its length was too long), and
the header is the next message's.

`Framer` splits the stream (it does no I/O, for tests); `serve` reads stdin in a thread and
hands each message to pygls's protocol, answering framing and JSON errors with a JSON-RPC
error (id null).
"""

from __future__ import annotations

import asyncio
import json
import logging
import re
import threading
from collections.abc import Callable
from typing import Any, Protocol

from rssm_core.records import dataclass

log = logging.getLogger("rssmc.lsp")

# The largest message accepted: 64 MiB (a document of a few million characters, as JSON).
# A larger announced length is answered with an error and skipped.
MAX_MESSAGE_BYTES = 64 * 1024 * 1024
MAX_HEADER_BYTES = 16 * 1024
PARSE_ERROR = -32700
INVALID_REQUEST = -32600
CHUNK = 64 * 1024

_HEADER_LINE = re.compile(rb"([!#$%&'*+.^_`|~0-9A-Za-z-]+):[ \t]*([^\r\n]*?)[ \t]*\r\n")
_LENGTH = re.compile(rb"[0-9]+")
# A length of more digits (leading zeros aside) is taken as this one: over any limit, and
# never given to int() (which refuses 4,300 digits) nor to a C size (2**63 overflows one).
TOO_MANY_BYTES = 10**20
_RESYNC = re.compile(rb"content-length:[ \t]*[0-9]+[ \t]*\r\n", re.IGNORECASE)
_TAIL = 64   # bytes kept between chunks while looking for a header (longer than one)
# the start of a header line, up to its CR: what a body cut inside the next header ends with
_PARTIAL = re.compile(rb"c(?:o(?:n(?:t(?:e(?:n(?:t(?:-(?:l(?:e(?:n(?:g(?:t(?:h(?::[ \t]*"
                      rb"[0-9]*[ \t]*\r?)?)?)?)?)?)?)?)?)?)?)?)?)?)?\Z", re.IGNORECASE)


@dataclass(frozen=True)
class Message:
    body: bytes


@dataclass(frozen=True)
class FramingError:
    """Bytes that were not a well-framed message (answered with `code`, id null)."""

    reason: str
    code: int = PARSE_ERROR


Event = Message | FramingError


class Framer:
    """Splits a byte stream into messages; after a framing error, skips to the next
    `Content-Length:` header line. Memory stays bounded by MAX_MESSAGE_BYTES."""

    def __init__(self, max_bytes: int = MAX_MESSAGE_BYTES) -> None:
        self.max_bytes = max_bytes
        self.buf = bytearray()
        self.length: int | None = None   # reading a body of this length
        self.skip: int | None = None      # discarding an oversized body (bytes left)
        self.junk = False                 # discarding up to the next header
        self.scanned = 0                  # body bytes already searched for a header

    def feed(self, data: bytes) -> list[Event]:
        self.buf += data
        out: list[Event] = []
        while self._step(out):
            pass
        return out

    # ------------------------------------------------------------------ states
    def _step(self, out: list[Event]) -> bool:
        """Advance once; False when more bytes are needed."""
        if self.junk:
            return self._resync()
        if self.skip is not None:
            return self._skip()
        if self.length is not None:
            return self._body(out)
        return self._headers(out)

    def _error(self, out: list[Event], reason: str, code: int = PARSE_ERROR,
               resync_from: int = 1, then_headers: bool = False) -> bool:
        """Report, then look for a header from `resync_from` on (or read headers there)."""
        out.append(FramingError(reason, code))
        del self.buf[:resync_from]
        self.length = self.skip = None
        self.junk = not then_headers
        return True

    def _resync(self) -> bool:
        m = _RESYNC.search(self.buf)
        if m is None:
            if len(self.buf) > _TAIL:
                del self.buf[:len(self.buf) - _TAIL]
            return False
        del self.buf[:m.start()]
        self.junk = False
        return True

    def _skip(self) -> bool:
        assert self.skip is not None
        n = self.skip
        # (n may be any announced length: a bound over len(buf) would overflow a C size)
        m = _RESYNC.search(self.buf, 0, min(n + _TAIL, len(self.buf)))
        if m is not None and m.start() < n:      # the announced length was a lie
            del self.buf[:m.start()]
            self.skip = None
            return True
        if len(self.buf) >= n:
            del self.buf[:n]
            self.skip = None
            return True
        drop = max(0, len(self.buf) - _TAIL)
        del self.buf[:drop]
        self.skip -= drop
        return False

    def _body(self, out: list[Event]) -> bool:
        assert self.length is not None
        n = self.length
        m = _RESYNC.search(self.buf, max(0, self.scanned - _TAIL), min(len(self.buf), n))
        if m is not None:
            return self._error(out, f"the header announced {n} bytes but the next message "
                               f"began after {m.start()}", resync_from=m.start())
        self.scanned = min(len(self.buf), n)
        if len(self.buf) < n:
            return False
        # a body cut inside the next header: no JSON text ends like the start of a header
        cut = _PARTIAL.search(self.buf, max(0, n - _TAIL), n)
        if cut is not None:
            return self._error(out, f"the header announced {n} bytes but the next message "
                               f"began after {cut.start()}", resync_from=cut.start(),
                               then_headers=True)
        out.append(Message(bytes(self.buf[:n])))
        del self.buf[:n]
        self.length = None
        return True

    def _headers(self, out: list[Event]) -> bool:
        # blank lines between messages are tolerated
        while self.buf[:2] == b"\r\n" or self.buf[:1] == b"\n":
            del self.buf[:2 if self.buf[:1] == b"\r" else 1]
        end = self.buf.find(b"\r\n\r\n", 0, MAX_HEADER_BYTES)
        if end < 0:
            return self._incomplete_headers(out)
        head = bytes(self.buf[:end + 2])
        length, problem = _content_length(head)
        if problem is not None:
            return self._error(out, problem)
        assert length is not None
        del self.buf[:end + 4]
        if length > self.max_bytes:
            size = f"{length}" if length < TOO_MANY_BYTES else f"{TOO_MANY_BYTES} or more"
            out.append(FramingError(f"a message of {size} bytes is larger than the limit "
                                    f"of {self.max_bytes} bytes", INVALID_REQUEST))
            self.skip = length
            return True
        self.length, self.scanned = length, 0
        return True

    def _incomplete_headers(self, out: list[Event]) -> bool:
        """No empty line yet: fail early on a line that cannot be a header."""
        if len(self.buf) > MAX_HEADER_BYTES:
            return self._error(out, f"the headers are longer than {MAX_HEADER_BYTES} bytes")
        pos = 0
        while True:
            nl = self.buf.find(b"\n", pos)
            if nl < 0:
                return False
            problem = _header_problem(_HEADER_LINE.fullmatch(self.buf, pos, nl + 1))
            if problem is not None:
                return self._error(out, problem)
            pos = nl + 1


def _content_length(head: bytes) -> tuple[int | None, str | None]:
    """The Content-Length of a header block (each line ended by CR LF), or the problem."""
    length: int | None = None
    pos = 0
    while pos < len(head):
        m = _HEADER_LINE.match(head, pos)
        problem = _header_problem(m)
        if problem is not None:
            return None, problem
        assert m is not None
        pos = m.end()
        if m.group(1).lower() != b"content-length":
            continue
        value = _length_value(m.group(2))
        if length is not None and value != length:
            return None, "two different Content-Length headers"
        length = value
    if length is None:
        return None, "the headers have no Content-Length"
    return length, None


def _length_value(digits: bytes) -> int:
    """The value of a Content-Length's digits; TOO_MANY_BYTES for more than 20 of them."""
    significant = digits.lstrip(b"0")
    return int(significant or b"0") if len(significant) <= 20 else TOO_MANY_BYTES


def _header_problem(m: re.Match[bytes] | None) -> str | None:
    """What is wrong with a header line (None: a Content-Length or Content-Type header)."""
    if m is None:
        return "not a header line (a header is `Name: value` ended by CR LF)"
    name, value = m.group(1).lower(), m.group(2)
    if name == b"content-length":
        if _LENGTH.fullmatch(value) is None:
            return f"Content-Length is not a number: {value[:40]!r}"
        return None
    if name != b"content-type":
        return f"unknown header {m.group(1)[:40]!r} (only Content-Length and Content-Type)"
    if b"content-length:" in value.lower():
        return "a Content-Length header inside another header"
    return None


# ---------------------------------------------------------------------- serving
class Dispatcher(Protocol):
    def structure_message(self, data: dict[str, Any]) -> Any: ...

    def handle_message(self, message: Any) -> None: ...

    def _send_data(self, data: Any) -> None: ...


def error_response(code: int, message: str) -> dict[str, Any]:
    return {"jsonrpc": "2.0", "id": None, "error": {"code": code, "message": message}}


def dispatch(protocol: Dispatcher, body: bytes,
             classify: Callable[[Exception], tuple[int, str] | None]) -> None:
    """Decode one message and hand it to the protocol. An error is answered with what
    `classify` says (None: already answered)."""
    try:
        message = json.loads(body, object_hook=protocol.structure_message)
        protocol.handle_message(message)
    except (SystemExit, KeyboardInterrupt):
        raise
    except Exception as e:
        log.debug("cannot handle a message", exc_info=True)
        got = classify(e)
        if got is not None:
            protocol._send_data(error_response(*got))


class _Reader:
    """Reads the input in a daemon thread (it must not keep the process alive), one chunk
    at a time: the next read waits until the loop took the previous chunk."""

    def __init__(self, read: Callable[[int], bytes], loop: asyncio.AbstractEventLoop) -> None:
        self.read = read
        self.loop = loop
        self.queue: asyncio.Queue[bytes] = asyncio.Queue(maxsize=1)
        threading.Thread(target=self._run, name="rssm-stdin", daemon=True).start()

    def _run(self) -> None:
        while True:
            try:
                chunk = self.read(CHUNK)
            except (OSError, ValueError):
                chunk = b""
            try:
                asyncio.run_coroutine_threadsafe(self.queue.put(chunk), self.loop).result()
            except RuntimeError:   # the loop is closed
                return
            if not chunk:
                return


async def serve(read: Callable[[int], bytes], protocol: Dispatcher,
                classify: Callable[[Exception], tuple[int, str] | None],
                stop: threading.Event) -> None:
    """Read messages until end of input (or `stop`) and dispatch them."""
    reader = _Reader(read, asyncio.get_running_loop())
    framer = Framer()
    while not stop.is_set():
        chunk = await reader.queue.get()
        if not chunk:
            return
        try:
            events = framer.feed(chunk)
        except Exception as e:   # a bug of the framer: not the end of the session
            log.error("cannot frame the input (%s: %s); skipping to the next header",
                      type(e).__name__, e)
            framer = Framer()
            framer.junk = True
            events = [FramingError(f"the input could not be framed ({type(e).__name__})")]
        for event in events:
            if isinstance(event, Message):
                dispatch(protocol, event.body, classify)
            else:
                log.warning("framing error: %s", event.reason)
                protocol._send_data(error_response(event.code, f"Parse error: {event.reason}"
                                                   if event.code == PARSE_ERROR else
                                                   f"Invalid request: {event.reason}"))
            await asyncio.sleep(0)   # let the answers and analyses run between messages
