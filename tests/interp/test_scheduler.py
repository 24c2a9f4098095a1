"""The scheduler: reproducibility, the clock, stopping, the communication modes' meaning,
behaviour switching, deadlocks, Ctrl-C."""

from __future__ import annotations

import itertools
import shutil
from pathlib import Path

import pytest

from rssm_dsl.hpn.flat import FlatNet, FlatPlace, FlatTransition
from rssm_dsl.interp import RunConfig, SimOptions, Simulator
from rssm_dsl.interp.engine import TokenGame, UnsafeFiring
from rssm_dsl.interp.trace import TraceWriter, read_trace
from rssm_dsl.source import Span
from tests.interp.conftest import (
    EXAMPLES,
    SPECS,
    compile_text,
    compiled,
    lwr4_config,
    run,
    runtime,
)


def traced(tmp_path: Path, name: str, comp_path: Path,
           **options: object) -> list[dict[str, object]]:
    comp = compiled(comp_path)
    rt = runtime(comp)
    rt.tracer = TraceWriter(tmp_path / name)
    Simulator(rt, SimOptions(**options)).run()   # type: ignore[arg-type]
    rt.tracer.close()
    return read_trace(tmp_path / name)


def test_same_seed_same_run_other_seed_other_interleaving(tmp_path: Path) -> None:
    spec = EXAMPLES / "relay_blocking.rssm"
    a = traced(tmp_path, "a.jsonl", spec, seed=7, until=0.2)
    b = traced(tmp_path, "b.jsonl", spec, seed=7, until=0.2)
    c = traced(tmp_path, "c.jsonl", spec, seed=8, until=0.2)
    assert a == b
    fires = [[e["transition"] for e in t if e["event"] == "fire"] for t in (a, c)]
    assert fires[0] != fires[1]


def test_macro_steps_and_tracing_change_nothing_but_speed(lwr4: object,
                                                         tmp_path: Path) -> None:
    """Local steps compiled into macro steps make the same run as firing them one by one (as
    a traced run does)."""
    runs = []
    for macros, trace in ((True, False), (False, False), (True, True)):
        rt = runtime(lwr4, lwr4_config())  # type: ignore[arg-type]
        if trace:
            rt.tracer = TraceWriter(tmp_path / "t.jsonl")
        result = Simulator(rt, SimOptions(seed=3, until=0.15, macros=macros)).run()
        if rt.tracer is not None:
            rt.tracer.close()
        runs.append((result.steps, result.marking, {s: (x.i, repr(x.vars)) for s, x in
                                                    rt.subsystems.items()},
                     {c: (x.sent, x.received, x.overwritten) for c, x in rt.channels.items()}))
    assert runs[0] == runs[1] == runs[2]


def test_steps_limit_is_exact(lwr4: object) -> None:
    for n in (1, 17, 1000):
        _, result = run(lwr4, lwr4_config(), max_steps=n)  # type: ignore[arg-type]
        assert result.reason == "steps" and result.steps == n


def test_frequencies_are_honoured_on_the_simulated_clock(lwr4: object) -> None:
    rt, result = run(lwr4, lwr4_config(), until=0.5)  # type: ignore[arg-type]
    assert result.reason == "until" and result.time == 0.5
    # an iteration starts at every tick 0, 1/f, ..., T: f*T + 1 of them
    assert rt.subsystems["a1.e.lwr"].i == 501
    assert rt.subsystems["a1.c"].i == 51
    assert rt.devices["a1.E.lwr"].steps == 501
    assert all(s.ticker is not None and s.ticker.overruns == 0
               for s in rt.subsystems.values())


