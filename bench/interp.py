"""Interpreter figures, measured in one run on this machine.

1. Transition firings per second of the pure token game (conditions as free choices, no
   operations, no time: the verifier's abstraction), on the LWR4+ example and on a generated
   10-agent system (rssm_dsl.synth.ring_system(10)). Goal: >= 200,000 firings/s.
2. Firings per second of the full semantics (deterministic mode: operations, conditions,
   devices, simulated clock) on the same two systems.
3. Overhead of the HPN semantics: the LWR4+ system run by the interpreter (scripted constant
   device holding the arm at its start pose), per iteration of the virtual effector's
   behaviour, against the same work done by direct Python calls: every extern operation the
   run called, called directly as many times (with the arguments of its last call in the
   run), and as many device steps and measurements. The externs are those of the compiled
   specification, found through their bindings (none is named here), and the rig (effector,
   device) is the one `rssmc run` finds. Goal: under 3x. Measured as pairs (an interpreter
   run, then the direct calls of the same work); the figure is the median of the pairs'
   ratios, robust to the load changing between pairs. The calls are counted in a separate
   run, so the timed runs carry no counting wrapper.

The rates are the best of ``--repeat`` runs (the first run compiles the firing code of the
transitions it uses, the later ones reuse it, as a long run would).
Times are CPU time of this process (``time.process_time``): the machine is shared, and wall
time would also count the time other processes hold the cores.

    python bench/interp.py [--repeat 5] [--seconds 1.0]
"""

from __future__ import annotations

import argparse
import json
import math
import statistics
import tempfile
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from rssm_dsl.bindings import import_module, split_binding
from rssm_dsl.hpn.flatten import flatten
from rssm_dsl.interp import RunConfig, SimOptions, Simulator, build_runtime
from rssm_dsl.interp.engine import TokenGame
from rssm_dsl.pipeline import Compilation, compile_file
from rssm_dsl.run.rig import Rig, find_rig
from rssm_dsl.synth import ring_system

ROOT = Path(__file__).resolve().parent.parent
clock = time.process_time
LWR4 = ROOT / "examples" / "lwr4_circle.rssm"
CONSTANT = "rssm_stdlib.devices.constant:ConstantDevice"
ECHO = "rssm_stdlib.devices.echo:EchoDevice"
Q0 = [0.0, -0.6, 0.0, 1.4, 0.0, 0.6 + 1.4 - math.pi, 0.0]     # bench/lwr4_handloop.py
STATE = {"q": Q0, "dq": [0.0] * 7, "position": [0.58, 0.0, 0.4], "velocity": [0.0] * 3}


def token_game(comp: Compilation, steps: int) -> float:
    """Seconds per firing of the pure token game."""
    assert comp.hpn is not None
    game = TokenGame(flatten(comp.hpn))
    t0 = clock()
    n = game.run_free(steps, seed=1)
    return (clock() - t0) / n


def lwr4_config(rig: Rig) -> RunConfig:
    """The LWR4+ device replaced by a constant one holding the arm at its start pose."""
    return RunConfig(base_dir=LWR4.parent, devices={rig.device: CONSTANT},
                     device_options={rig.device: {"values": json.dumps({"state": STATE})}})


def ring_config(comp: Compilation) -> RunConfig:
    assert comp.system is not None
    return RunConfig(base_dir=ROOT, devices={d.id: ECHO for d in comp.system.devices()})


def full_run(comp: Compilation, config: RunConfig, seconds: float
             ) -> tuple[float, int, dict[str, int]]:
    """Seconds per firing of the full semantics; firings; iterations per subsystem."""
    rt = build_runtime(comp, config)
    sim = Simulator(rt, SimOptions(seed=1, until=seconds))
    t0 = clock()
    result = sim.run()
    dt = clock() - t0
    assert result.reason == "until", result.message
    return dt / result.steps, result.steps, {s.id: s.i for s in rt.subsystems.values()}


class Recording:
    """Counts the calls of an extern's Python function and keeps the last call's
    arguments (patched into its module for the counting run)."""

    def __init__(self, fn: Callable[..., Any]) -> None:
        self.fn = fn
        self.calls = 0
        self.args: tuple[Any, ...] = ()

    def __call__(self, *args: Any) -> Any:
        self.calls += 1
        self.args = args
        return self.fn(*args)


@dataclass
class Work:
    """What one interpreted run of the LWR4+ system did."""

    iterations: int                                   # of the virtual effector
    device_steps: int
    calls: dict[str, tuple[Callable[..., Any], tuple[Any, ...], int]]   # extern -> fn, args, n


def lwr4_rig(comp: Compilation) -> Rig:
    assert comp.system is not None
    rig = find_rig(comp.system)
    assert isinstance(rig, Rig), rig
    return rig


