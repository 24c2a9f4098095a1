"""What docs/semantics.md says about the examples of examples/semantics/, checked on the
interpreter as `rssmc simulate` runs them (deterministic mode, seed 0): the order of one
iteration, and for each of the four mode pairs who waits and which value the consumer reads.

Each example is run with a trace; the statements are checked on its events (`send`,
`receive`, `switch`, and the `fire` events of the data cases and of a blocking producer seeing
its value taken), on the run's summary and on the subsystems' final memory."""

from __future__ import annotations

import json
import subprocess
import sys
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import pytest

from rssm_dsl.diagnostics.render import render_text
from rssm_dsl.interp import RunConfig, SimOptions, Simulator, build_runtime
from rssm_dsl.interp.trace import TraceWriter, read_trace
from rssm_dsl.pipeline import compile_file

ROOT = Path(__file__).resolve().parents[2]
EXAMPLES = ROOT / "examples" / "semantics"
Event = dict[str, Any]


@dataclass(frozen=True)
class Run:
    reason: str
    events: list[Event]
    memory: dict[str, dict[str, Any]]       # subsystem id -> its variables at the end
    subsystems: dict[str, dict[str, Any]]   # subsystem id -> its summary
    channels: dict[str, dict[str, Any]]     # channel id -> its summary

    def iterations(self, subsystem: str) -> int:
        return int(self.subsystems[subsystem]["i"])

    def overruns(self, subsystem: str) -> int:
        return int(self.subsystems[subsystem]["overruns"])


def simulate(name: str, tmp_path: Path, until: float | None = None) -> Run:
    path = EXAMPLES / f"{name}.rssm"
    comp = compile_file(path)
    assert not comp.diagnostics, render_text(comp.diagnostics, comp.program.line)
    rt = build_runtime(comp, RunConfig(base_dir=path.parent))
    trace = tmp_path / f"{name}.jsonl"
    rt.tracer = TraceWriter(trace)
    try:
        result = Simulator(rt, SimOptions(until=until)).run()
    finally:
        rt.tracer.close()
    assert result.ok, result.message
    assert result.summary is not None
    summary = result.summary.to_json()
    return Run(result.reason, read_trace(trace),
               {sid: dict(s.vars) for sid, s in rt.subsystems.items()},
               {s["id"]: s for s in summary["subsystems"]},
               {c["id"]: c for c in summary["channels"]})


# ---------------------------------------------------------------------------- one iteration


def test_one_iteration_in_order(tmp_path: Path) -> None:
    run = simulate("iteration", tmp_path)
    assert run.reason == "finished"
    sends = [e for e in run.events if e["event"] == "send"]
    takes = [e for e in run.events if e["event"] == "receive"]
    # the output partial function reads n as the iteration started: the first value is 1
    assert [e["value"] for e in sends] == [1, 2, 3, 4, 5]
    assert [e["value"] for e in takes] == [1, 2, 3, 4, 5]

    # dst: every iteration is "transition function (one data case), receive, conditions"
    steps: list[tuple[str, Any]] = []
    for e in run.events:
        if e.get("subsystem") != "dst.c":
            continue
        if e["event"] == "receive":
            steps.append(("take", e["value"]))
        elif e["event"] == "switch":
            steps.append(("switch", (e["from"], e["to"], e["conditions"], e["time"])))
        elif e["event"] == "fire" and e["role"] == "case":
            steps.append(("case", (e["label"].endswith("when new(x)"), e["time"])))
        elif e["event"] == "fire" and e["role"] == "iteration":
            steps.append(("end" if " ends " in e["label"] else "next", None))
    assert steps == [
        ("case", (False, 0.0)), ("take", 1), ("next", None),
        ("case", (True, 0.1)), ("take", 2), ("next", None),
        ("case", (True, 0.2)), ("take", 3), ("next", None),
        # the condition sees the 4 received in this iteration, not yet added to total
        ("case", (True, 0.3)), ("take", 4), ("end", None),
        ("switch", ("sum", "report", {"reached": True}, 0.3)),
        # report starts at the next tick and its transition function sees new(x): the 4
        ("case", (True, 0.4)), ("take", 5), ("end", None),
        ("switch", ("report", None, {"done": True}, 0.4)),
    ]
    assert run.memory["dst.c"]["total"] == 1 + 2 + 3 + 4
    assert run.iterations("dst.c") == 5
    assert run.subsystems["dst.c"]["iterations"] == {"sum": 4, "report": 1}

    # src: each iteration computes both partial functions, then sends, then i := i + 1
    order = [("case" if e["event"] == "fire" else "send") for e in run.events
             if e.get("subsystem") == "src.c"
             and (e["event"] == "send" or (e["event"] == "fire" and e["role"] == "case"))]
    assert order == ["case", "case", "send"] * 5
    assert run.iterations("src.c") == 5
    switch = next(e for e in run.events if e["event"] == "switch" and e["subsystem"] == "src.c")
    assert (switch["to"], switch["conditions"]) == (None, {"five": True})


