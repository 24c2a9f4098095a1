"""The table of expectations (expectations.py) on the interpreter: deterministic mode,
simulated clock, a trace of every firing (replayed on the flat net to know the marking at each
step) and the subsystems' memory at the end (the consumers record what their transition
functions saw)."""

from __future__ import annotations

from functools import cache
from pathlib import Path

import pytest

from rssm_dsl.hpn.flat import Role
from tests.semantics import systems
from tests.semantics.behaviour_checks import (
    ENDING_AGENTS,
    BehaviourRun,
    check_ending_row,
    check_switch_row,
)
from tests.semantics.expectations import (
    ARRANGEMENT_ROWS,
    ENDING_ROWS,
    MODE_ROWS,
    PATTERN_ROWS,
    SWITCH_ROWS,
    ArrangementRow,
    EndingRow,
    Mode,
    ModeRow,
    PatternRow,
    Reads,
    SwitchRow,
)
from tests.semantics.interp_modes import ChannelRun, Receive, Sample, observe
from tests.semantics.interp_runner import InterpRun, simulate
from tests.semantics.netview import channel_of, channel_view, of_subsystem

# (producer Hz, consumer Hz, simulated seconds): together they make every situation arise
SETUPS: dict[str, tuple[float, float, float]] = {
    "slow-producer": (10.0, 100.0, 2.0),
    "fast-producer": (100.0, 10.0, 2.0),
    "producer-1.5x": (15.0, 10.0, 3.0),
    "consumer-1.5x": (10.0, 15.0, 3.0),
}
MIN_INSTANCES = 3
SEEDS = (0, 1)


