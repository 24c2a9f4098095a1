"""Compile-time figures and export figures, on generated ring systems
(rssm_dsl.synth.ring_system: about 100 lines of specification per agent).

Compile: lines of specification, the time of each phase (load+parse, check, IR) as the best
of a few runs, time per 1000 lines (linear growth keeps it flat), and peak memory (traced in
a separate run); then the growth of the time from the smallest size to the largest next to
the growth of the text. Goal: a 100-agent system (about 10,000 lines) compiles in under 1 s.
(bench/frontend_scale.py does the same for inputs large in one direction each: thousands of
small agents, of buffers, of switches, of case clauses.)

Exports: the size of the HPN (pages, places, transitions, arcs) and the time of the
exporters whose cost grows with the net: the flattened PNML (flattening included), the paged
PNML and the CPN Tools `.cpn` of the unflattened HPN, as `rssmc compile --emit` runs them
(cyclic collector on), best of a few runs; then milliseconds per agent (flat when linear) and
the growth from the smallest to the largest size next to the growth of the net. Goal: linear,
a 100-agent system exported in under 1 s. Before the IR index (`HPN.index`, rssm_dsl/hpn/ir.py)
the paged PNML and the CPN export scanned every table once per page: quadratic, 68 s and 65 s
at 100 agents.

Command: the wall time of the whole `rssmc compile FILE` (its default outputs: JSON IR, dump,
DOT, flat PNML, written to a folder), as a user runs it, on small agents (median of a few
runs), and the growth from the smallest size to the largest. Goal (issue 32, item 3): 5,000
small agents in under 5 s on two cores (the outputs are made on both, rssm_dsl/emit/outputs.py).

    python bench/compile.py [--sizes 1,10,100,1000] [--export-sizes 25,50,100] [--repeat 3]
    python bench/compile.py --small --sizes 500,5000 --export-sizes ''   (issue 32's agents;
        with --small the command table runs too: --command-sizes, 500,5000 by default)
"""

from __future__ import annotations

import argparse
import os
import statistics
import subprocess
import sys
import tempfile
import time
import tracemalloc
from collections.abc import Callable
from pathlib import Path

from rssm_dsl.diagnostics import DiagnosticBag
from rssm_dsl.emit.cpn import hpn_cpn
from rssm_dsl.emit.pnml import flat_pnml, paged_pnml
from rssm_dsl.gcpause import collector_paused
from rssm_dsl.hpn.build import build_hpn
from rssm_dsl.hpn.flatten import flatten
from rssm_dsl.hpn.ir import HPN
from rssm_dsl.pipeline import compile_file
from rssm_dsl.semantics.analyze import analyze
from rssm_dsl.semantics.loader import Loader
from rssm_dsl.source import Span
from rssm_dsl.synth import ring_system, small_agents_system

EXPORTS: dict[str, Callable[[HPN], str]] = {
    "pnml": lambda hpn: flat_pnml(flatten(hpn)),
    "pnml-paged": paged_pnml,
    "cpn": hpn_cpn,
}


def phases(path: Path) -> tuple[float, float, float]:
    with collector_paused():
        return _phases(path)


def _phases(path: Path) -> tuple[float, float, float]:
    bag = DiagnosticBag()
    t0 = time.perf_counter()
    program = Loader(bag).load_root(path, Span(str(path), 1, 1, 1, 1))
    t1 = time.perf_counter()
    system = analyze(program, bag)
    t2 = time.perf_counter()
    assert system is not None and not bag.has_errors, bag.sorted()[:3]
    build_hpn(system)
    t3 = time.perf_counter()
    return t1 - t0, t2 - t1, t3 - t2


def peak_memory(path: Path) -> float:
    tracemalloc.start()
    phases(path)
    _, peak = tracemalloc.get_traced_memory()
    tracemalloc.stop()
    return peak / 1e6


def compile_table(sizes: list[int], repeat: int, tmp: Path, small: bool = False) -> None:
    phases(Path(__file__).resolve().parent.parent / "examples" / "lwr4_circle.rssm")  # warm up
    print(f"{'agents':>7} {'lines':>8} {'parse s':>8} {'check s':>8} {'IR s':>7} {'total s':>8}"
          f" {'s/1k lines':>10} {'peak MB':>8}")
    rows: list[tuple[int, int, float]] = []
    for n in sizes:
        path = tmp / f"ring{n}.rssm"
        text = small_agents_system(n) if small else ring_system(n)
        path.write_text(text)
        lines = text.count("\n")
        best = min((phases(path) for _ in range(repeat)), key=sum)
        total = sum(best)
        rows.append((n, lines, total))
        mem = peak_memory(path)
        print(f"{n:>7} {lines:>8} {best[0]:>8.3f} {best[1]:>8.3f} {best[2]:>7.3f} "
              f"{total:>8.3f} {1000 * total / lines:>10.4f} {mem:>8.1f}", flush=True)
    if len(rows) > 1:
        (n0, l0, t0), (n1, l1, t1) = rows[0], rows[-1]
        print(f"growth {n0} -> {n1} agents: lines x{l1 / l0:.2f}, compile x{t1 / t0:.2f} "
              "(linear: the same)")


