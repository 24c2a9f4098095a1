"""The LWR4+ experiment's figures, measured in one run on this machine.

1. Speed: the HPN-driven run (what ``rssmc run examples/lwr4_circle.rssm`` runs: the
   interpreter executing the specification's net, c at 100 Hz, e at 1 kHz, the MuJoCo LWR4+
   device, the run's recorder sampling every device step) against a hand-written Python loop
   doing the same control on the same model (bench/lwr4_handloop.py: MuJoCo steps, Pinocchio's
   gravity and Jacobian, the same impedance law, gains and damping form) for the same
   trajectory (the example's: two 10 cm circles of 2.0 s at a constant rate, clockwise then
   counter-clockwise) and the same simulated duration. Both as µs per 1 kHz step and real-time
   factor, and their ratio. Goals (issue 19, item 5): the HPN-driven run at least 10x faster
   than real time (on the CI machine, which is slower than a typical workstation) and the
   interpreter's overhead, the ratio of the HPN-driven run's time per step to the hand loop's,
   at most 1.3x. The two figures the goals are about are printed last, as ratios.
2. Tracking: RMS and maximum Cartesian error of both, with the specification's
   velocity-error damping and the paper's damping (-D dP/dt). Goal: RMS under 1 mm.

Times are CPU time of this process (``time.process_time``): the machine is shared, and wall
time also counts the time other processes hold the cores (the wall figures are printed too).
The runs alternate (an HPN run, then a hand loop) and the speed figures are the medians over
``--repeat`` pairs (15 by default: on a shared machine the median of five pairs' ratios moved
by 0.1 between invocations); the ratio is the median of the pairs' ratios. The ratio of the
fastest HPN run to the fastest hand loop is printed too (the least disturbed run of each).

    python bench/lwr4.py [--repeat 15] [--json out.json]
"""

from __future__ import annotations

import argparse
import json
import statistics
import sys
import time
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parent.parent
if str(ROOT) not in sys.path:
    sys.path.insert(0, str(ROOT))

from bench.lwr4_handloop import LoopConfig, run_hand_loop  # noqa: E402
from rssm_dsl.pipeline import Compilation, compile_file  # noqa: E402
from rssm_dsl.run import Experiment, RunOptions, run_experiment  # noqa: E402

EXAMPLE = ROOT / "examples" / "lwr4_circle.rssm"
RTF_GOAL = 10.0          # x real time, at least
OVERHEAD_GOAL = 1.3      # x the hand loop's time per step, at most


def hpn_run(comp: Compilation, damping: str) -> Experiment:
    return run_experiment(comp, RunOptions(damping=damping))


