"""The base-protocol framer (rssm_dsl/lsp/framing.py) on its own: every framing error is
reported once and the next well-framed message is found again, however the bytes arrive."""

from __future__ import annotations

import json

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from rssm_dsl.lsp.framing import (
    INVALID_REQUEST,
    MAX_MESSAGE_BYTES,
    PARSE_ERROR,
    Event,
    Framer,
    FramingError,
    Message,
)

GOOD = json.dumps({"jsonrpc": "2.0", "id": 7, "method": "shutdown"}).encode()


def frame(body: bytes, length: int | None = None) -> bytes:
    n = len(body) if length is None else length
    return f"Content-Length: {n}\r\n\r\n".encode() + body


def feed(data: bytes, step: int = 0, framer: Framer | None = None) -> list[Event]:
    """Feed the data at once, or `step` bytes at a time."""
    framer = framer or Framer()
    if not step:
        return framer.feed(data)
    out: list[Event] = []
    for i in range(0, len(data), step):
        out += framer.feed(data[i:i + step])
    return out


BROKEN = {
    "length too short": frame(GOOD, 5),
    "length too long": frame(b"{}", 500),
    "length cut inside the next header": frame(b"{}", 10),
    "length not a number": b"Content-Length: abc\r\n\r\n{}",
    "headers ended by a bare LF": b"Content-Length: 2\n\n{}",
    "no Content-Length": b"Content-Type: application/json\r\n\r\n{}",
    "two different lengths": b"Content-Length: 2\r\nContent-Length: 3\r\n\r\n{}",
    "random bytes": b"\x00\xff garbage \r\n\r\n more",
    "a header without a colon": b"Content-Length 2\r\n\r\n{}",
}


@pytest.mark.parametrize("step", [0, 1, 7])
@pytest.mark.parametrize("kind", sorted(BROKEN))
def test_a_broken_frame_is_reported_and_the_next_message_found(kind: str, step: int) -> None:
    events = feed(BROKEN[kind] + frame(GOOD) + frame(GOOD), step)
    messages = [e.body for e in events if isinstance(e, Message)]
    errors = [e for e in events if isinstance(e, FramingError)]
    assert messages[-2:] == [GOOD, GOOD]
    # the broken frame: a framing error, or a body that is not JSON (answered as such)
    assert errors or any(m != GOOD for m in messages)
    assert all(e.code == PARSE_ERROR for e in errors)


def test_well_framed_messages_pass_whatever_the_chunks() -> None:
    stream = frame(GOOD) + b"Content-Type: application/vscode-jsonrpc; charset=utf-8\r\n" \
        + frame(b"[1, 2]") + frame("{\"text\": \"é\\r\\nContent-Length: 5\"}".encode())
    for step in (0, 1, 3, 64):
        assert [e for e in feed(stream, step)] == [
            Message(GOOD), Message(b"[1, 2]"),
            Message("{\"text\": \"é\\r\\nContent-Length: 5\"}".encode())]


def test_blank_lines_between_messages_are_tolerated() -> None:
    assert feed(b"\r\n\n" + frame(GOOD) + b"\r\n" + frame(GOOD)) == [Message(GOOD)] * 2


def test_a_length_over_the_limit_is_refused_and_skipped() -> None:
    huge = b"Content-Length: 99999999999999\r\n\r\n{}"
    events = feed(huge + frame(GOOD))
    assert events[0] == FramingError(events[0].reason, INVALID_REQUEST)  # type: ignore[union-attr]
    assert events[1:] == [Message(GOOD)]


def test_an_honest_body_over_the_limit_is_skipped_without_being_kept() -> None:
    framer = Framer(max_bytes=1000)
    body = b"[" + b"0," * 5000 + b"0]"
    events = feed(frame(body) + frame(GOOD), 512, framer)
    assert [type(e) for e in events] == [FramingError, Message]
    assert events[1] == Message(GOOD)
    assert len(framer.buf) == 0


def test_a_length_with_many_digits_is_over_the_limit() -> None:
    events = feed(b"Content-Length: " + b"9" * 5000 + b"\r\n\r\n{}" + frame(GOOD))
    assert isinstance(events[0], FramingError) and events[-1] == Message(GOOD)


def test_junk_without_any_header_keeps_memory_bounded() -> None:
    framer = Framer()
    events: list[Event] = []
    for _ in range(100):
        events += framer.feed(b"x" * 10_000 + b"\r\n")
    assert len(framer.buf) < 20_000
    assert len(events) == 1 and isinstance(events[0], FramingError)
    assert framer.feed(frame(GOOD)) == [Message(GOOD)]


def test_the_limit_is_64_mib() -> None:
    assert MAX_MESSAGE_BYTES == 64 * 1024 * 1024


# junk that ends like (a piece of) a header: glued to the next message's header
TAILS = [
    b"Content-Length: 5\r\nX", b"Content-Type: b", b"Content-Length: 5\r\nContent-Type: b",
    b"Content-Length: 15", b"Content-Length: 15\r", b"Content-Length: 5\r\n",
    b"Content-Length: 5\r\n\r\n", b"Content-Length: 5\r\n\r\nab", b"Content-Length: 5\r\n\r\nabcdef",
    b"Content-Length: 1000\r\n\r\nabc\r\nContent-Length: 7\r\n", b"Fo", b"\r", b"X: y\r\n",
    b"Content-Length: 150\r\nContent-Le", b"Content-Length: 99999999999999\r\n\r\n",
]


@pytest.mark.parametrize("step", [0, 1])
@pytest.mark.parametrize("tail", TAILS)
def test_junk_glued_to_the_next_header_does_not_swallow_it(tail: bytes, step: int) -> None:
    events = feed(tail + frame(GOOD), step)
    assert events[-1] == Message(GOOD)
    assert any(isinstance(e, FramingError) or e != Message(GOOD) for e in events[:-1])


PIECES = st.sampled_from([b"Content-Length: ", b"content-length:", b"Content-Type: ", b"5",
                          b"63", b"150", b"\r\n", b"\r", b"\n", b"{", b"}", b"x", b":", b" ",
                          b"C", b"Co", b"Conte", b"\xff"])


@settings(max_examples=300)
@given(junk=st.lists(PIECES, max_size=24).map(b"".join) | st.binary(max_size=300),
       step=st.sampled_from([0, 1, 5]))
def test_after_any_junk_the_next_message_is_delivered(junk: bytes, step: int) -> None:
    events = feed(junk + frame(GOOD), step)
    assert events and events[-1] == Message(GOOD)