def test_blocking_modes_keep_their_meaning() -> None:
    comp = compiled(EXAMPLES / "relay_blocking.rssm")
    rt, _ = run(comp, until=1.0, seed=2)
    request = rt.channels["a1.c.request->a2.c.request"]      # blocking / blocking
    reply = rt.channels["a2.c.reply->a1.c.reply"]            # nonblocking / blocking
    assert request.overwritten == 0 and request.sent - request.received in (0, 1)
    assert reply.received <= reply.sent
    a1, a2 = rt.subsystems["a1.c"], rt.subsystems["a2.c"]
    # a1 runs at 100 Hz; every request is taken, a2 answers each one
    assert a1.i == 101 and abs(a2.i - a1.i) <= 1
    # up counts to 5 and down counts back: the switches alternate
    assert a1.switches >= 8 and a1.behaviours["up"].iterations > 0 \
        and a1.behaviours["down"].iterations > 0


def test_new_is_true_once_per_received_value(tmp_path: Path) -> None:
    text = """
system t {
  agent a1 {
    control c @ 10 Hz {
      memory k: int = 0
      output v: int to e.x nonblocking
      behaviour run {
        update v { v := k }
        update memory { k := k + 1 }
        terminal never when false
      }
      initial run
    }
    effector x @ 100 Hz {
      input v: int from c nonblocking
      memory fresh: int = 0
      memory stale: int = 0
      memory last: int = -1
      behaviour take {
        update memory {
          case new(v):
            fresh := fresh + 1
            last := v
          otherwise:
            stale := stale + 1
        }
        terminal never when fresh < 0 or stale < 0 or last < -1
      }
      initial take
      switch take -> take when never
    }
  }
}
"""
    comp = compile_text(tmp_path, text)
    rt, _ = run(comp, until=1.0)
    x = rt.subsystems["a1.e.x"]
    ch = rt.channels["a1.c.v->a1.e.x.v"]
    # new(v) held for exactly the values received, each used by one transition function
    assert x.vars["fresh"] in (ch.received, ch.received - 1)
    assert x.vars["fresh"] + x.vars["stale"] in (x.i, x.i - 1)
    assert 9 <= ch.received <= 11 and x.vars["stale"] > 80


def test_otherwise_switch_and_termination(tmp_path: Path) -> None:
    text = """
system t {
  agent a1 {
    control c {
      memory n: int = 0
      behaviour count {
        update memory { n := n + 1 }
        terminal enough when n >= 3
      }
      behaviour odd {
        update memory { n := n + 10 }
        terminal once when true
      }
      initial count
      switch count -> odd when n % 2 == 1
      switch count -> end otherwise
      switch odd -> end when once
    }
  }
}
"""
    comp = compile_text(tmp_path, text)
    rt, result = run(comp, max_steps=10_000)
    c = rt.subsystems["a1.c"]
    assert result.reason == "finished"
    assert c.ended and c.vars["n"] == 13 and c.behaviours["odd"].iterations == 1


def test_deadlock_is_reported_with_the_user_names() -> None:
    comp = compiled(SPECS / "handshake_deadlock.rssm")
    _, result = run(comp, until=5.0)
    assert result.reason == "deadlock"
    (d,) = result.diagnostics
    assert d.code == "E805"
    waiting = {b.owner: b.place for b in result.blocked}
    assert waiting == {"a1.c": "p[1,c,greet,snd,1,wait]", "a2.c": "p[2,c,greet,snd,1,wait]"}
    assert "a1.c waits in p[1,c,greet,snd,1,wait]" in d.message
    assert result.time == 0.0


def test_ctrl_c_stops_cleanly_and_flushes(tmp_path: Path) -> None:
    (tmp_path / "stopper.py").write_text(
        "def maybe_stop(x):\n"
        "    if x >= 5.0:\n"
        "        raise KeyboardInterrupt\n"
        "    return x\n")
    text = """
extern maybe_stop(x: float) -> float = "stopper:maybe_stop"
system t {
  agent a1 {
    control c @ 100 Hz {
      memory x: float = 0.0
      behaviour b {
        update memory { x := maybe_stop(x + 1.0) }
        terminal never when false
      }
      initial b
    }
  }
}
"""
    comp = compile_text(tmp_path, text)
    rt = runtime(comp, RunConfig(base_dir=tmp_path))
    rt.tracer = TraceWriter(tmp_path / "t.jsonl")
    result = Simulator(rt, SimOptions(until=10.0)).run()
    rt.tracer.close()
    assert result.reason == "interrupted" and result.ok
    assert rt.subsystems["a1.c"].vars["x"] == 4.0
    events = read_trace(tmp_path / "t.jsonl")
    assert events[-1]["event"] == "end" and events[-1]["reason"] == "interrupted"


