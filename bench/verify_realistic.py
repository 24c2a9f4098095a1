"""What `rssmc verify` does on specifications written the way a robotics engineer writes them:
the four systems of examples/verify/ with an expected verdict in their header
(handover_buggy, handover, rover, palletizer; tests/verify/test_slicing.py pins the verdicts).

    python bench/verify_realistic.py [--limit 60] [--reduction auto] [--no-progress-check]
                                     [--mem-gb 8] [--only NAME]

Each spec is verified by the CLI (`rssmc verify --format json --timeout LIMIT`) in its own
process, under an address-space limit (--mem-gb) and killed if it runs 60 s past its limit,
one spec at a time. Per spec the table gives the verdict, the expected verdict (read from the
spec's header, "Expected verdict of `rssmc verify`: ..."), whether they agree, the wall time
to the verdict (compilation included), the states the verifier reports, the method, whether
a counterexample came with a firing sequence, the peak resident memory of the process and
what stopped it. It is a benchmark, not a test: it exits 0 whatever the verdicts.
"""

from __future__ import annotations

import argparse
import json
import os
import re
import resource
import subprocess
import sys
import tempfile
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parent.parent
SPECS = [ROOT / "examples" / "verify" / f"{name}.rssm"
         for name in ("handover_buggy", "handover", "rover", "palletizer", "lockstep")]
INTENDED = re.compile(r"Expected verdict of `rssmc verify`:\s*([A-Z]+)")
GRACE = 60.0        # seconds past --limit before the process is killed


@dataclass
class Row:
    spec: str
    intended: str
    verdict: str
    seconds: float
    states: str
    method: str
    trace: str
    peak_mb: float
    stopped: str


def intended_verdict(spec: Path) -> str:
    m = INTENDED.search(spec.read_text(encoding="utf-8"))
    return m.group(1) if m else "?"


def _limit_memory(mem_bytes: int) -> None:
    resource.setrlimit(resource.RLIMIT_AS, (mem_bytes, mem_bytes))


def run_cli(spec: Path, args: argparse.Namespace) -> tuple[dict[str, Any] | None, float, float, str]:
    """(the JSON report or None, wall seconds, peak resident MB, what went wrong if anything)."""
    cmd = [sys.executable, "-m", "rssm_dsl", "verify", str(spec), "--format", "json",
           "--timeout", str(args.limit), "--reduction", args.reduction]
    if args.no_progress_check:
        cmd.append("--no-progress-check")
    mem = int(args.mem_gb * 1e9)
    with tempfile.TemporaryFile() as out, tempfile.TemporaryFile() as err:
        start = time.monotonic()
        proc = subprocess.Popen(cmd, stdout=out, stderr=err, cwd=ROOT,
                                preexec_fn=lambda: _limit_memory(mem))
        killed = ""
        while True:
            pid, status, usage = os.wait4(proc.pid, os.WNOHANG)
            if pid:
                break
            if time.monotonic() - start > args.limit + GRACE:
                proc.kill()
                pid, status, usage = os.wait4(proc.pid, 0)
                killed = f"killed {GRACE:.0f} s after the limit"
                break
            time.sleep(0.1)
        wall = time.monotonic() - start
        proc.returncode = os.waitstatus_to_exitcode(status)
        peak_mb = usage.ru_maxrss / 1024          # kB on Linux
        out.seek(0)
        err.seek(0)
        text, errors = out.read().decode(), err.read().decode()
    if killed:
        return None, wall, peak_mb, killed
    try:
        return json.loads(text), wall, peak_mb, ""
    except json.JSONDecodeError:
        last = (errors.strip().splitlines() or text.strip().splitlines() or ["no output"])[-1]
        return None, wall, peak_mb, f"exit {proc.returncode}: {last[:80]}"


def trace_given(report: dict[str, Any]) -> str:
    """Which counterexamples came with a firing sequence (deadlock, unsafe, progress)."""
    kinds = []
    if any(d.get("steps") for d in report.get("deadlocks") or []):
        kinds.append("deadlock")
    if (report.get("unsafe") or {}).get("steps"):
        kinds.append("unsafe")
    lassos = [p for p in report.get("progress") or [] if p.get("steps") or p.get("cycle")]
    if lassos:
        kinds.append("progress lasso: " + ", ".join(str(p.get("subsystem")) for p in lassos))
    without = report.get("progress_lost_without_trace") or []
    if without:
        kinds.append("lost, no trace: " + ", ".join(map(str, without)))
    return "; ".join(kinds) if kinds else "no"


def measure(spec: Path, args: argparse.Namespace) -> Row:
    intended = intended_verdict(spec)
    report, wall, peak, problem = run_cli(spec, args)
    if report is None:
        return Row(spec.stem, intended, "ERROR", wall, "-", "-", "-", peak, problem)
    space = report.get("state_space") or {}
    states = f"{space.get('states', '?')}" + ("" if space.get("complete") else " (incomplete)")
    stopped = report.get("stopped_by")
    if isinstance(stopped, dict):
        stopped = stopped.get("message") or stopped.get("kind")
    return Row(spec.stem, intended, str(report.get("verdict", "?")).upper(), wall, states,
               str(space.get("method", "?")), trace_given(report), peak, str(stopped or "-"))


def print_table(rows: list[Row]) -> None:
    head = (f"{'spec':<15} {'expected':<9} {'verdict':<13} {'agree':<5} {'time s':>7} "
            f"{'states':>22} {'method':<28} {'peak MB':>8}  counterexample with firing sequence"
            f" | stopped by")
    print(head)
    print("-" * len(head))
    for r in rows:
        agree = "yes" if r.verdict == r.intended else "no"
        print(f"{r.spec:<15} {r.intended:<9} {r.verdict:<13} {agree:<5} {r.seconds:>7.1f} "
              f"{r.states:>22} {r.method:<28} {r.peak_mb:>8.0f}  {r.trace} | {r.stopped}")


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--limit", type=float, default=60.0, help="seconds per spec (--timeout)")
    ap.add_argument("--reduction", default="auto", choices=["auto", "off", "on", "compositional"])
    ap.add_argument("--no-progress-check", action="store_true")
    ap.add_argument("--mem-gb", type=float, default=8.0, help="address-space limit per spec")
    ap.add_argument("--only", help="only the specs whose name contains this")
    args = ap.parse_args()
    specs = [s for s in SPECS if not args.only or args.only in s.stem]
    print(f"rssmc verify --timeout {args.limit:g} --reduction {args.reduction}"
          f"{' --no-progress-check' if args.no_progress_check else ''}, "
          f"address space <= {args.mem_gb:g} GB, one spec at a time\n", flush=True)
    rows = []
    for spec in specs:
        rows.append(measure(spec, args))
        print(f"  {spec.stem}: {rows[-1].verdict} in {rows[-1].seconds:.1f} s", flush=True)
    print()
    print_table(rows)
    return 0


if __name__ == "__main__":
    sys.exit(main())