def hand_loop(exp: Experiment, damp_velocity_error: bool) -> dict[str, Any]:
    """The hand loop with the experiment's gains, trajectory and duration."""
    params = exp.params
    cfg = LoopConfig(stiffness=float(params["stiffness"]), damping=float(params["damping"]),
                     radius=0.05, period=2.0, profile="constant")
    wall0 = time.perf_counter()
    r = run_hand_loop(duration_s=exp.device_steps * 1e-3,
                      damp_velocity_error=damp_velocity_error, config=cfg,
                      clock=time.process_time)
    wall = time.perf_counter() - wall0
    return {"cpu_us_per_step": r["us_per_step"], "cpu_rtf": r["real_time_factor"],
            "wall_s": wall, "steps": r["steps"], "rms_m": r["rms_error_m"],
            "max_m": r["max_error_m"]}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--repeat", type=int, default=15, help="pairs of runs (default 15)")
    ap.add_argument("--json", type=Path, help="also write the figures as JSON")
    args = ap.parse_args()

    comp = compile_file(EXAMPLE)
    assert comp.ok, "the example does not compile"
    hpn_run(comp, "velocity-error")          # warm up: imports, models, compiled firing code

    pairs: list[tuple[Experiment, dict[str, Any]]] = []
    for _ in range(max(1, args.repeat)):
        exp = hpn_run(comp, "velocity-error")
        pairs.append((exp, hand_loop(exp, True)))
    exp, hand = pairs[-1]
    hpn_us = statistics.median(e.cpu / e.device_steps * 1e6 for e, _ in pairs)
    hpn_rtf = statistics.median(e.cpu_real_time_factor for e, _ in pairs)
    hpn_wall = statistics.median(e.real_time_factor for e, _ in pairs)
    hand_us = statistics.median(h["cpu_us_per_step"] for _, h in pairs)
    hand_rtf = statistics.median(h["cpu_rtf"] for _, h in pairs)
    ratio = statistics.median((e.cpu / e.device_steps * 1e6) / h["cpu_us_per_step"]
                              for e, h in pairs)
    hpn_best = min(e.cpu / e.device_steps * 1e6 for e, _ in pairs)
    hand_best = min(h["cpu_us_per_step"] for _, h in pairs)
    best_ratio = hpn_best / hand_best

    paper = hpn_run(comp, "paper")
    paper_hand = hand_loop(paper, False)

    print(f"LWR4+ experiment ({EXAMPLE.relative_to(ROOT)}): {exp.device_steps} steps of 1 ms "
          f"({exp.simulated:.3f} s simulated), K = {exp.params['stiffness']:g} N/m, "
          f"D = {exp.params['damping']:g} N·s/m; medians of {len(pairs)} pairs, CPU time")
    print(f"  HPN-driven run   {hpn_us:7.1f} µs/step  {hpn_rtf:6.1f}x real time "
          f"(wall: {hpn_wall:.1f}x)  {exp.firings / exp.device_steps:.1f} firings/step")
    print(f"  hand loop        {hand_us:7.1f} µs/step  {hand_rtf:6.1f}x real time")
    print("tracking error on the 10 cm circle (RMS / max):")
    rows = (("HPN, velocity-error damping", exp.metrics.rms_error, exp.metrics.max_error),
            ("hand, velocity-error damping", hand["rms_m"], hand["max_m"]),
            ("HPN, paper's damping", paper.metrics.rms_error, paper.metrics.max_error),
            ("hand, paper's damping", paper_hand["rms_m"], paper_hand["max_m"]))
    for label, rms, mx in rows:
        print(f"  {label:30s} {rms * 1e3:6.3f} mm / {mx * 1e3:6.3f} mm")
    print(f"  goal RMS < 1 mm (HPN, velocity-error): "
          f"{'met' if exp.metrics.rms_error < 1e-3 else 'NOT met'}")
    print("speed, as ratios (medians, CPU time, this machine):")
    print(f"  real-time factor of the HPN-driven run   {hpn_rtf:6.1f}x   goal >= {RTF_GOAL:g}x: "
          f"{'met' if hpn_rtf >= RTF_GOAL else 'NOT met'}")
    print(f"  overhead: HPN-driven run / hand loop      {ratio:6.2f}x   goal <= {OVERHEAD_GOAL:g}x: "
          f"{'met' if ratio <= OVERHEAD_GOAL else 'NOT met'}")
    print(f"  overhead, fastest runs ({hpn_best:.1f} / {hand_best:.1f} µs) {best_ratio:6.2f}x")
    if args.json is not None:
        args.json.write_text(json.dumps({
            "steps": exp.device_steps, "pairs": len(pairs),
            "hpn": {"cpu_us_per_step": hpn_us, "cpu_rtf": hpn_rtf, "wall_rtf": hpn_wall,
                    "firings_per_step": exp.firings / exp.device_steps},
            "hand": {"cpu_us_per_step": hand_us, "cpu_rtf": hand_rtf},
            "ratio": ratio, "ratio_fastest": best_ratio,
            "goals": {"real_time_factor_min": RTF_GOAL, "overhead_max": OVERHEAD_GOAL},
            "tracking_m": {label: {"rms": rms, "max": mx} for label, rms, mx in rows},
        }, indent=2) + "\n", encoding="utf-8")


if __name__ == "__main__":
    main()