def test_token_game_detects_unsafe_firings() -> None:
    s = Span("n", 1, 1, 1, 1)
    places = tuple(FlatPlace(i, f"p{i}", f"p{i}", s, (f"p{i}",)) for i in range(3))
    trans = (FlatTransition(0, "t0", "t0", s, (0,), (1, 2)),
             FlatTransition(1, "t1", "t1", s, (1,), (2,)))
    game = TokenGame(FlatNet("n", places, trans, frozenset({0}), frozenset()))
    game.fire(0)
    assert game.marking() == {1, 2} and game.enabled == {1}
    with pytest.raises(UnsafeFiring):
        game.fire(1)


def test_spec_folder_copy_runs_the_camera_example(tmp_path: Path) -> None:
    """The camera example: CSV replay into a virtual receptor, behaviour switches on data."""
    for name in ("camera_tracker.rssm", "camera.csv"):
        shutil.copy(EXAMPLES / name, tmp_path / name)
    comp = compiled(tmp_path / "camera_tracker.rssm")
    rt, result = run(comp, until=3.0, seed=1)
    assert result.reason == "until"
    c = rt.subsystems["a1.c"]
    assert c.behaviours["search"].iterations > 0 and c.behaviours["track"].iterations > 0
    assert c.switches >= 2
    assert rt.devices["a1.R.camera"].steps == 91 and rt.devices["a1.E.motor"].steps == 301
    pan = rt.subsystems["a1.e.pan"]
    assert abs(pan.vars["command"] - rt.devices["a1.E.motor"].vars["angle"]) <= 0.02 + 1e-9


def _solo(name: str, hz: str = "") -> str:
    return f"""
  agent {name} {{
    control c{hz} {{
      memory n: int = 0
      behaviour go {{
        update memory {{ n := n + 1 }}
        terminal never when false
      }}
      initial go
    }}
  }}"""


@pytest.mark.parametrize("agents", ["ab", "abc"])
@pytest.mark.parametrize("eager", [True, False])
def test_the_seeded_choice_reaches_each_of_three_enabled_transitions(tmp_path: Path,
                                                                     eager: bool,
                                                                     agents: str) -> None:
    """Two or three agents whose control subsystems can all start at once (on their first
    tick): over seeds, each is the first to enter its behaviour (the choice is among all
    that are enabled, not the first, the lowest or the last)."""
    comp = compile_text(tmp_path, "system three {" + "".join(_solo(x, " @ 10 Hz") for x in agents)
                        + "\n}\n")
    first: set[str] = set()
    begins: set[str] = set()      # the first iteration to begin: a choice among ticks due
    for seed in range(24):
        rt = runtime(comp)
        rt.tracer = TraceWriter(tmp_path / f"{seed}.jsonl")
        Simulator(rt, SimOptions(seed=seed, max_steps=60, eager=eager)).run()
        rt.tracer.close()
        events = read_trace(tmp_path / f"{seed}.jsonl")
        enters = [e["subsystem"] for e in events if e["event"] == "enter"]
        assert sorted(enters) == [f"{x}.c" for x in agents], enters
        first.add(str(enters[0]))
        begins.add(next(str(e["subsystem"]) for e in events if e["event"] == "fire"
                        and str(e["label"]).endswith("(go) begins")))
    assert first == {f"{x}.c" for x in agents}
    if not eager:           # eager: an iteration begins as soon as its subsystem entered
        assert begins == {f"{x}.c" for x in agents}