def export_times(hpn: HPN, repeat: int) -> dict[str, float]:
    out: dict[str, float] = {}
    for name, export in EXPORTS.items():
        best = float("inf")
        for _ in range(repeat):
            t0 = time.perf_counter()
            export(hpn)
            best = min(best, time.perf_counter() - t0)
        out[name] = best
    return out


def export_table(sizes: list[int], repeat: int, tmp: Path) -> None:
    print()
    names = list(EXPORTS)
    print(f"{'agents':>7} {'pages':>7} {'places':>7} {'trans':>7} {'arcs':>7} "
          + " ".join(f"{n + ' s':>12}" for n in names) + "  "
          + " ".join(f"{n + ' ms/agent':>20}" for n in names))
    rows: list[tuple[int, int, dict[str, float]]] = []
    for n in sizes:
        path = tmp / f"ring{n}.rssm"
        path.write_text(ring_system(n))
        hpn = compile_file(path).hpn
        assert hpn is not None
        size = len(hpn.pages) + len(hpn.places) + len(hpn.transitions) + len(hpn.arcs)
        times = export_times(hpn, repeat)
        rows.append((n, size, times))
        print(f"{n:>7} {len(hpn.pages):>7} {len(hpn.places):>7} {len(hpn.transitions):>7} "
              f"{len(hpn.arcs):>7} " + " ".join(f"{times[k]:>12.3f}" for k in names) + "  "
              + " ".join(f"{1000 * times[k] / n:>20.2f}" for k in names), flush=True)
    if len(rows) > 1:
        (n0, s0, t0), (n1, s1, t1) = rows[0], rows[-1]
        print(f"growth {n0} -> {n1} agents: net x{s1 / s0:.2f} (linear export: the same); "
              + ", ".join(f"{k} x{t1[k] / t0[k]:.2f}" for k in names))


def command_time(path: Path, out: Path) -> float:
    """The wall time of one `rssmc compile` run (a fresh process, as a user runs it)."""
    env = {**os.environ, "PYTHONPATH": str(Path(__file__).resolve().parent.parent)}
    t0 = time.perf_counter()
    subprocess.run([sys.executable, "-m", "rssm_dsl", "compile", str(path), "-o", str(out),
                    "-q"], check=True, env=env)
    return time.perf_counter() - t0


def command_table(sizes: list[int], repeat: int, tmp: Path) -> None:
    print()
    print(f"{'agents':>7} {'rssmc compile s':>16} {'MB written':>11}")
    rows: list[tuple[int, float]] = []
    for n in sizes:
        path = tmp / f"small{n}.rssm"
        path.write_text(small_agents_system(n))
        out = tmp / f"out{n}"
        wall = statistics.median(command_time(path, out) for _ in range(repeat))
        size = sum(f.stat().st_size for f in out.rglob("*") if f.is_file()) / 1e6
        rows.append((n, wall))
        print(f"{n:>7} {wall:>16.2f} {size:>11.1f}", flush=True)
    if len(rows) > 1:
        (n0, t0), (n1, t1) = rows[0], rows[-1]
        print(f"growth {n0} -> {n1} agents: agents x{n1 / n0:.0f}, rssmc compile x{t1 / t0:.2f}")


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--sizes", default="1,10,100,1000", help="agents, compile table ('' skips)")
    ap.add_argument("--export-sizes", default="25,50,100", help="agents, export table ('' skips)")
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--small", action="store_true",
                    help="compile table of small agents (rssm_dsl.synth.small_agents_system, "
                    "about 13 lines each: 5,000 agents are 1.4 MB) instead of ring systems")
    ap.add_argument("--command-sizes", default=None,
                    help="small agents, `rssmc compile` wall-time table ('' skips; default "
                    "500,5000 with --small, else skipped)")
    args = ap.parse_args()
    sizes = [int(s) for s in args.sizes.split(",") if s]
    command = args.command_sizes if args.command_sizes is not None else \
        ("500,5000" if args.small else "")
    command_sizes = [int(s) for s in command.split(",") if s]
    export_sizes = [int(s) for s in args.export_sizes.split(",") if s]
    with tempfile.TemporaryDirectory() as tmp:
        if sizes:
            compile_table(sizes, args.repeat, Path(tmp), args.small)
        if export_sizes:
            export_table(export_sizes, args.repeat, Path(tmp))
        if command_sizes:
            command_table(command_sizes, args.repeat, Path(tmp))


if __name__ == "__main__":
    main()
