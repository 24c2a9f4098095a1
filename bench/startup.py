"""CLI start-up: wall time of `rssmc check` on the LWR4+ example and of
`rssmc --version`, against the bare interpreter start in the same invocation (the machine is
shared and noisy: the runs of the three commands alternate, and each gets the median and the
fastest of its runs). The commands run as users run them, the `rssmc` script of the
interpreter's environment (`python -m rssm_dsl` where there is none), with bytecode caching
on, as an installed package has it (this machine sets PYTHONDONTWRITEBYTECODE, which would
time the compilation of every module at every start). Issue 16's goal is `rssmc check` under
150 ms on the CI machine, measured in a venv of the core install (`pip install .`: the
extras' .pth files, Pinocchio's among them, slow every start); `.ci/run` prints it so.

    python bench/startup.py [--runs 15]
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
SCRIPT = Path(sys.executable).with_name("rssmc")
RSSMC = [str(SCRIPT)] if SCRIPT.exists() else [sys.executable, "-m", "rssm_dsl"]
ENV = {k: v for k, v in os.environ.items() if k != "PYTHONDONTWRITEBYTECODE"}


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--runs", type=int, default=15)
    args = ap.parse_args()
    commands = {
        "python -c pass": [sys.executable, "-c", "pass"],
        "rssmc --version": [*RSSMC, "--version"],
        "rssmc check examples/lwr4_circle.rssm": [*RSSMC, "check", "examples/lwr4_circle.rssm"],
    }
    for cmd in commands.values():       # warm the file cache and lark's grammar cache
        run(cmd)
    times: dict[str, list[float]] = {label: [] for label in commands}
    for _ in range(args.runs):
        for label, cmd in commands.items():
            times[label].append(run(cmd))
    base = statistics.median(times["python -c pass"])
    print(f"rssmc as {' '.join(RSSMC)}")
    print(f"{'command':<40} {'median ms':>10} {'fastest ms':>11} {'median - python ms':>19}")
    for label, ts in times.items():
        t = statistics.median(ts)
        print(f"{label:<40} {t * 1000:>10.0f} {min(ts) * 1000:>11.0f} {(t - base) * 1000:>19.0f}")


def run(cmd: list[str]) -> float:
    start = time.perf_counter()
    subprocess.run(cmd, cwd=ROOT, env=ENV, check=False, stdout=subprocess.DEVNULL,
                   stderr=subprocess.DEVNULL)
    return time.perf_counter() - start


if __name__ == "__main__":
    main()
