"""The data side of a channel. The token side is the flat net's two fused places, `full`
(p^fusion[...,1]: data not yet taken) and `empty` (p^fusion[...,2]); the net's mode pages
decide when a send or a receive may happen. This is the data slot they move:

* send copies the producer's output buffer into the slot (values are immutable, so the copy is
  the value itself); a send while the slot holds data nobody took (a non-blocking producer
  overwriting) is counted as an overwrite;
* receive copies the slot into the consumer's input buffer and sets new(x) for it;
* a non-blocking receive that finds the channel empty does not run the receive operation: the
  input buffer keeps its old value and new(x) stays false.
"""

from __future__ import annotations

from typing import Any

from rssm_dsl.semantics.model import Channel


class ChannelState:
    __slots__ = ("channel", "id", "overwritten", "received", "sent", "unread", "value")

    def __init__(self, channel: Channel, initial: Any) -> None:
        self.channel = channel
        self.id = channel.id
        self.value: Any = initial
        self.unread = False
        self.sent = 0
        self.received = 0
        self.overwritten = 0

    def put(self, value: Any) -> bool:
        """Store a sent value; True when it overwrote a value nobody took."""
        overwrote = self.unread
        if overwrote:
            self.overwritten += 1
        self.value = value
        self.unread = True
        self.sent += 1
        return overwrote

    def take(self) -> Any:
        self.unread = False
        self.received += 1
        return self.value
