"""The table of expectations (expectations.py) on the generated ROS 2 nodes over real DDS:
one workspace with every agent of the semantic tests (systems.ros_system()), built once per
session; each group of rows runs some of its agents with the launch runner and is judged
from the nodes' traces (one JSON-lines file per subsystem: every iteration's new(x), the
samples sent and received with their sequence numbers, the conditions; every behaviour
switch and error) and their exit codes.

Time is real here, so the situations are made dominant by generous rate ratios and judged on
counts and order, never on exact timing:

- fast producer (200 Hz) / slow consumer (10 Hz): data always waits (blocking producer) or is
  overwritten (non-blocking producer);
- slow producer (10 Hz) / fast consumer (200 Hz): mostly no data (a blocking consumer waits,
  a non-blocking one goes on), and a non-blocking consumer finds every sample waiting once;
- agent nbw, producer 15 Hz / consumer 10 Hz: a blocking consumer that never waits finds one
  sample or two (one overwritten)."""

from __future__ import annotations

import itertools
import statistics
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import pytest

from rssm_dsl.ros2 import toolchain
from tests.ros2.conftest import Processes
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
    Situation,
    SwitchRow,
)
from tests.semantics.ros_runner import Launch, build, launch
from tests.semantics.systems import MODE_AGENTS, RECEIVE_AGENTS, SEND_AGENTS

pytestmark = [pytest.mark.ros2, pytest.mark.slow]

RUN = 12.0           # seconds the nodes of a mode or arrangement run (start-up included)
FAST, SLOW = 200.0, 10.0
_launches: dict[str, Launch] = {}
RunOf = Callable[[str], Launch]


def _rates(agents: dict[str, tuple[float, float]]) -> tuple[str, ...]:
    return tuple(p for a, (prod, cons) in agents.items()
                 for p in (f"/{a}/c:rssm.rate_hz:={prod}", f"/{a}/e_sink:rssm.rate_hz:={cons}"))


RUNS: dict[str, tuple[list[str], float, tuple[str, ...]]] = {
    "fast-producer": ([*MODE_AGENTS, "nbw"], RUN,
                      _rates({**{a: (FAST, SLOW) for a in MODE_AGENTS}, "nbw": (15.0, 10.0)})),
    "slow-producer": (list(MODE_AGENTS), RUN, _rates({a: (SLOW, FAST) for a in MODE_AGENTS})),
    "receive": (list(RECEIVE_AGENTS), RUN, ()),
    "send": (list(SEND_AGENTS), RUN, ()),
    "behaviours": (["cond", "sw", "errh", "errv", "errt", "erru", "solo"], 10.0, ()),
}


@pytest.fixture
def run_of(ros_venv: toolchain.RosVenv, build_dir: Path, domain: int, tmp_path: Path,
           processes: Processes) -> RunOf:
    """run_of(name): the launch `name` of RUNS, run once per session (by the first test
    that needs it, on its domain)."""

    def get(name: str) -> Launch:
        if name not in _launches:
            built = build(ros_venv, build_dir)
            agents, duration, params = RUNS[name]
            _launches[name] = launch(built, domain, tmp_path / name, processes, agents,
                                     duration, params)
        return _launches[name]

    return get


# ---------------------------------------------------------------------------- modes


@dataclass
class Pair:
    produced: int                # producer iterations (one sample each)
    consumed: int                # consumer iterations
    took: list[int | None]       # per consumer iteration: seq of the sample taken, or None
    new: list[bool]              # per consumer iteration: new(data) its transition function saw
    intervals: list[float]       # seconds between the ends of consecutive consumer iterations

    @property
    def takes(self) -> list[int]:
        return [s for s in self.took if s is not None]

    @property
    def gaps(self) -> list[int]:
        """Per take after the first: samples skipped since the previous take."""
        t = self.takes
        return [b - a - 1 for a, b in itertools.pairwise(t)]