# ---------------------------------------------------------------------------- modes


@dataclass(frozen=True)
class Step:
    kind: str            # send | take (the consumer took a value) | taken (the blocking
    #                      producer saw it taken, its send ends) | case (the consumer's data case)
    time: float
    value: int | None = None
    overwrote: bool = False
    new: bool = False


@dataclass(frozen=True)
class Channel:
    steps: list[Step]

    def of(self, *kinds: str) -> list[Step]:
        return [s for s in self.steps if s.kind in kinds]

    @property
    def sent(self) -> list[int]:
        return [s.value for s in self.of("send") if s.value is not None]

    @property
    def read(self) -> list[int]:
        return [s.value for s in self.of("take") if s.value is not None]

    @property
    def cases(self) -> list[bool]:
        """new(x) as each transition function of the consumer saw it."""
        return [s.new for s in self.of("case")]


def channel(run: Run, producer: str, consumer: str) -> Channel:
    cid = f"{producer}.x->{consumer}.x"
    steps: list[Step] = []
    for e in run.events:
        kind = e["event"]
        if kind == "send" and e["channel"] == cid:
            steps.append(Step("send", e["time"], e["value"], overwrote=e["overwrote"]))
        elif kind == "receive" and e["channel"] == cid:
            steps.append(Step("take", e["time"], e["value"]))
        elif kind == "fire" and e.get("subsystem") == producer and e["label"].endswith(
                "sees x taken (blocking)"):
            steps.append(Step("taken", e["time"]))
        elif kind == "fire" and e.get("subsystem") == consumer and e["role"] == "case":
            new = e["label"].endswith("when new(x)")
            assert new or e["label"].endswith("when not new(x)"), e["label"]
            steps.append(Step("case", e["time"], new=new))
    return Channel(steps)


def check_every_mode(run: Run, ch: Channel, consumer: str) -> None:
    """What holds in every mode: the consumer reads the newest value sent before its receive
    (never one twice, never an older one), new(x) is true for exactly the transition function
    after a receive, and `seen` is the value the last such transition function got."""
    last_sent: int | None = None
    fresh = False
    for s in ch.of("send", "take"):
        if s.kind == "send":
            last_sent, fresh = s.value, True
        else:
            assert fresh and s.value == last_sent, (s, last_sent)
            fresh = False
    previous = "start"
    used: int | None = None
    pending: int | None = None
    for s in ch.of("take", "case"):
        if s.kind == "case":
            assert s.new == (previous == "take"), f"new(x) wrong at {s.time} s"
            if s.new:
                used = pending
        else:
            pending = s.value
        previous = s.kind
    assert run.memory[consumer]["seen"] == (used if used is not None else 0)
    assert not any(e["event"] == "switch" for e in run.events), "error `older` held"


def check_producer_waits(ch: Channel) -> None:
    """A blocking producer: its send ends only once the consumer took the value, so sends,
    takes and the ends of the sends alternate, and nothing is ever overwritten."""
    steps = ch.of("send", "take", "taken")
    assert len(steps) >= 6
    for k, s in enumerate(steps):
        assert s.kind == ("send", "take", "taken")[k % 3], [x.kind for x in steps]
        assert not s.overwrote
    assert ch.read == ch.sent[:len(ch.read)] == list(range(1, len(ch.read) + 1))


def check_producer_goes_on(run: Run, ch: Channel, producer: str) -> None:
    """A non-blocking producer never waits for the take."""
    assert not ch.of("taken")
    assert run.overruns(producer) == 0


def check_overwrites(run: Run, ch: Channel, producer: str, consumer: str) -> None:
    """A faster non-blocking producer: it runs at its own rate, replaces unread values, and the
    consumer reads about every fifth value (each the newest sent before its receive)."""
    assert run.iterations(producer) == 31
    assert ch.sent == list(range(1, 32))
    overwritten = sum(s.overwrote for s in ch.of("send"))
    assert overwritten > 0
    assert run.channels[f"{producer}.x->{consumer}.x"]["overwritten"] == overwritten
    assert len(ch.read) == run.iterations(consumer) == 7
    gaps = [b - a for a, b in zip(ch.read[1:], ch.read[2:], strict=False)]
    assert ch.read[0] == 1 and all(4 <= g <= 6 for g in gaps), ch.read
    # the slow consumer finds a fresh value on each of its ticks
    assert [s.time for s in ch.of("take")] == [0.5 * k for k in range(7)]
    assert run.overruns(consumer) == 0