def count_work(comp: Compilation, seconds: float) -> Work:
    """Run the system once with every extern of the specification wrapped (resolved through
    its binding and patched where the binding points): what the run called, and how often."""
    assert comp.system is not None
    rig = lwr4_rig(comp)
    config = lwr4_config(rig)
    recorders: dict[str, Recording] = {}
    saved: list[tuple[object, str, object]] = []
    try:
        for ext in comp.system.externs:
            module_name, attr = split_binding(ext.binding)
            owner: object = import_module(module_name, config.base_dir)
            *path, last = attr.split(".")
            for part in path:
                owner = getattr(owner, part)
            fn = getattr(owner, last)
            recorders[ext.name] = Recording(fn)
            saved.append((owner, last, fn))
            setattr(owner, last, recorders[ext.name])
        rt = build_runtime(comp, config)
    finally:
        for owner, last, fn in reversed(saved):
            setattr(owner, last, fn)
    result = Simulator(rt, SimOptions(seed=1, until=seconds)).run()
    assert result.reason == "until", result.message
    calls = {name: (r.fn, r.args, r.calls) for name, r in recorders.items() if r.calls}
    assert calls, "the run called no extern operation: nothing to compare the interpreter with"
    return Work(rt.subsystems[rig.effector].i, rt.devices[rig.device].steps, calls)


def interpreted(comp: Compilation, seconds: float, work: Work) -> float:
    """CPU seconds of an interpreted LWR4+ run (no wrapper); it must redo ``work``."""
    rig = lwr4_rig(comp)
    rt = build_runtime(comp, lwr4_config(rig))
    sim = Simulator(rt, SimOptions(seed=1, until=seconds))
    t0 = clock()
    result = sim.run()
    dt = clock() - t0
    assert result.reason == "until", result.message
    assert rt.subsystems[rig.effector].i == work.iterations, "the run is not deterministic"
    return dt


def direct(comp: Compilation, work: Work) -> float:
    """The same work as direct Python calls: CPU seconds."""
    rig = lwr4_rig(comp)
    rt = build_runtime(comp, lwr4_config(rig))       # for a device built as the run builds it
    device = rt.devices[rig.device].impl
    frequency = next(d.frequency for d in rt.system.devices() if d.id == rig.device)
    dt = 1.0 / (frequency or 1000.0)
    t0 = clock()
    for _ in range(work.device_steps):
        device.step(dt)
        device.measure()
    for fn, args, n in work.calls.values():
        for _ in range(n):
            fn(*args)
    elapsed = clock() - t0
    rt.close_devices()
    return elapsed


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--repeat", type=int, default=5)
    ap.add_argument("--seconds", type=float, default=1.0, help="simulated seconds per run")
    ap.add_argument("--steps", type=int, default=300_000, help="firings of the token game")
    ap.add_argument("--pairs", type=int, default=15, help="interpreter/direct run pairs")
    ap.add_argument("--pair-seconds", type=float, default=0.25,
                    help="simulated seconds of each interpreter run of a pair")
    args = ap.parse_args()

    lwr4 = compile_file(LWR4)
    with tempfile.TemporaryDirectory() as tmp:
        ring_path = Path(tmp) / "ring10.rssm"
        ring_path.write_text(ring_system(10), encoding="utf-8")
        ring = compile_file(ring_path)
    assert lwr4.ok and ring.ok and lwr4.hpn is not None and ring.hpn is not None

    print("pure token game (free choice, no operations), best of", args.repeat)
    for name, comp in (("LWR4+ example", lwr4), ("10-agent ring", ring)):
        assert comp.hpn is not None
        net = flatten(comp.hpn)
        per = min(token_game(comp, args.steps) for _ in range(args.repeat))
        print(f"  {name:<14} {len(net.places):>5} places {len(net.transitions):>5} transitions"
              f"  {1 / per:>12,.0f} firings/s   (goal >= 200,000: "
              f"{'met' if 1 / per >= 200_000 else 'NOT met'})")

    print("full semantics (deterministic: operations, conditions, devices, clock)")
    for name, comp, config in (("LWR4+ example", lwr4, lwr4_config(lwr4_rig(lwr4))),
                               ("10-agent ring", ring, ring_config(ring))):
        runs = [full_run(comp, config, args.seconds) for _ in range(args.repeat)]
        per, steps, counts = min(runs, key=lambda r: r[0])
        total = sum(counts.values())
        print(f"  {name:<14} {1 / per:>12,.0f} firings/s  ({steps:,} firings, {total:,} "
              f"subsystem iterations in {args.seconds:g} simulated s)")

    print("overhead: LWR4+ virtual effector iteration, interpreter vs direct calls")
    work = count_work(lwr4, args.pair_seconds)
    pairs: list[tuple[float, float]] = []
    for _ in range(args.pairs):
        pairs.append((interpreted(lwr4, args.pair_seconds, work), direct(lwr4, work)))
    n = work.iterations
    ratios = sorted(a / b for a, b in pairs)
    median = statistics.median(ratios)
    interp_us = statistics.median(a for a, _ in pairs) / n * 1e6
    direct_us = statistics.median(b for _, b in pairs) / n * 1e6
    called = ", ".join(f"{calls:,} {name}" for name, (_, _, calls) in work.calls.items())
    print(f"  {args.pairs} pairs of runs of {n:,} effector iterations (extern calls: {called}; "
          f"{work.device_steps:,} device steps)")
    print(f"  interpreter {interp_us:8.1f} us per effector iteration (median; the whole system: "
          "effector, control subsystem, device)")
    print(f"  direct      {direct_us:8.1f} us per iteration (median; the same calls and device "
          "steps in plain loops)")
    print(f"  overhead    {median:8.2f}x (interpreter / direct: median of the pairs' ratios; "
          f"range {ratios[0]:.2f}-{ratios[-1]:.2f})   (goal < 3x: "
          f"{'met' if median < 3 else 'NOT met'})")


if __name__ == "__main__":
    main()