def _starts(tmp_path: Path, mode: str, eager: bool) -> tuple[dict[str, list[float]], object]:
    """The times at which each paced subsystem of a 10 Hz / 30 Hz pair starts iterations."""
    comp = compile_text(tmp_path, "system rates {" + _solo("slow", " @ 10 Hz")
                        + _solo("fast", " @ 30 Hz") + "\n}\n")
    wall = mode == "concurrent"
    rt = runtime(comp, RunConfig(base_dir=tmp_path, wall_clock=wall))
    gated = {rt.net.transitions[t].name: rt.net.transitions[t].subsystem
             for t, g in enumerate(rt.gates) if g is not None}
    rt.tracer = TraceWriter(tmp_path / f"{mode}-{eager}.jsonl")
    result = Simulator(rt, SimOptions(mode=mode, until=0.5, eager=eager)).run()
    rt.tracer.close()
    starts: dict[str, list[float]] = {"slow.c": [], "fast.c": []}
    for e in read_trace(tmp_path / f"{mode}-{eager}.jsonl"):
        if e["event"] == "fire" and e["transition"] in gated:
            starts[str(gated[str(e["transition"])])].append(float(e["time"]))  # type: ignore[arg-type]
    return starts, result


@pytest.mark.parametrize("eager", [True, False])
def test_subsystems_at_different_rates_start_on_their_own_ticks(tmp_path: Path,
                                                                eager: bool) -> None:
    """On the simulated clock, with or without eager local steps: the 10 Hz subsystem starts
    its iterations at 0, 0.1, ..., 0.5 and the 30 Hz one at every 1/30 s, each exactly on
    its tick, neither held back by the other nor running ahead."""
    starts, _ = _starts(tmp_path, "deterministic", eager)
    assert starts["slow.c"] == pytest.approx([k / 10 for k in range(6)])
    assert starts["fast.c"] == pytest.approx([k / 30 for k in range(16)])


def test_concurrent_mode_never_starts_an_iteration_before_its_tick(tmp_path: Path) -> None:
    """On the wall clock the k-th iteration of a subsystem at f Hz starts at k/f or later (a
    busy machine makes it late and skips ticks, never early)."""
    starts, result = _starts(tmp_path, "concurrent", True)
    assert result.reason == "until"  # type: ignore[attr-defined]
    for sid, hz in (("slow.c", 10), ("fast.c", 30)):
        times = starts[sid]
        assert 1 <= len(times) <= 0.5 * hz + 1, (sid, times)
        ticks = [round(t * hz, 6) for t in times]
        # one start per tick at most: each in a later tick's period than the one before
        assert all(int(b + 1e-6) > int(a + 1e-6)
                   for a, b in itertools.pairwise(ticks)), ticks
        assert all(t >= k - 1e-6 for k, t in enumerate(ticks)), ticks


def test_an_overrun_is_a_start_a_whole_period_late() -> None:
    """The clock model (docs/simulate.md): an iteration that starts late by less than a
    period is no overrun and keeps the next tick on the grid; one late by a whole period or
    more is an overrun, and the ticks it missed are skipped."""
    from rssm_dsl.interp.clock import Ticker

    t = Ticker("a1.c", 10.0)                 # period 100 ms
    t.start(0)
    assert (t.next, t.overruns) == (100_000_000, 0)
    t.start(150_000_000)                     # half a period late
    assert (t.next, t.overruns) == (200_000_000, 0)
    t.start(299_999_999)                     # a whole period late, less 1 ns
    assert (t.next, t.overruns) == (300_000_000, 0)
    t.start(400_000_000)                     # a whole period late: the tick at 300 ms missed
    assert (t.next, t.overruns) == (500_000_000, 1)
    t.start(750_000_000)                     # 2.5 periods late: one overrun, ticks skipped
    assert (t.next, t.overruns) == (800_000_000, 2)
