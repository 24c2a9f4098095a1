"""What the tests need to know about the flat net of a compiled specification, found from its
structure (roles, channels, fused places), not from names: the places and transitions of one
channel's send and receive pages, the data cases of a subsystem, its behaviour pattern.

Used by the interpreter runner (it replays the trace's firings on the net to know the
marking at every step) and by the verifier runner (it asks reachability questions about
the same places and transitions)."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

from rssm_dsl.hpn.flat import FlatNet, FlatTransition, Role
from rssm_dsl.hpn.flatten import flatten
from rssm_dsl.pipeline import Compilation, compile_file


def compile_spec(path: Path) -> Compilation:
    comp = compile_file(path)
    assert comp.ok, [d.message for d in comp.diagnostics]
    return comp


def flat_net(comp: Compilation) -> FlatNet:
    assert comp.hpn is not None
    return flatten(comp.hpn)


@dataclass(frozen=True)
class ChannelView:
    """One channel of the flat net: its fused places and the transitions of the producer's
    send page and of the consumer's receive page for it (in every behaviour)."""

    id: str
    producer: str
    consumer: str
    full: int
    empty: int
    send_arrive: frozenset[int]    # places where the producer's send starts
    send_start: frozenset[int]     # in (+ empty | + full) -> op(send)
    send_done: frozenset[int]      # the transition that leaves the send page
    send_ops: frozenset[int]       # op places of the send
    rcv_arrive: frozenset[int]     # places where the consumer's receive starts
    take: frozenset[int]           # in + full -> op(receive)
    pass_empty: frozenset[int]     # the receive page completes without a receive operation
    #                                (from `empty`: nothing new)
    rcv_done: frozenset[int]       # transitions that leave the receive page
    rcv_ops: frozenset[int]        # op places of the receive

    def into_arrival(self, net: FlatNet) -> frozenset[int]:
        """Transitions that put the consumer's token into the place where its receive starts."""
        return _into(net, self.rcv_arrive)

    def into_send(self, net: FlatNet) -> frozenset[int]:
        """Transitions that put the producer's token into the place where its send starts."""
        return _into(net, self.send_arrive)


def _into(net: FlatNet, places: frozenset[int]) -> frozenset[int]:
    return frozenset(t.index for t in net.transitions if set(t.post) & places
                     and not set(t.pre) & places)


def channel_view(net: FlatNet, channel: str) -> ChannelView:
    fused = [p for p in net.places if p.channel == channel and p.operation is None
             and p.subsystem is None]
    assert len(fused) == 2, [p.name for p in fused]
    (empty,) = [p.index for p in fused if p.index in net.initial]
    (full,) = [p.index for p in fused if p.index != empty]
    chan = {full, empty}
    trs = [t for t in net.transitions if t.channel == channel]
    sends = [t for t in trs if t.role is Role.SEND]
    rcvs = [t for t in trs if t.role is Role.RECEIVE]
    assert sends and rcvs, channel
    producer = sends[0].subsystem
    consumer = rcvs[0].subsystem
    assert producer is not None and consumer is not None
    ops = {p.index for p in net.places if p.operation is not None}
    send_start = {t.index for t in sends if set(t.pre) & chan and set(t.post) & ops}
    send_ops = {q for t in sends for q in t.post if q in ops}
    send_arrive = {q for t in sends if t.index in send_start for q in t.pre if q not in chan}
    send_inner = {q for t in sends for q in t.pre if q not in chan}
    send_done = {t.index for t in sends
                 if any(q not in chan and q not in send_inner for q in t.post)}
    take = {t.index for t in rcvs if full in t.pre and set(t.post) & ops}
    rcv_ops = {q for t in rcvs for q in t.post if q in ops}
    rcv_arrive = {q for t in rcvs if t.index in take for q in t.pre if q != full}
    # whatever else leaves the arrival place completes the receive without its operation
    pass_empty = {t.index for t in rcvs if set(t.pre) & rcv_arrive and t.index not in take}
    rcv_inner = {q for t in rcvs for q in t.pre if q not in chan}
    rcv_done = {t.index for t in rcvs if any(q not in chan and q not in rcv_inner
                                             for q in t.post)}
    return ChannelView(channel, producer, consumer, full, empty, frozenset(send_arrive),
                       frozenset(send_start),
                       frozenset(send_done), frozenset(send_ops), frozenset(rcv_arrive),
                       frozenset(take), frozenset(pass_empty), frozenset(rcv_done),
                       frozenset(rcv_ops))


def channel_of(net: FlatNet, consumer: str, buffer: str) -> str:
    """The id of the channel into ``consumer``'s input ``buffer``."""
    ids = {p.channel for p in net.places if p.channel is not None}
    (found,) = [c for c in ids if c.endswith(f"->{consumer}.{buffer}")]
    return found


def of_subsystem(net: FlatNet, subsystem: str, role: Role) -> list[FlatTransition]:
    return [t for t in net.transitions if t.subsystem == subsystem and t.role is role]


def case_new(comp: Compilation, t: FlatTransition) -> tuple[bool, ...]:
    """new(x) per input buffer of a data-case transition (from the HPN's condition)."""
    assert comp.hpn is not None and t.condition is not None
    cond = comp.hpn.transitions[t.condition].condition
    assert cond is not None and cond.new is not None
    return tuple(cond.new)


def function_join(net: FlatNet, subsystem: str) -> frozenset[int]:
    """The joins of the subsystem's transition functions P^f (the commit, new(x) cleared):
    the transitions out of the places that the data cases' pages end in."""
    cases = of_subsystem(net, subsystem, Role.CASE)
    case_in = {q for t in cases for q in t.pre}
    # a case page: in -> case -> op -> done -> out; the join takes every partial function's out
    dones = {t.index for t in net.transitions if t.subsystem == subsystem
             and any(q in {p for c in cases for p in c.post} for q in t.pre)}
    outs = {q for d in dones for q in net.transitions[d].post}
    joins = {t.index for t in net.transitions if t.subsystem == subsystem and set(t.pre) & outs
             and not set(t.pre) & case_in}
    return frozenset(joins)
