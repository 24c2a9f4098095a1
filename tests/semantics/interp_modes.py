"""The receives of one channel in an interpreter run, each classified by its situation and
described by what happened: whether the consumer waited, what it read, what its next
transition function saw (the consumer's memory record), whether samples were lost, whether
the producer's send waited for the take."""

from __future__ import annotations

from dataclasses import dataclass

from rssm_dsl.hpn.flat import Role
from tests.semantics.expectations import Mode, Situation
from tests.semantics.interp_runner import InterpRun
from tests.semantics.netview import channel_of, channel_view, of_subsystem


@dataclass(frozen=True)
class Receive:
    iteration: int             # the consumer's iteration (0, 1, ...) whose receive this is
    situation: Situation
    waited: bool               # nothing fresh when it looked, and it completed by a take
    took: int | None           # the value taken, None when it took nothing
    waiting: tuple[int, ...]   # values sent since the previous take, oldest first
    sent_after_look: tuple[int, ...]   # values sent between the look and the completion
    before: int | None         # the buffer as this iteration's transition function saw it
    after: int | None          # ... and as the next one saw it (None: the run ended first)
    new_after: bool | None     # new(x) as the next transition function saw it
    lost: int                  # samples overwritten since the previous take


@dataclass(frozen=True)
class Sample:
    value: int
    overwrote: bool            # it replaced a sample nobody took
    done_after_take: bool | None   # the producer's send completed only after the consumer
    #                                took this sample (None: never taken, or the run ended)


@dataclass(frozen=True)
class ChannelRun:
    receives: list[Receive]
    samples: list[Sample]


def observe(run: InterpRun, consumer: str, buffer: str, consumer_mode: Mode) -> ChannelRun:
    net = run.net
    ch = channel_view(net, channel_of(net, consumer, buffer))
    arrive_t = ch.into_arrival(net)
    iteration_t = {t.index for t in of_subsystem(net, consumer, Role.ITERATION)}
    index = {t.name: t.index for t in net.transitions}
    blocking = consumer_mode is Mode.BLOCKING

    sent: list[int] = []              # values in the order sent
    since_take: list[int] = []        # values sent since the last take
    overwrote: dict[int, bool] = {}
    take_step: dict[int, int] = {}    # value -> step of its take
    done_step: dict[int, int] = {}    # value -> step at which its send page completed
    pending_send: int | None = None
    iteration = 0
    look: tuple[int, bool, tuple[int, ...], int] | None = None   # (iteration, full, waiting, sent)
    raw: list[tuple[int, bool, tuple[int, ...], bool, int | None, tuple[int, ...]]] = []
    took_value: int | None = None

    # the marking before and after every firing (the trace replayed on the net)
    fired = {e["step"]: (before, after) for e, before, after in run.firings()}
    for e in run.events:
        kind = e["event"]
        if kind == "send" and e["channel"] == ch.id:
            v = int(e["value"])
            sent.append(v)
            since_take.append(v)
            overwrote[v] = bool(e["overwrote"])
            pending_send = v
        elif kind == "receive" and e["channel"] == ch.id:
            took_value = int(e["value"])
            take_step[took_value] = e["step"]
        elif kind == "fire":
            t = index[e["transition"]]
            before, after = fired[e["step"]]
            if t in iteration_t:
                iteration += 1
            if t in ch.send_done and pending_send is not None:
                done_step[pending_send] = e["step"]
                pending_send = None
            if blocking and t in arrive_t and ch.full not in after:
                # nothing there: a blocking receive waits, the situation is what it found
                look = (iteration, False, tuple(since_take), len(sent))
            if (t in ch.take or t in ch.pass_empty) and look is None:
                # the receive decides at once: the situation is what it finds now
                look = (iteration, ch.full in before, tuple(since_take), len(sent))
            if t in ch.rcv_done and look is not None:
                it, full, waiting, n_sent = look
                took = took_value if t not in ch.pass_empty else None
                raw.append((it, full, waiting, not full and took is not None, took,
                            tuple(sent[n_sent:])))
                if took is not None:
                    since_take = []
                look, took_value = None, None

    k = int(run.memory[consumer]["k"])
    seen = run.memory[consumer]["seen"]
    fresh = run.memory[consumer]["fresh"]
    assert k <= len(seen), "the consumer's record is a ring: make the run shorter"
    receives = []
    for it, full, waiting, waited, took, after_look in raw:
        if not full:
            situation = Situation.NO_DATA
        elif len(waiting) == 1:
            situation = Situation.WAITING
        else:
            situation = Situation.OVERWRITTEN
        has_next = it + 1 < k
        receives.append(Receive(
            it, situation, waited, took, waiting, after_look,
            int(seen[it]) if it < k else None,
            int(seen[it + 1]) if has_next else None,
            bool(fresh[it + 1]) if has_next else None,
            max(0, len(waiting) - 1) if took is not None else 0))
    samples = [Sample(v, overwrote[v],
                      (done_step[v] > take_step[v]) if v in take_step and v in done_step
                      else None) for v in sent]
    return ChannelRun(receives, samples)
