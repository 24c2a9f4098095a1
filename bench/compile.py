"""Compile-time figures (issue 2): generated systems of 1, 10, 100 and 1000 agents.

Prints lines of specification, the time of each phase (load+parse, check, IR) as the best
of a few runs, time per 1000 lines (linear growth keeps it flat), and peak memory (traced
in a separate run). Goal: a 100-agent system (about 10,000 lines) compiles in under 1 s.

    python bench/compile.py [--sizes 1,10,100,1000] [--repeat 3]
"""

from __future__ import annotations

import argparse
import tempfile
import time
import tracemalloc
from pathlib import Path

from rssm_dsl.diagnostics import DiagnosticBag
from rssm_dsl.hpn.build import build_hpn
from rssm_dsl.pipeline import _no_gc
from rssm_dsl.semantics.analyze import analyze
from rssm_dsl.semantics.loader import Loader
from rssm_dsl.source import Span
from rssm_dsl.synth import ring_system


def phases(path: Path) -> tuple[float, float, float]:
    with _no_gc():
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


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--sizes", default="1,10,100,1000")
    ap.add_argument("--repeat", type=int, default=3)
    args = ap.parse_args()
    sizes = [int(s) for s in args.sizes.split(",")]
    phases(Path(__file__).resolve().parent.parent / "examples" / "lwr4_circle.rssm")  # warm up
    print(f"{'agents':>7} {'lines':>8} {'parse s':>8} {'check s':>8} {'IR s':>7} {'total s':>8}"
          f" {'s/1k lines':>10} {'peak MB':>8}")
    with tempfile.TemporaryDirectory() as tmp:
        for n in sizes:
            path = Path(tmp) / f"ring{n}.rssm"
            text = ring_system(n)
            path.write_text(text)
            lines = text.count("\n")
            best = min((phases(path) for _ in range(args.repeat)), key=sum)
            total = sum(best)
            mem = peak_memory(path)
            print(f"{n:>7} {lines:>8} {best[0]:>8.3f} {best[1]:>8.3f} {best[2]:>7.3f} "
                  f"{total:>8.3f} {1000 * total / lines:>10.4f} {mem:>8.1f}")


if __name__ == "__main__":
    main()
