"""The front end (`rssmc check`, `rssmc compile`) on inputs large in one direction each, to
show it linear in the input (issue 32, item 3). The families (rssm_dsl.synth):

- agents:   N small agents in a ring (one control subsystem, one behaviour, a channel to the
            next agent; about 220 bytes each: 5,000 agents are 1.1 MB);
- buffers:  N channels between two subsystems of one agent (half paired by name, half
            naming the buffer on the other side);
- switches: one behaviour left by N switches that may all hold at once (W604);
- cases:    one `update` with N case clauses, each with an error (E506, E503, E502).

For each size: the bytes of the input, then the CPU time of each phase as `rssmc` runs it
(CPU time, not wall time: the figures hold on a machine that runs other work too), best of
--repeat runs with the cyclic collector paused as the commands pause it: parse (load
and parse), check (the semantic analysis), report (the diagnostics sorted and rendered as
text, as `rssmc check` prints them), IR (the HPN, for valid inputs), emit (the outputs
`rssmc compile` writes by default: json, dump, dot, pnml; in memory); `check` is parse +
check + report, `compile` is that + IR + emit. Then the number of diagnostics and the peak
of traced memory (tracemalloc, in a separate run) of the whole compile, in MB and in MB per
MB of input. Last, per family, the growth of each total from the smallest size to the
largest next to the growth of the input (linear: the same).

    python bench/frontend_scale.py [--families agents,buffers,switches,cases]
                                   [--sizes 500,5000] [--repeat 1] [--no-memory]

--sizes applies to every family chosen; by default each family has its own sizes
(agents 500,5000; buffers 300,3000; switches 80,800,2000; cases 300,3000).
"""

from __future__ import annotations

import argparse
import tempfile
import time
import tracemalloc
from collections.abc import Callable
from pathlib import Path

from rssm_dsl.diagnostics import DiagnosticBag
from rssm_dsl.diagnostics.render import render_text
from rssm_dsl.emit import EMITTERS
from rssm_dsl.gcpause import collector_paused
from rssm_dsl.hpn.build import build_hpn
from rssm_dsl.semantics.analyze import analyze
from rssm_dsl.semantics.loader import Loader
from rssm_dsl.source import Span
from rssm_dsl.synth import (
    erroneous_cases_system,
    many_buffers_system,
    overlapping_switches_system,
    small_agents_system,
)

FAMILIES: dict[str, tuple[Callable[[int], str], list[int]]] = {
    "agents": (small_agents_system, [500, 5000]),
    "buffers": (many_buffers_system, [300, 3000]),
    "switches": (overlapping_switches_system, [80, 800, 2000]),
    "cases": (erroneous_cases_system, [300, 3000]),
}
PHASES = ("parse", "check", "report", "IR", "emit")
EMIT = ("json", "dump", "dot", "pnml")


def phases(path: Path) -> tuple[dict[str, float], int]:
    """The time of each phase, and the number of diagnostics."""
    with collector_paused():
        out: dict[str, float] = dict.fromkeys(PHASES, 0.0)
        bag = DiagnosticBag()
        t0 = time.process_time()
        loader = Loader(bag)
        program = loader.load_root(path, Span(str(path), 1, 1, 1, 1))
        t1 = time.process_time()
        system = analyze(program, bag) if not bag.has_errors else None
        t2 = time.process_time()
        diags = bag.sorted()
        if diags:
            render_text(diags, program.line)
        t3 = time.process_time()
        out.update(parse=t1 - t0, check=t2 - t1, report=t3 - t2)
        if system is not None and not bag.has_errors:
            hpn = build_hpn(system)
            t4 = time.process_time()
            for kind in EMIT:
                EMITTERS[kind](hpn)
            t5 = time.process_time()
            out.update(IR=t4 - t3, emit=t5 - t4)
        return out, len(diags)


def peak_memory(path: Path) -> float:
    tracemalloc.start()
    try:
        phases(path)
        return tracemalloc.get_traced_memory()[1] / 1e6
    finally:
        tracemalloc.stop()


def family(name: str, sizes: list[int], repeat: int, memory: bool, tmp: Path) -> None:
    make = FAMILIES[name][0]
    print(f"\n{name}: {make.__name__}")
    print(f"{'N':>6} {'KB':>7} " + " ".join(f"{p + ' s':>8}" for p in PHASES)
          + f" {'check s':>8} {'compile s':>9} {'diags':>7}"
          + (f" {'peak MB':>8} {'MB/MB':>6}" if memory else ""))
    rows: list[tuple[int, float, float]] = []
    for n in sizes:
        path = tmp / f"{name}{n}.rssm"
        text = make(n)
        path.write_text(text, encoding="utf-8")
        size = len(text.encode()) / 1e6
        runs = [phases(path) for _ in range(repeat)]
        best, diags = min(runs, key=lambda r: sum(r[0].values()))
        check = best["parse"] + best["check"] + best["report"]
        total = sum(best.values())
        rows.append((n, check, total))
        line = (f"{n:>6} {1000 * size:>7.0f} " + " ".join(f"{best[p]:>8.3f}" for p in PHASES)
                + f" {check:>8.3f} {total:>9.3f} {diags:>7}")
        if memory:
            peak = peak_memory(path)
            line += f" {peak:>8.1f} {peak / size:>6.0f}"
        print(line, flush=True)
    if len(rows) > 1:
        (n0, c0, t0), (n1, c1, t1) = rows[0], rows[-1]
        print(f"growth {n0} -> {n1}: input x{n1 / n0:.1f}; check x{c1 / c0:.1f}, "
              f"compile x{t1 / t0:.1f} (linear: about x{n1 / n0:.1f})")


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--families", default=",".join(FAMILIES))
    ap.add_argument("--sizes", default="", help="N for every family (default: per family)")
    ap.add_argument("--repeat", type=int, default=1)
    ap.add_argument("--no-memory", action="store_true", help="skip the traced-memory run")
    args = ap.parse_args()
    sizes = [int(s) for s in args.sizes.split(",") if s]
    # warm up the imports and caches on a small input
    with tempfile.TemporaryDirectory() as tmp:
        warm = Path(tmp) / "warm.rssm"
        warm.write_text(small_agents_system(3), encoding="utf-8")
        phases(warm)
        for name in args.families.split(","):
            family(name, sizes or FAMILIES[name][1], args.repeat, not args.no_memory,
                   Path(tmp))


if __name__ == "__main__":
    main()