def pair(run: Launch, agent: str) -> Pair:
    prod = run.of(f"{agent}.c", "iteration")
    cons = run.of(f"{agent}.e.sink", "iteration")
    took: list[int | None] = []
    for e in cons:
        got = e["received"].get("data")
        if got is not None:
            # the producers count: sample k carries k (compute, then send)
            assert got["value"] == got["seq"], got
        took.append(None if got is None else int(got["seq"]))
    ends = [float(e["t"]) for e in cons]
    return Pair(len(prod), len(cons), took, [bool(e["new"][0]) for e in cons],
                [b - a for a, b in itertools.pairwise(ends)])


def _agent(row: ModeRow) -> tuple[str, str]:
    """The agent and run in which the row's situation dominates."""
    name = row.pair
    if row.situation is Situation.NO_DATA:
        return name, "slow-producer"
    if row.situation is Situation.OVERWRITTEN or row.producer is Mode.BLOCKING:
        return name, "fast-producer"
    if row.consumer is Mode.NONBLOCKING:
        return name, "slow-producer"     # the fast consumer finds every sample once
    return "nbw", "fast-producer"        # close rates: the consumer never waits


def _generic(p: Pair) -> None:
    takes = p.takes
    assert len(takes) >= 10, p
    assert all(a < b for a, b in itertools.pairwise(takes)), "a sample taken twice"
    # new(x) of an iteration is what the previous iteration's receive did
    assert p.new[1:] == [t is not None for t in p.took[:-1]], "new(x) is not the last receive"


@pytest.mark.parametrize("row", MODE_ROWS, ids=lambda r: r.id)
def test_mode_row(run_of: RunOf, row: ModeRow) -> None:
    agent, run_name = _agent(row)
    p = pair(run_of(run_name), agent)
    _generic(p)
    # the producer's mode shows best against a slow consumer
    fast = pair(run_of("fast-producer"), row.pair)
    if row.producer_waits:
        assert fast.produced <= len(fast.takes) + 1, (fast.produced, len(fast.takes))
    else:
        assert fast.produced >= 4 * len(fast.takes), (fast.produced, len(fast.takes))

    if not row.arises:
        # a blocking producer never runs ahead: every sample is taken, none skipped
        assert p.takes == list(range(1, len(p.takes) + 1)), p.takes[:20]
        return
    took_share = len(p.takes) / p.consumed
    if row.situation is Situation.NO_DATA:
        if row.consumer_waits:
            assert p.consumed <= p.produced + 1, (p.consumed, p.produced)
            assert statistics.median(p.intervals) >= 5 / FAST, "the consumer did not wait"
        else:
            assert p.consumed >= 4 * p.produced, (p.consumed, p.produced)
            assert p.took.count(None) >= 3 * len(p.takes), "mostly nothing new"
    elif agent != "nbw" and run_name == "fast-producer":
        # the consumer is the slow side: data waits in (almost) every iteration
        assert took_share >= 0.9, took_share
    elif agent == "nbw":
        assert took_share >= 0.8, took_share
    else:
        assert p.consumed >= 4 * p.produced, (p.consumed, p.produced)
    if row.reads is Reads.PREVIOUS:
        assert p.new.count(False) >= 3 * p.new.count(True)
    elif row.reads is Reads.NEWEST:
        assert sum(p.gaps) >= 3 * len(p.takes), p.takes[:20]       # newest: the rest lost
    elif agent == "nbw":
        assert sum(g == 0 for g in p.gaps) >= len(p.gaps) // 4, p.gaps   # the one waiting
    else:
        _no_loss(row, p)                                  # every sample read once, in order
    if row.new:
        assert p.new.count(True) >= 10
    if not row.lost and agent != "nbw":
        _no_loss(row, p)


def _no_loss(row: ModeRow, p: Pair) -> None:
    """No sample skipped between two takes. A blocking producer makes that certain; with a
    non-blocking one, a consumer stalled for a whole producer period on a loaded machine
    meets another situation (overwritten), so a few gaps are tolerated there."""
    if row.producer is Mode.BLOCKING:
        assert set(p.gaps) == {0}, p.takes[:20]
    else:
        assert sum(g == 0 for g in p.gaps) >= 0.95 * len(p.gaps), p.gaps


