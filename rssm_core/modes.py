"""The communication modes of RSSM, defined once: the mode of each side, the four
producer/consumer pairings and what each means, and the net of each side's mode page.

Producer blocking: waits until the consumer has taken the data. Producer non-blocking: goes
on at once, overwriting data that was never read. Consumer blocking: waits for fresh data.
Consumer non-blocking: takes fresh data if there is any, otherwise goes on with what it had
(its input buffer keeps its value, ``new(x)`` stays false).

A channel is two fused places, ``full`` (data not yet taken) and ``empty``, initially
``empty``; the channel's one token lies in one of them or in the ``op`` place of the send or
receive moving the data. :func:`send_net` and :func:`receive_net` give the transitions of a
side's mode page over the places ``in``, ``op`` (the send or receive operation), ``wait``,
``out``, ``full`` and ``empty``; the compiler builds every mode page from them (so the
verifier's state space and the interpreter's token game both follow this table), and the
generated ROS 2 nodes read :func:`pairing` / :func:`rule` to decide who waits and whether a
sample is acknowledged.
"""

from __future__ import annotations

from enum import Enum
from typing import assert_never

from rssm_core.records import dataclass


class Mode(str, Enum):
    """The mode of one side of a channel."""

    BLOCKING = "blocking"
    NONBLOCKING = "nonblocking"


class Pairing(Enum):
    """The four producer/consumer mode combinations of a channel."""

    BLOCKING_BLOCKING = (Mode.BLOCKING, Mode.BLOCKING)
    BLOCKING_NONBLOCKING = (Mode.BLOCKING, Mode.NONBLOCKING)
    NONBLOCKING_BLOCKING = (Mode.NONBLOCKING, Mode.BLOCKING)
    NONBLOCKING_NONBLOCKING = (Mode.NONBLOCKING, Mode.NONBLOCKING)

    @property
    def producer(self) -> Mode:
        return self.value[0]

    @property
    def consumer(self) -> Mode:
        return self.value[1]

    @property
    def text(self) -> str:
        """``producer/consumer``, e.g. ``blocking/nonblocking``."""
        return f"{self.producer.value}/{self.consumer.value}"


def pairing(producer: Mode, consumer: Mode) -> Pairing:
    return Pairing((producer, consumer))


@dataclass(frozen=True)
class Rule:
    """What a pairing means for the two sides of a channel."""

    producer_waits_until_taken: bool   # the send ends only once the consumer took the data
    producer_overwrites: bool          # a send while unread data is there replaces it
    consumer_waits_for_data: bool      # the receive waits until fresh data is there
    consumer_skips_when_empty: bool    # with nothing fresh the receive ends, buffer unchanged
    acknowledged: bool                 # the consumer tells the producer it took the data


def rule(p: Pairing) -> Rule:
    """The meaning of a pairing (one row per combination, matched exhaustively)."""
    match p:
        case Pairing.BLOCKING_BLOCKING:
            return Rule(True, False, True, False, True)
        case Pairing.BLOCKING_NONBLOCKING:
            return Rule(True, False, False, True, True)
        case Pairing.NONBLOCKING_BLOCKING:
            return Rule(False, True, True, False, False)
        case Pairing.NONBLOCKING_NONBLOCKING:
            return Rule(False, True, False, True, False)
        case _:
            assert_never(p)


# ---------------------------------------------------------------- the nets of the mode pages


class Slot(str, Enum):
    """A place of a mode page (``full`` and ``empty`` are the channel's fused places)."""

    IN = "in"
    OP = "op"
    WAIT = "wait"
    OUT = "out"
    FULL = "full"
    EMPTY = "empty"


class Step(str, Enum):
    """What a transition of a mode page does."""

    START_SEND = "start_send"          # the channel is empty: the send operation runs
    OVERWRITE = "overwrite"            # unread data is there: the send replaces it
    SENT = "sent"                      # the data is in the channel; the page ends
    SENT_WAIT = "sent_wait"            # the data is in the channel; the producer waits
    SEEN_TAKEN = "seen_taken"          # the consumer took it: the waiting producer ends
    TAKE = "take"                      # fresh data is there: the receive operation runs
    RECEIVED = "received"              # the data is in the input buffer; the page ends
    NOTHING_NEW = "nothing_new"        # nothing fresh: the page ends, buffer unchanged


@dataclass(frozen=True)
class Transition:
    number: int                        # n of t[...,n] in the paper's notation
    step: Step
    inputs: tuple[Slot, ...]
    outputs: tuple[Slot, ...]


def send_net(mode: Mode) -> tuple[Transition, ...]:
    """The producer's mode page: in -> op (the send operation) -> out."""
    start = Transition(1, Step.START_SEND, (Slot.IN, Slot.EMPTY), (Slot.OP,))
    match mode:
        case Mode.NONBLOCKING:
            return (start,
                    Transition(2, Step.OVERWRITE, (Slot.IN, Slot.FULL), (Slot.OP,)),
                    Transition(3, Step.SENT, (Slot.OP,), (Slot.OUT, Slot.FULL)))
        case Mode.BLOCKING:
            return (start,
                    Transition(3, Step.SENT_WAIT, (Slot.OP,), (Slot.WAIT, Slot.FULL)),
                    Transition(4, Step.SEEN_TAKEN, (Slot.WAIT, Slot.EMPTY),
                               (Slot.OUT, Slot.EMPTY)))
        case _:
            assert_never(mode)


def receive_net(mode: Mode) -> tuple[Transition, ...]:
    """The consumer's mode page: in -> op (the receive operation) -> out, or straight on."""
    take = (Transition(1, Step.TAKE, (Slot.IN, Slot.FULL), (Slot.OP,)),
            Transition(2, Step.RECEIVED, (Slot.OP,), (Slot.OUT, Slot.EMPTY)))
    match mode:
        case Mode.BLOCKING:
            return take
        case Mode.NONBLOCKING:
            return (*take, Transition(3, Step.NOTHING_NEW, (Slot.IN, Slot.EMPTY),
                                      (Slot.OUT, Slot.EMPTY)))
        case _:
            assert_never(mode)


def slots(net: tuple[Transition, ...]) -> tuple[Slot, ...]:
    """The places a mode page needs, in the order of :class:`Slot`."""
    used = {s for t in net for s in (*t.inputs, *t.outputs)}
    return tuple(s for s in Slot if s in used)
