"""Size and compile time of a coordinator + N robots (tests/hpn/fleet.py: the coordinator's
control subsystem has one input per robot), for N = 6, 12, 24, 64, with the data-availability
cases as the user wrote them (rssm_dsl/semantics/cases.py): its `update memory` has no case
clause (``plain``) or case clauses over new(s1) and new(s2) only (``cases``).

Prints per N the places and transitions of the HPN and of the flat net, the coordinator's data
cases, and the median compile time (parse, check, build the HPN) of --runs runs; then the
growth ratio of each count from N = 6 to N = 64 (64 / 6 = 10.7 for linear growth). The column
"full form" is the number of cases the paper's expansion would give the coordinator (2^N per
partial function: the compiler built that many before the rule, and refused N > 12, E504).

    python bench/cases.py [--runs 3]
"""

from __future__ import annotations

import argparse
import statistics
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

from rssm_dsl.hpn.flatten import flatten  # noqa: E402
from rssm_dsl.hpn.ir import CondKind  # noqa: E402
from rssm_dsl.pipeline import compile_file  # noqa: E402
from tests.hpn.fleet import fleet  # noqa: E402

SIZES = (6, 12, 24, 64)


def measure(path: Path, runs: int) -> tuple[tuple[int, int, int, int, int], float]:
    times = []
    for _ in range(runs):
        start = time.perf_counter()
        comp = compile_file(path)
        times.append(time.perf_counter() - start)
    assert comp.ok and comp.hpn is not None
    hpn = comp.hpn
    net = flatten(hpn)
    cases = sum(1 for t in hpn.transitions.values() if t.condition is not None
                and t.condition.kind is CondKind.CASE and t.condition.subsystem == "coord.c")
    return ((len(hpn.places), len(hpn.transitions), len(net.places), len(net.transitions),
             cases), statistics.median(times))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--runs", type=int, default=3)
    args = ap.parse_args()
    header = ("kind", "N", "HPN places", "HPN transitions", "flat places", "flat transitions",
              "coord cases", "full form", "compile s")
    print(" | ".join(header))
    with tempfile.TemporaryDirectory() as tmp:
        for cases in (False, True):
            kind = "cases" if cases else "plain"
            counts: dict[int, tuple[int, ...]] = {}
            for n in SIZES:
                path = Path(tmp) / f"fleet_{kind}_{n}.rssm"
                path.write_text(fleet(n, cases), encoding="utf-8")
                counts[n], seconds = measure(path, args.runs)
                print(" | ".join([kind, str(n), *(f"{x:,}" for x in counts[n]),
                                  f"2^{n}", f"{seconds:.2f}"]))
            ratios = [b / a for a, b in zip(counts[6][:4], counts[64][:4], strict=True)]
            print(f"{kind}: growth N=6 -> N=64 (linear: {64 / 6:.1f}): "
                  + ", ".join(f"{name} x{r:.1f}" for name, r in zip(header[2:6], ratios,
                                                                     strict=True)))


if __name__ == "__main__":
    main()
