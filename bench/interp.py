"""Interpreter figures (issue 4), measured in one run on this machine.

1. Transition firings per second of the pure token game (conditions as free choices, no
   operations, no time: the verifier's abstraction), on the LWR4+ example and on a generated
   10-agent system (rssm_dsl.synth.ring_system(10)). Goal: >= 200,000 firings/s.
2. Firings per second of the full semantics (deterministic mode: operations, conditions,
   devices, simulated clock) on the same two systems.
3. Overhead of the HPN semantics: the LWR4+ system run by the interpreter (scripted constant
   device holding the arm at its start pose), per iteration of the virtual effector's
   behaviour, against the same operations called directly in a Python loop (the same number
   of impedance and circle_setpoint calls, device steps and measurements). Goal: under 3x.
   Measured as pairs (an interpreter run, then the direct loop with the same operations);
   the figure is the median of the pairs' ratios, robust to the load changing between pairs.

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
from pathlib import Path
from typing import Any

import numpy as np

from rssm_dsl.bindings import resolve
from rssm_dsl.hpn.flatten import flatten
from rssm_dsl.interp import RunConfig, SimOptions, Simulator, build_runtime
from rssm_dsl.interp.device import DeviceSpec
from rssm_dsl.interp.engine import TokenGame
from rssm_dsl.pipeline import Compilation, compile_file
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


def lwr4_config() -> RunConfig:
    return RunConfig(base_dir=LWR4.parent, devices={"a1.E.lwr": CONSTANT},
                     device_options={"a1.E.lwr": {"values": json.dumps({"state": STATE})}})


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


class Counting:
    """Counts the calls of a bound operation (patched into its module for the run)."""

    def __init__(self, fn: Callable[..., Any]) -> None:
        self.fn = fn
        self.calls = 0

    def __call__(self, *args: Any) -> Any:
        self.calls += 1
        return self.fn(*args)


def interpreted(comp: Compilation, seconds: float) -> tuple[float, int, int, int, int]:
    """Wall seconds of an interpreted LWR4+ run, effector iterations, impedance calls,
    circle_setpoint calls, device steps."""
    import rssm_stdlib.lwr4plus.ops as ops  # type: ignore[import-not-found]

    imp, circ = Counting(ops.impedance), Counting(ops.circle_setpoint)
    saved = ops.impedance, ops.circle_setpoint
    ops.impedance, ops.circle_setpoint = imp, circ
    try:
        rt = build_runtime(comp, lwr4_config())
    finally:
        ops.impedance, ops.circle_setpoint = saved
    sim = Simulator(rt, SimOptions(seed=1, until=seconds))
    t0 = clock()
    result = sim.run()
    dt = clock() - t0
    assert result.reason == "until", result.message
    return (dt, rt.subsystems["a1.e.lwr"].i, imp.calls, circ.calls,
            rt.devices["a1.E.lwr"].steps)


def direct(iterations: int, imp_calls: int, circ_calls: int, device_steps: int) -> float:
    """The same operations in a plain loop: wall seconds."""
    impedance = resolve("rssm_stdlib.lwr4plus.ops:impedance", None)
    circle = resolve("rssm_stdlib.lwr4plus.ops:circle_setpoint", None)
    constant = resolve(CONSTANT, None)
    assert callable(impedance) and callable(circle) and callable(constant)
    from rssm_dsl.semantics.types import FLOAT, ArrayT, RecordT

    vec3, vec7 = ArrayT(FLOAT, 3), ArrayT(FLOAT, 7)
    lwr_state = RecordT("LwrState", (("q", vec7), ("dq", vec7), ("position", vec3),
                                     ("velocity", vec3)))
    spec = DeviceSpec("a1.E.lwr", "lwr", "LWR4Plus", "effector", 1000.0,
                      {"torque": vec7}, {"state": lwr_state},
                      {"torque": np.zeros(7), "state": STATE},
                      options={"values": json.dumps({"state": STATE})})
    device = constant(spec)
    state = device.measure()["state"]
    setpoint = circle(0.05, 2.0, 0.0, -1.0)
    phase = 0.0
    n = max(iterations, imp_calls, circ_calls, device_steps)
    t0 = clock()
    for k in range(n):
        if k < device_steps:
            device.step(0.001)
            state = device.measure()["state"]
        if k < circ_calls:
            setpoint = circle(0.05, 2.0, phase, -1.0)
            phase += 0.01 * 2.0 * math.pi / 2.0
        if k < imp_calls:
            impedance(state, setpoint, 2000.0, 100.0)
    return clock() - t0


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
    for name, comp, config in (("LWR4+ example", lwr4, lwr4_config()),
                               ("10-agent ring", ring, ring_config(ring))):
        runs = [full_run(comp, config, args.seconds) for _ in range(args.repeat)]
        per, steps, counts = min(runs, key=lambda r: r[0])
        total = sum(counts.values())
        print(f"  {name:<14} {1 / per:>12,.0f} firings/s  ({steps:,} firings, {total:,} "
              f"subsystem iterations in {args.seconds:g} simulated s)")

    print("overhead: LWR4+ virtual effector iteration, interpreter vs direct calls")
    pairs: list[tuple[float, float]] = []
    for _ in range(args.pairs):
        dt, iters, imp, circ, dev = interpreted(lwr4, args.pair_seconds)
        dd = direct(iters, imp, circ, dev)
        pairs.append((dt / iters, dd / iters))
    ratios = sorted(a / b for a, b in pairs)
    median = statistics.median(ratios)
    interp_us = statistics.median(a for a, _ in pairs) * 1e6
    direct_us = statistics.median(b for _, b in pairs) * 1e6
    print(f"  {args.pairs} pairs of runs of {iters} effector iterations ({imp} impedance, "
          f"{circ} circle_setpoint calls, {dev} device steps each)")
    print(f"  interpreter {interp_us:8.1f} us per effector iteration (median; the whole system: "
          "effector, control subsystem, device)")
    print(f"  direct      {direct_us:8.1f} us per iteration (median; the same operations in a "
          "loop)")
    print(f"  ratio       {median:8.2f}x (median of the pairs' ratios; range "
          f"{ratios[0]:.2f}-{ratios[-1]:.2f})   (goal < 3x: "
          f"{'met' if median < 3 else 'NOT met'})")


if __name__ == "__main__":
    main()
