"""The interpreter agrees with the verifier: every marking it reaches is in the verifier's
reachable set, a spec the verifier finds deadlocking deadlocks in simulation with the same
marking (in the same names), and the verifier's counterexamples replay as it says."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import pytest

from rssm_dsl.hpn.flatten import flatten
from rssm_dsl.interp import RunConfig, SimOptions, Simulator
from rssm_dsl.interp.replay import judge, load_counterexample, resolve_steps
from rssm_dsl.interp.trace import TraceWriter, read_trace
from rssm_dsl.pipeline import Compilation
from rssm_dsl.verify import VerifyOptions, verify
from rssm_dsl.verify.netbits import NetBits, bits, to_mask
from rssm_dsl.verify.statespace import explore_full
from tests.interp.conftest import EXAMPLES, SPECS, compiled, lwr4_config, runtime


def reachable(comp: Compilation) -> set[int]:
    assert comp.hpn is not None
    nb = NetBits.of(flatten(comp.hpn))
    result = explore_full(nb, max_states=1_000_000)
    assert result.complete and result.graph is not None
    return {result.graph.marking(s) for s in range(result.graph.size)}


def markings(comp: Compilation, config: RunConfig | None, **options: object) -> list[int]:
    rt = runtime(comp, config)
    sim = Simulator(rt, SimOptions(record_markings=True, **options))  # type: ignore[arg-type]
    sim.run()
    return [to_mask(m) for m in sim.markings]


@pytest.mark.parametrize("name", ["lwr4_circle", "relay_blocking"])
def test_every_marking_reached_is_in_the_verifiers_reachable_set(name: str) -> None:
    comp = compiled(EXAMPLES / f"{name}.rssm")
    config = lwr4_config() if name == "lwr4_circle" else None
    states = reachable(comp)
    seen: set[int] = set()
    for seed in range(3):
        for eager in (True, False):
            ms = markings(comp, config, seed=seed, until=0.05, eager=eager)
            assert len(ms) > 100
            outside = [m for m in ms if m not in states]
            assert not outside, f"seed {seed}: {len(outside)} markings outside the state space"
            seen.update(ms)
    assert len(seen) > 50


def test_camera_example_fires_by_the_verifiers_rule(tmp_path: Path) -> None:
    """Too many states to enumerate here (over 3 million): check instead that every firing of
    the trace is enabled by the verifier's firing rule and leads to the marking the
    interpreter recorded."""
    for name in ("camera_tracker.rssm", "camera.csv"):
        shutil.copy(EXAMPLES / name, tmp_path / name)
    comp = compiled(tmp_path / "camera_tracker.rssm")
    assert comp.hpn is not None
    nb = NetBits.of(flatten(comp.hpn))
    rt = runtime(comp)
    rt.tracer = TraceWriter(tmp_path / "t.jsonl")
    sim = Simulator(rt, SimOptions(record_markings=True, until=0.5, seed=4))
    sim.run()
    rt.tracer.close()
    index = {t.name: t.index for t in nb.net.transitions}
    fired = [index[e["transition"]] for e in read_trace(tmp_path / "t.jsonl")
             if e["event"] == "fire"]
    m = nb.initial
    assert to_mask(sim.markings[0]) == m
    for k, t in enumerate(fired):
        assert m & nb.pre[t] == nb.pre[t], f"step {k + 1}: {nb.net.transitions[t].name}"
        assert not nb.unsafe_places(m, t)
        m = nb.fire(m, t)
        assert m == to_mask(sim.markings[k + 1])
    assert len(fired) > 1000


def test_a_deadlock_found_by_the_verifier_happens_in_simulation() -> None:
    comp = compiled(SPECS / "handshake_deadlock.rssm")
    assert comp.hpn is not None
    net = flatten(comp.hpn)
    report = verify(net, VerifyOptions(check_progress=False))
    assert report.deadlock_free is False and report.deadlocks
    verifier_markings = {tuple(sorted(c.marking)) for c in report.deadlocks}
    for seed in range(5):
        rt = runtime(comp)
        result = Simulator(rt, SimOptions(seed=seed, until=10.0)).run()
        assert result.reason == "deadlock"
        assert result.diagnostics[0].code == "E805"
        labels = tuple(sorted(net.place(n).label for n in result.marking))
        assert labels in verifier_markings


def test_replaying_the_verifiers_deadlock(tmp_path: Path) -> None:
    comp = compiled(SPECS / "handshake_deadlock.rssm")
    assert comp.hpn is not None
    report = verify(flatten(comp.hpn), VerifyOptions(check_progress=False))
    path = tmp_path / "report.json"
    path.write_text(json.dumps(report.to_json()), encoding="utf-8")
    cx = load_counterexample(path)
    assert cx.kind == "deadlock" and cx.steps
    rt = runtime(comp)
    forced, bad = resolve_steps(rt.net, cx.sequence(), str(path))
    assert not bad
    sim = Simulator(rt, SimOptions(forced=forced))
    result = sim.run()
    verdict = judge(cx, forced, result, sim)
    assert result.reason == "replayed" and result.steps == len(cx.steps)
    assert verdict.reproduced, verdict.message
    assert "differs" not in verdict.message
    assert verdict.diagnostics[0].code == "E805"


def test_replaying_a_loss_of_progress(tmp_path: Path) -> None:
    comp = compiled(SPECS / "starve.rssm")
    assert comp.hpn is not None
    report = verify(flatten(comp.hpn))
    assert report.progress and report.progress[0].subsystem == "a1.c"
    path = tmp_path / "report.json"
    path.write_text(json.dumps(report.to_json()), encoding="utf-8")
    cx = load_counterexample(path)
    assert cx.kind == "progress" and cx.cycle
    rt = runtime(comp)
    forced, _ = resolve_steps(rt.net, cx.sequence(), str(path))
    sim = Simulator(rt, SimOptions(forced=forced, record_markings=True))
    result = sim.run()
    verdict = judge(cx, forced, result, sim)
    assert verdict.reproduced, verdict.message
    assert "a1.c never completes an iteration again" in verdict.message


def test_a_replay_that_does_not_fit_diverges(tmp_path: Path) -> None:
    comp = compiled(SPECS / "handshake_deadlock.rssm")
    rt = runtime(comp)
    names = ["t[in]", "t[1,c,greet,4]"]
    path = tmp_path / "bad.json"
    path.write_text(json.dumps(names))
    cx = load_counterexample(path)
    forced, bad = resolve_steps(rt.net, cx.sequence(), str(path))
    assert not bad
    sim = Simulator(rt, SimOptions(forced=forced))
    result = sim.run()
    assert result.reason == "error" and result.diagnostics[0].code == "E806"
    assert "t[1,c,greet,4], which is not enabled" in result.diagnostics[0].message
    _, unknown = resolve_steps(rt.net, ["t[9,nope]"], str(path))
    assert unknown and unknown[0].code == "E806"


def test_trace_replays_the_same_run(tmp_path: Path) -> None:
    comp = compiled(EXAMPLES / "relay_blocking.rssm")
    rt = runtime(comp)
    rt.tracer = TraceWriter(tmp_path / "t.jsonl")
    first = Simulator(rt, SimOptions(seed=5, until=0.1)).run()
    rt.tracer.close()
    cx = load_counterexample(tmp_path / "t.jsonl")
    rt2 = runtime(comp)
    forced, _ = resolve_steps(rt2.net, cx.sequence(), "trace")
    second = Simulator(rt2, SimOptions(forced=forced)).run()
    assert second.reason == "replayed" and second.steps == first.steps
    assert second.forced == 0                        # every condition held, as recorded
    assert bits(to_mask(frozenset(rt2.net.place(n).index for n in second.marking))) == bits(
        to_mask(frozenset(rt.net.place(n).index for n in first.marking)))
    assert {s: x.vars for s, x in rt.subsystems.items()} == \
        {s: x.vars for s, x in rt2.subsystems.items()}


@pytest.mark.parametrize(("spec", "stuck"), [
    (SPECS / "starve.rssm", {"a1.c"}),
    (EXAMPLES / "handover_stall.rssm", {"giver.c", "taker.c"}),
    (EXAMPLES / "relay_blocking.rssm", set()),
])
def test_the_simulator_stalls_where_the_verifier_loses_progress(spec: Path,
                                                                 stuck: set[str]) -> None:
    """The subsystems a seeded run reports stalled (E809) are those whose progress the
    verifier finds lost, and a spec without such a loss runs to its bound."""
    comp = compiled(spec)
    assert comp.hpn is not None
    report = verify(flatten(comp.hpn))
    assert {p.subsystem for p in report.progress} == stuck
    result = Simulator(runtime(comp), SimOptions(until=20.0)).run()
    if stuck:
        assert result.reason == "stalled"
        assert {b.owner for b in result.blocked} == stuck
    else:
        assert result.reason in ("until", "finished"), result.message
