"""The `Rule` table of rssm_core/modes.py (what the generated ROS 2 nodes read) against the
mode nets of the same module (what the HPN builder, hence the interpreter and the verifier,
read): each field of a pairing's rule is derived here from the token game of the producer's
send net and the consumer's receive net over the channel's `full`/`empty` places, so a
change to either side that the other does not follow fails."""

from __future__ import annotations

from collections.abc import Iterable

import pytest

from rssm_core.modes import Mode, Pairing, Slot, Step, Transition, receive_net, rule, send_net

Marking = frozenset[Slot]


def _fire(net: Iterable[Transition], m: Marking) -> list[tuple[Transition, Marking]]:
    return [(t, (m - set(t.inputs)) | set(t.outputs)) for t in net if set(t.inputs) <= m]


def _reachable(net: tuple[Transition, ...], start: set[Slot]) -> list[Marking]:
    """Every marking one side reaches alone (the other side does nothing meanwhile)."""
    seen = {frozenset(start)}
    todo = [frozenset(start)]
    while todo:
        m = todo.pop()
        for _, n in _fire(net, m):
            if n not in seen:
                seen.add(n)
                todo.append(n)
    return sorted(seen, key=sorted)


def _producer_ends_alone(mode: Mode, channel: Slot) -> bool:
    """From `in`, with the channel in state `channel`, the send page reaches `out` without
    the consumer taking anything."""
    return any(Slot.OUT in m for m in _reachable(send_net(mode), {Slot.IN, channel}))


def _consumer_ends_alone(mode: Mode, channel: Slot) -> bool:
    return any(Slot.OUT in m for m in _reachable(receive_net(mode), {Slot.IN, channel}))


def _derived(p: Pairing) -> tuple[bool, bool, bool, bool, bool]:
    send, receive = send_net(p.producer), receive_net(p.consumer)
    # the producer's send ends only once the consumer took the data: from an empty channel
    # it cannot reach `out` alone, and once the consumer has taken it (full -> empty, the
    # receive page's take and received) it can
    waits = not _producer_ends_alone(p.producer, Slot.EMPTY)
    if waits:
        stuck = [m for m in _reachable(send, {Slot.IN, Slot.EMPTY}) if Slot.FULL in m]
        assert stuck, "a waiting producer leaves data in the channel"
        taken = {*(stuck[-1] - {Slot.FULL}), Slot.EMPTY}
        assert any(Slot.OUT in m for m in _reachable(send, taken)), "and sees it taken"
    # a send while unread data is there replaces it: the page can start on `full`
    overwrites = any(set(t.inputs) == {Slot.IN, Slot.FULL} for t in send)
    # the receive waits for fresh data: on an empty channel it cannot end alone
    consumer_waits = not _consumer_ends_alone(p.consumer, Slot.EMPTY)
    # with nothing fresh the receive ends at once and takes nothing (no operation runs)
    skips = any(set(t.inputs) == {Slot.IN, Slot.EMPTY} and Slot.OUT in t.outputs
                and Slot.OP not in t.outputs for t in receive)
    # the consumer tells the producer it took the data: the producer's page has a step that
    # needs the channel emptied by the consumer after its own send
    acknowledged = any(t.step is Step.SEEN_TAKEN and Slot.EMPTY in t.inputs for t in send)
    return waits, overwrites, consumer_waits, skips, acknowledged


@pytest.mark.parametrize("p", list(Pairing), ids=lambda p: p.text)
def test_the_rule_is_what_the_mode_nets_do(p: Pairing) -> None:
    r = rule(p)
    assert (r.producer_waits_until_taken, r.producer_overwrites, r.consumer_waits_for_data,
            r.consumer_skips_when_empty, r.acknowledged) == _derived(p)


@pytest.mark.parametrize("p", list(Pairing), ids=lambda p: p.text)
def test_a_full_channel_holds_a_producer_exactly_when_it_does_not_overwrite(p: Pairing) -> None:
    """On unread data, a producer either overwrites it or waits for the consumer: never both,
    never neither (a send page that could not go on from `full` at all would deadlock)."""
    r = rule(p)
    alone = _producer_ends_alone(p.producer, Slot.FULL)
    assert alone == r.producer_overwrites
    assert r.producer_overwrites != r.producer_waits_until_taken
    # a consumer either waits for data or skips: exactly one
    assert r.consumer_waits_for_data != r.consumer_skips_when_empty
    # fresh data is always taken, whatever the consumer's mode
    assert _consumer_ends_alone(p.consumer, Slot.FULL)
    taken = [m for m in _reachable(receive_net(p.consumer), {Slot.IN, Slot.FULL})
             if Slot.OUT in m]
    assert taken == [frozenset({Slot.OUT, Slot.EMPTY})]