@pytest.mark.parametrize("row", PATTERN_ROWS, ids=lambda r: r.id)
def test_pattern_row(run_of: RunOf, row: PatternRow) -> None:
    if row.id == "compute-then-send":
        # sample k carries k (pair() checks it for every sample taken): the output computed
        # in the iteration that sent it, not the one before (sample 1 would carry 0)
        for agent in MODE_AGENTS:
            assert len(pair(run_of("slow-producer"), agent).takes) >= 10
    elif row.id == "receive-then-use":
        for agent in MODE_AGENTS:
            _generic(pair(run_of("slow-producer"), agent))
    else:
        run: Launch = run_of("behaviours")
        iters = run.of("cond.e.w", "iteration")
        watch = [e for e in iters if e["behaviour"] == "watch"]
        after = [e for e in iters if e["behaviour"] == "after"]
        assert [e["received"]["data"]["value"] for e in watch] == [1, 2, 3]
        assert after and after[0]["new"] == [True]
        (switch,) = run.of("cond.e.w", "switch")
        assert (switch["from"], switch["to"], switch["conditions"]) == ("watch", "after",
                                                                      {"got3": True})


# ---------------------------------------------------------------------------- arrangements


@pytest.mark.parametrize("row", ARRANGEMENT_ROWS, ids=lambda r: r.id)
def test_arrangement_row(run_of: RunOf, row: ArrangementRow) -> None:
    """The order in which a's and b's operations completed in each iteration (the order of
    the trace's `received` / `sent`); b completes first while a waits."""
    agents = RECEIVE_AGENTS if row.side == "receive" else SEND_AGENTS
    agent = next(a for a, arr in agents.items() if arr == row.arrangement)
    run: Launch = run_of(row.side)
    field = "received" if row.side == "receive" else "sent"
    orders = [tuple(e[field]) for e in run.of(f"{agent}.c", "iteration")]
    both = [o for o in orders if set(o) == {"a", "b"}]
    assert len(both) >= 10, orders
    if row.order is not None:
        assert set(both) == {row.order}, set(both)
    if row.b_while_a_waits:
        assert both.count(("b", "a")) >= 0.8 * len(both), both


# ---------------------------------------------------------------------------- switching, ending


def behaviour_run(run: Launch, agent: str) -> BehaviourRun:
    sub = f"{agent}.c"
    iterations: dict[str, int] = {}
    for e in run.of(sub, "iteration"):
        iterations[e["behaviour"]] = iterations.get(e["behaviour"], 0) + 1
    switches = [(e["from"], e["to"], e["conditions"]) for e in run.of(sub, "switch")]
    errors = [(e["code"], e["handled"]) for e in run.of(sub, "error")]
    code = run.exits.get(f"/{agent}/c")
    stopped = errors[-1][0] if code == 1 and errors else None
    last_i = max((e["i"] for e in run.traces.get(sub, []) if "i" in e), default=None)
    return BehaviourRun(iterations, switches, errors,
                        ended=code == 0 and bool(switches) and switches[-1][1] is None,
                        stopped=stopped, i=last_i)


@pytest.mark.parametrize("row", SWITCH_ROWS, ids=lambda r: r.id)
def test_switch_row(run_of: RunOf, row: SwitchRow) -> None:
    run: Launch = run_of("behaviours")
    check_switch_row(row, behaviour_run(run, "sw"))


@pytest.mark.parametrize("row", ENDING_ROWS, ids=lambda r: r.id)
def test_ending_row(run_of: RunOf, row: EndingRow) -> None:
    run: Launch = run_of("behaviours")
    agent = ENDING_AGENTS[row.id]
    code = run.exits.get(f"/{agent}/c")
    assert code == (1 if row.id == "unhandled-failure-stops" else 0), run.log
    check_ending_row(row, behaviour_run(run, agent))


def test_subsystem_without_channels(run_of: RunOf) -> None:
    """Agent solo: a control subsystem without channels iterates 3 times and ends."""
    run = run_of("behaviours")
    assert run.exits.get("/solo/c") == 0, run.log
    assert len(run.of("solo.c", "iteration")) == 3
    assert [(e["from"], e["to"]) for e in run.of("solo.c", "switch")] == [("b", None)]
