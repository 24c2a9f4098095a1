"""Verification figures, measured in one run:

1. time to verdict of our full exploration vs SPIN's (C compile included) on the same nets of
   1e4 to 1e6 states: compiled specifications (the LWR4+ example) and generated ring
   pipelines (tests/verify/netkit.py), printed as a ratio;
2. the largest N for which an N-agent generated system (rssm_dsl.synth: control subsystem,
   two virtual effectors, their devices, control subsystems in a ring) is verified within
   60 s: a table for N = 1, 2, 4, 8, ... and 100 with the default options (progress check
   on: sliced, each blocking group by the cheapest method that decides it), our
   compositional check (also with the progress check on, which it decides too), our reduced
   search
   (stubborn sets), our full search and SPIN, each stopped at the time limit (times include
   the place invariants, capped at 5 s).

    python bench/verify.py [--limit 60] [--max-n 128] [--skip-spin] [--only-scale]
"""

from __future__ import annotations

import argparse
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT / "tests" / "verify"))

from netkit import pipeline_ring  # noqa: E402

from rssm_dsl.hpn.flat import FlatNet  # noqa: E402
from rssm_dsl.hpn.flatten import flatten  # noqa: E402
from rssm_dsl.pipeline import compile_file  # noqa: E402
from rssm_dsl.synth import lean_ring_system, ring_system  # noqa: E402
from rssm_dsl.verify import VerifyOptions, verify  # noqa: E402
from rssm_dsl.verify.promela import run_spin  # noqa: E402


def flat_of(text: str, name: str, tmp: Path) -> FlatNet:
    path = tmp / f"{name}.rssm"
    path.write_text(text)
    comp = compile_file(path)
    assert comp.ok and comp.hpn is not None, comp.diagnostics[:3]
    return flatten(comp.hpn)


def versus_spin(skip_spin: bool) -> None:
    print("1. time to verdict, full exploration: ours vs SPIN (compile + run)")
    print(f"   {'net':<22} {'states':>9} {'ours s':>8} {'verdict':>10} {'SPIN s':>8} "
          f"{'SPIN states':>11} {'SPIN/ours':>9}")
    nets: list[tuple[str, FlatNet]] = [
        ("lwr4_circle (spec)", flatten(compile_file(ROOT / "examples" / "lwr4_circle.rssm").hpn)),  # type: ignore[arg-type]
        ("pipeline_ring(6,BB)", pipeline_ring(6, "BB")),
        ("pipeline_ring(8,BB)", pipeline_ring(8, "BB")),
        ("pipeline_ring(10,BB)", pipeline_ring(10, "BB")),
    ]
    for name, net in nets:
        t = time.monotonic()
        report = verify(net, VerifyOptions(reduction="off", check_progress=False))
        ours = time.monotonic() - t
        if skip_spin:
            print(f"   {name:<22} {report.states:>9} {ours:>8.2f} {report.verdict.value:>10}")
            continue
        spin = run_spin(net, timeout=600)
        ratio = spin.total_seconds / ours if ours > 0 else float("nan")
        print(f"   {name:<22} {report.states:>9} {ours:>8.2f} {report.verdict.value:>10} "
              f"{spin.total_seconds:>8.2f} {spin.states_stored:>11} {ratio:>9.2f}", flush=True)


def scale(limit: float, max_n: int, skip_spin: bool) -> None:
    print(f"\n2. N-agent systems verified within {limit:.0f} s (deadlock and safeness; the "
          "progress check is off, except in the columns 'default' and 'with progress')")
    print(f"   {'system':<10} {'N':>4} {'places':>7} {'default, progress':>26} "
          f"{'compositional':>26} {'with progress':>26} "
          f"{'reduced':>22} {'full':>22} {'SPIN':>16}")
    with tempfile.TemporaryDirectory() as tmpdir:
        tmp = Path(tmpdir)
        for label, gen in (("lean ring", lean_ring_system), ("ring", ring_system)):
            alive = {"default": True, "compositional": True, "progress": True,
                     "reduced": True, "full": True, "spin": not skip_spin}
            # powers of two, and 100 agents (the scale the verifier aims at)
            sizes = sorted({2 ** i for i in range(max_n.bit_length()) if 2 ** i <= max_n}
                           | ({100} if max_n >= 100 else set()))
            for n in sizes:
                if not any(alive.values()):
                    break
                net = flat_of(gen(n), f"{label.replace(' ', '_')}{n}", tmp)
                cells: dict[str, str] = {}
                for method, reduction in (("default", "auto"),
                                          ("compositional", "compositional"),
                                          ("progress", "compositional"),
                                          ("reduced", "on"), ("full", "off")):
                    if not alive[method]:
                        cells[method] = "-"
                        continue
                    t = time.monotonic()
                    r = verify(net, VerifyOptions(reduction=reduction, time_limit=limit,
                                                  check_progress=method in ("default",
                                                                            "progress"),
                                                  invariants=True))
                    dt = time.monotonic() - t
                    ok = r.verdict.value != "inconclusive" and dt <= limit
                    alive[method] = ok
                    cells[method] = (f"{r.verdict.value[:8]} {r.states} st {dt:.1f}s" if ok
                                     else f"gave up ({r.states} st)")
                if alive["spin"]:
                    spin = run_spin(net, timeout=limit)
                    ok = spin.ran and spin.complete and spin.total_seconds <= limit
                    alive["spin"] = ok
                    cells["spin"] = (f"{spin.states_stored} st {spin.total_seconds:.1f}s" if ok
                                     else "gave up")
                else:
                    cells["spin"] = "-"
                print(f"   {label:<10} {n:>4} {len(net.places):>7} {cells['default']:>26} "
                      f"{cells['compositional']:>26} {cells['progress']:>26} "
                      f"{cells['reduced']:>22} {cells['full']:>22} {cells['spin']:>16}",
                      flush=True)


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--limit", type=float, default=60.0)
    ap.add_argument("--max-n", type=int, default=128)
    ap.add_argument("--skip-spin", action="store_true")
    ap.add_argument("--only-scale", action="store_true", help="skip part 1")
    args = ap.parse_args()
    if not args.only_scale:
        versus_spin(args.skip_spin)
    scale(args.limit, args.max_n, args.skip_spin)


if __name__ == "__main__":
    main()
