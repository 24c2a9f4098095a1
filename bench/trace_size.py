"""Bytes per simulated second of what a run records: the trace (JSON lines, one event per
firing and data move: grows with the firings) against the series file of `--series`
(rssm_core/series.py: the default selection, every behaviour and numeric memory variable,
one sample per iteration: grows with the series times their samples), for each example run
by `rssmc simulate` in the same invocation.

    python bench/trace_size.py [--until 10]
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import tempfile
from pathlib import Path

from rssm_core.series import read_series

ROOT = Path(__file__).resolve().parent.parent
SPECS = ["relay_blocking.rssm", "camera_tracker.rssm", "handover_stall.rssm"]


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--until", type=float, default=10.0)
    args = ap.parse_args()
    print(f"{'example':<24} {'trace B/s':>12} {'series B/s':>12} {'ratio':>8}  series")
    with tempfile.TemporaryDirectory() as tmp:
        for name in SPECS:
            trace, npz = Path(tmp) / f"{name}.jsonl", Path(tmp) / f"{name}.npz"
            run = subprocess.run(
                [sys.executable, "-m", "rssm_dsl", "simulate", str(ROOT / "examples" / name),
                 "--until", str(args.until), "--no-live", "-q", "-f", "json",
                 "--trace", str(trace), "--series", str(npz), "--stall-periods", "0"],
                capture_output=True, text=True, cwd=ROOT / "examples", check=False)
            if run.returncode not in (0, 3):
                print(f"{name}: simulate exited {run.returncode}: {run.stderr[-400:]}")
                continue
            seconds = float(json.loads(run.stdout)["time"]) or args.until
            n = len(read_series(npz)[1])
            t_rate, s_rate = trace.stat().st_size / seconds, npz.stat().st_size / seconds
            print(f"{name:<24} {t_rate:>12,.0f} {s_rate:>12,.0f} {t_rate / s_rate:>7.0f}x  {n}")


if __name__ == "__main__":
    main()