@pytest.fixture(scope="module")
def work(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return tmp_path_factory.mktemp("semantics-interp")


@cache
def _mode_run(work: Path, producer: Mode, consumer: Mode, setup: str, seed: int
              ) -> tuple[InterpRun, ChannelRun]:
    name = producer.letter + consumer.letter
    p_hz, c_hz, until = SETUPS[setup]
    text = systems.system("modes", systems.mode_agent(name, producer, consumer, p_hz, c_hz))
    path = systems.write(work, f"modes_{name}_{setup}", text)
    run = simulate(path, until=until, seed=seed)
    assert run.reason == "until", run.message
    return run, observe(run, f"{name}.e.sink", "data", consumer)


def mode_runs(work: Path, producer: Mode, consumer: Mode) -> list[tuple[InterpRun, ChannelRun]]:
    return [_mode_run(work, producer, consumer, s, seed) for s in SETUPS for seed in SEEDS]


def _reads_problem(row: ModeRow, r: Receive) -> str | None:
    expected: int | None
    if row.reads is Reads.PREVIOUS:
        if r.took is not None:
            return f"took {r.took}, expected to take nothing"
        if r.after is not None and r.after != r.before:
            return f"the buffer changed from {r.before} to {r.after} without a receive"
        return None
    if r.took is None:
        return "took nothing"
    if row.reads is Reads.WAITING:
        expected = r.waiting[0] if len(r.waiting) == 1 else None
    elif row.reads is Reads.NEWEST:
        expected = r.waiting[-1] if len(r.waiting) >= 2 else None
    else:
        assert row.reads is Reads.NEXT
        expected = r.sent_after_look[0] if r.sent_after_look else None
    if r.took != expected:
        return f"took {r.took}, expected {row.reads.value} ({expected}); waiting {r.waiting}"
    if r.after is not None and r.after != r.took:
        return f"the next transition function saw {r.after}, not the value taken {r.took}"
    return None


def _receive_problems(row: ModeRow, r: Receive) -> list[str]:
    out = []
    if r.waited != row.consumer_waits:
        out.append(f"consumer waited: {r.waited}")
    reads = _reads_problem(row, r)
    if reads:
        out.append(reads)
    if r.new_after is not None and r.new_after != row.new:
        out.append(f"new(data) of the next iteration: {r.new_after}")
    if (r.lost > 0) != row.lost:
        out.append(f"samples lost before this receive: {r.lost}")
    return out


@pytest.mark.parametrize("row", MODE_ROWS, ids=lambda r: r.id)
def test_mode_row(work: Path, row: ModeRow) -> None:
    runs = mode_runs(work, row.producer, row.consumer)
    instances = [r for _, ch in runs for r in ch.receives if r.situation is row.situation]
    samples: list[Sample] = [s for _, ch in runs for s in ch.samples]
    if not row.arises:
        assert not instances, f"{row.situation.value} arose: {instances[:3]}"
        assert not any(s.overwrote for s in samples), "a sample was overwritten"
        return
    assert len(instances) >= MIN_INSTANCES, f"{row.situation.value} arose {len(instances)} times"
    problems = [(r, p) for r in instances for p in _receive_problems(row, r)]
    assert not problems, problems[:5]
    # the producer's side: did its send complete only once the consumer took the sample, did
    # the sample taken replace one never read?
    taken = [({s.value: s for s in ch.samples})[r.took] for _, ch in runs for r in ch.receives
             if r.situation is row.situation and r.took is not None]
    judged = [s for s in (taken or samples) if s.done_after_take is not None]
    assert judged
    assert {s.done_after_take for s in judged} == {row.producer_waits}, row.producer_waits
    assert {s.overwrote for s in taken} <= {row.lost}


# ---------------------------------------------------------------------------- the pattern


@pytest.mark.parametrize("row", PATTERN_ROWS, ids=lambda r: r.id)
def test_pattern_row(work: Path, row: PatternRow) -> None:
    if row.id == "compute-then-send":
        for p, c in ((Mode.BLOCKING, Mode.BLOCKING), (Mode.NONBLOCKING, Mode.NONBLOCKING)):
            for _, ch in mode_runs(work, p, c):
                values = [s.value for s in ch.samples]
                assert values == list(range(1, len(values) + 1)), values[:5]
    elif row.id == "receive-then-use":
        judged: list[Receive] = []
        for p, c in ((Mode.BLOCKING, Mode.NONBLOCKING), (Mode.NONBLOCKING, Mode.NONBLOCKING)):
            for _, ch in mode_runs(work, p, c):
                judged += [r for r in ch.receives if r.new_after is not None]
        assert sum(r.took is None for r in judged) >= MIN_INSTANCES
        assert sum(r.took is not None for r in judged) >= MIN_INSTANCES
        for r in judged:
            assert r.new_after == (r.took is not None), r
            assert r.after == (r.took if r.took is not None else r.before), r
    else:
        assert row.id == "receive-then-conditions"
        path = systems.write(work, "conditions", systems.system("c", systems.conditions_agent()))
        run = simulate(path, until=1.0)
        got = [e["value"] for e in run.of("receive")]
        switch = next(e for e in run.of("switch") if e["subsystem"] == "cond.e.w")
        before = [e["value"] for e in run.of("receive") if e["step"] < switch["step"]]
        assert got[:3] == [1, 2, 3]
        assert before == [1, 2, 3], "watch ended in the iteration that received 3"
        assert run.iterations("cond.e.w")["watch"] == 3
        assert run.memory["cond.e.w"]["first"] == 3 and run.memory["cond.e.w"]["first_new"]


# ---------------------------------------------------------------------------- arrangements


def _arrangement_run(work: Path, row: ArrangementRow) -> tuple[InterpRun, str, str]:
    agents = systems.RECEIVE_AGENTS if row.side == "receive" else systems.SEND_AGENTS
    name = next(a for a, arr in agents.items() if arr == row.arrangement)
    make = systems.receive_agent if row.side == "receive" else systems.send_agent
    path = systems.write(work, f"arr_{name}", systems.system("arr", make(name, row.arrangement)))
    run = simulate(path, until=2.0)
    assert run.reason == "until", run.message
    if row.side == "receive":
        return run, channel_of(run.net, f"{name}.c", "a"), channel_of(run.net, f"{name}.c", "b")
    return (run, channel_of(run.net, f"{name}.e.ea", "a"),
            channel_of(run.net, f"{name}.e.eb", "b"))


@pytest.mark.parametrize("row", ARRANGEMENT_ROWS, ids=lambda r: r.id)
def test_arrangement_row(work: Path, row: ArrangementRow) -> None:
    """Per iteration of the subsystem with the arrangement: when did a's operation start and
    complete (it waits: its peer is slow), when did b's complete."""
    run, chan_a, chan_b = _arrangement_run(work, row)
    net = run.net
    a, b = channel_view(net, chan_a), channel_view(net, chan_b)
    owner = a.consumer if row.side == "receive" else a.producer
    if row.side == "receive":
        start_a, done = a.into_arrival(net), {"a": a.rcv_done, "b": b.rcv_done}
    else:
        start_a, done = a.into_send(net), {"a": a.send_done, "b": b.send_done}
    iteration = {t.index for t in of_subsystem(net, owner, Role.ITERATION)}
    index = {t.name: t.index for t in net.transitions}
    rows: list[dict[str, float]] = []
    current: dict[str, float] = {}
    for e, _, _ in run.firings():
        t = index[e["transition"]]
        if t in start_a:
            current["a_start"], current["a_start_time"] = e["step"], e["time"]
        for buf in ("a", "b"):
            if t in done[buf]:
                current[buf], current[buf + "_time"] = e["step"], e["time"]
        if t in iteration:
            rows.append(current)
            current = {}
    complete = [r for r in rows if {"a", "b", "a_start"} <= r.keys()]
    assert len(complete) >= MIN_INSTANCES, rows
    if row.order is not None:
        orders = {tuple(sorted(("a", "b"), key=lambda k: r[k])) for r in complete}
        assert orders == {row.order}, orders
    waited = [r for r in complete if r["a_time"] > r["a_start_time"]]
    assert len(waited) >= MIN_INSTANCES, "a's operation never waited"
    inside = {r["a_start"] < r["b"] < r["a"] for r in waited}
    assert inside == {row.b_while_a_waits}, inside


# ---------------------------------------------------------------------------- switching


def behaviour_run(run: InterpRun, subsystem: str) -> BehaviourRun:
    view = next(s for s in run.summary["subsystems"] if s["id"] == subsystem)
    return BehaviourRun(
        iterations={b: n for b, n in view["iterations"].items() if n},
        switches=[(e["from"], e["to"], e["conditions"]) for e in run.of("switch")
                  if e["subsystem"] == subsystem],
        errors=[(e["code"], e["handled"]) for e in run.of("error")
                if e["subsystem"] == subsystem],
        ended=view["state"] == "ended",
        stopped=run.codes[0] if run.reason == "error" and run.codes else None,
        i=view["i"], memory=run.memory[subsystem])


@pytest.fixture(scope="module")
def switching(work: Path) -> InterpRun:
    path = systems.write(work, "switching", systems.system("sw", systems.switching_agent()))
    return simulate(path, until=5.0)


@pytest.mark.parametrize("row", SWITCH_ROWS, ids=lambda r: r.id)
def test_switch_row(switching: InterpRun, row: SwitchRow) -> None:
    assert switching.reason == "until", switching.message     # e.mon runs on
    check_switch_row(row, behaviour_run(switching, "sw.c"))


# ---------------------------------------------------------------------------- ending


@pytest.mark.parametrize("row", ENDING_ROWS, ids=lambda r: r.id)
def test_ending_row(work: Path, row: EndingRow) -> None:
    agent = ENDING_AGENTS[row.id]
    text = {"errh": systems.error_agent("errh", True), "erru": systems.error_agent("erru", False),
            "errv": systems.error_value_agent(), "errt": systems.failing_condition_agent()}[agent]
    run = simulate(systems.write(work, agent, systems.system("e", text)), until=2.0)
    if row.id == "unhandled-failure-stops":
        assert run.reason == "error" and run.codes == ["E802"], (run.reason, run.codes)
    else:
        assert run.reason == "until", run.message    # c ended, e.mon runs on
    check_ending_row(row, behaviour_run(run, f"{agent}.c"))
    if row.id == "failing-condition-is-an-error":   # where: the place that tests divide's
        assert [e["place"] for e in run.of("error")] == ["p[errt,c,divide,2]"]
