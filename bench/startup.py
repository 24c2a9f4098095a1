"""CLI start-up: wall time of `rssmc check` on the LWR4+ example and of
`rssmc --version`, against the bare interpreter start in the same invocation (the machine is
shared and noisy: medians of several runs, and the ratio to the baseline). The commands run
with bytecode caching on, as an installed package has it (this machine sets
PYTHONDONTWRITEBYTECODE, which would time the compilation of every module at every start).

    python bench/startup.py [--runs 9]
"""

from __future__ import annotations

import argparse
import os
import statistics
import subprocess
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
RSSMC = [sys.executable, "-m", "rssm_dsl"]
ENV = {k: v for k, v in os.environ.items() if k != "PYTHONDONTWRITEBYTECODE"}


def wall(cmd: list[str], runs: int) -> float:
    times = []
    for _ in range(runs):
        start = time.perf_counter()
        subprocess.run(cmd, cwd=ROOT, env=ENV, check=False, stdout=subprocess.DEVNULL,
                       stderr=subprocess.DEVNULL)
        times.append(time.perf_counter() - start)
    return statistics.median(times)


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--runs", type=int, default=9)
    args = ap.parse_args()
    wall([*RSSMC, "--version"], 1)          # warm the file cache and lark's grammar cache
    wall([*RSSMC, "check", "examples/lwr4_circle.rssm"], 1)
    base = wall([sys.executable, "-c", "pass"], args.runs)
    print(f"{'command':<44} {'median ms':>10} {'minus python ms':>16}")
    print(f"{'python -c pass':<44} {base * 1000:>10.0f} {0:>16.0f}")
    for label, cmd in (("rssmc --version", ["--version"]),
                       ("rssmc check examples/lwr4_circle.rssm",
                        ["check", "examples/lwr4_circle.rssm"])):
        t = wall([*RSSMC, *cmd], args.runs)
        print(f"{label:<44} {t * 1000:>10.0f} {(t - base) * 1000:>16.0f}")


if __name__ == "__main__":
    main()