def check_consumer_waits(run: Run, ch: Channel, consumer: str) -> None:
    """A faster blocking consumer waits for each value: it takes one every 0.5 s, the
    producer's period, and so runs 8 iterations in 3 s instead of 31."""
    assert run.iterations(consumer) == 8
    assert run.overruns(consumer) > 0
    assert ch.read == list(range(1, 8))
    assert [s.time for s in ch.of("take")] == [0.5 * k for k in range(7)]
    assert ch.cases == [False] + [True] * 7


def check_consumer_goes_on(run: Run, ch: Channel, consumer: str) -> None:
    """A faster non-blocking consumer never waits: it runs at its own rate, takes each value
    once and, in the iterations after which nothing was taken, keeps x with new(x) false."""
    assert run.iterations(consumer) == 31
    assert run.overruns(consumer) == 0
    assert ch.read == list(range(1, 8))
    assert len(ch.cases) == 31 and ch.cases.count(True) == 6      # the 7th take is at 3.0 s
    assert run.memory[consumer]["x"] == 7


def check_slow_consumer_reads_all(run: Run, ch: Channel, producer: str, consumer: str) -> None:
    """A faster blocking producer is held back to the consumer's rate; the consumer reads
    every value, with new(x) in every iteration after its first."""
    assert run.iterations(producer) == 7 and run.overruns(producer) == 6
    assert run.iterations(consumer) == 7
    assert ch.read == list(range(1, 8))
    assert ch.cases == [False] + [True] * 6
    sends, takes = ch.of("send"), ch.of("take")
    # it sends 1 and 2, its send of 2 waits until the take at 0.5 s, then it sends 3
    assert [s.time for s in sends[:3]] == [0.0, 0.1, 0.5]
    assert takes[1].time == 0.5
    assert ch.steps.index(sends[2]) > ch.steps.index(ch.of("taken")[1])


@pytest.mark.parametrize("pair", ["bb", "bn", "nb", "nn"])
def test_mode_example(pair: str, tmp_path: Path) -> None:
    run = simulate(f"mode_{pair}", tmp_path, until=3.0)
    assert run.reason == "until"
    fast = channel(run, "fast_src.c", "slow_dst.c")    # the producer is faster
    slow = channel(run, "slow_src.c", "fast_dst.c")    # the consumer is faster
    check_every_mode(run, fast, "slow_dst.c")
    check_every_mode(run, slow, "fast_dst.c")
    assert run.iterations("slow_src.c") == 7
    producer_blocks, consumer_blocks = pair[0] == "b", pair[1] == "b"

    if producer_blocks:
        check_producer_waits(fast)
        check_producer_waits(slow)
        check_slow_consumer_reads_all(run, fast, "fast_src.c", "slow_dst.c")
    else:
        check_producer_goes_on(run, fast, "fast_src.c")
        check_producer_goes_on(run, slow, "slow_src.c")
        check_overwrites(run, fast, "fast_src.c", "slow_dst.c")

    if consumer_blocks:
        check_consumer_waits(run, slow, "fast_dst.c")
    else:
        check_consumer_goes_on(run, slow, "fast_dst.c")
        if producer_blocks:
            # the slow producer's send still waits for the take, at most one period of
            # the fast consumer
            for send, take in zip(slow.of("send"), slow.of("take"), strict=False):
                assert 0.0 <= take.time - send.time <= 0.1 + 1e-9


def test_the_printed_summary_of_mode_nn(tmp_path: Path) -> None:
    run = simulate("mode_nn", tmp_path, until=3.0)
    assert {sid: run.iterations(sid) for sid in run.subsystems} == {
        "fast_src.c": 31, "slow_dst.c": 7, "slow_src.c": 7, "fast_dst.c": 31}
    fast = run.channels["fast_src.c.x->slow_dst.c.x"]
    slow = run.channels["slow_src.c.x->fast_dst.c.x"]
    assert (fast["state"], fast["sent"], fast["received"], fast["overwritten"], fast["value"]) \
        == ("full", 31, 7, 23, "31")
    assert (slow["state"], slow["sent"], slow["received"], slow["overwritten"], slow["value"]) \
        == ("empty", 7, 7, 0, "7")


@pytest.mark.parametrize("name", ["iteration", "mode_bb", "mode_bn", "mode_nb", "mode_nn"])
def test_the_verifier_finds_no_deadlock(name: str) -> None:
    r = subprocess.run([sys.executable, "-m", "rssm_dsl", "verify",
                        str(EXAMPLES / f"{name}.rssm"), "--format", "json"],
                       cwd=ROOT, capture_output=True, text=True, timeout=600)
    report = json.loads(r.stdout)
    assert (r.returncode, report["verdict"]) == (0, "verified"), r.stdout[:2000]
    assert report["safe"] is True and report["deadlock_free"] is True
    assert report["progress_ok"] is True
