"""Time to verdict of `rssmc verify` on the fleet: a coordinator and N robots, written as a
new user writes them from the docs (tests/verify/specs/fleet{2,3,4,7}.rssm, and the planted
bugs fleet3_bug.rssm, fleet7_bug.rssm; each states its expected verdict in its header).

    python bench/verify_fleet.py [--limit 60] [--only fleet3,fleet3_bug] [--simulation]

Each spec is verified by the CLI (`rssmc verify SPEC --format json --timeout LIMIT
--no-simulation`, or with the simulation with --simulation) in its own process, one at a
time. Per spec: robots, the expected verdict (header line `expected: ...`), the verdict, the
wall time of the process (Python's start and the compilation included), the states and the
engines the report names, and the technique that decided (from the report's notes). It is
a benchmark, not a test: it exits 0 whatever the verdicts.
"""

from __future__ import annotations

import argparse
import json
import re
import subprocess
import sys
import time
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parent.parent
SPECS = ROOT / "tests" / "verify" / "specs"
NAMES = ("fleet2", "fleet3", "fleet4", "fleet7", "fleet3_bug", "fleet7_bug")
EXPECTED = re.compile(r"^// expected: ([A-Z]+)", re.MULTILINE)


def technique(report: dict[str, Any]) -> str:
    """What decided, from the report's notes."""
    notes = " ".join(report.get("notes", ()))
    out = []
    if "verified again with the values tracked" in notes:
        out.append("free choices cut short, then values tracked")
    elif "confirmed with the values tracked" in notes:
        out.append("free choices found it, values tracked confirm")
    elif "the data rules it out" in notes:
        out.append("free choices found it, values tracked rule it out")
    elif report.get("conditions", {}).get("free_choices"):
        out.append("free choices")
    if "progress follows from deadlock freedom" in notes:
        out.append("progress from deadlock freedom")
    return "; ".join(out) or "-"


def run(name: str, args: argparse.Namespace) -> list[str]:
    spec = SPECS / f"{name}.rssm"
    m = EXPECTED.search(spec.read_text(encoding="utf-8"))
    cmd = [sys.executable, "-m", "rssm_dsl", "verify", str(spec), "--format", "json",
           "--timeout", str(args.limit)]
    if not args.simulation:
        cmd.append("--no-simulation")
    start = time.monotonic()
    proc = subprocess.run(cmd, capture_output=True, text=True, cwd=ROOT, check=False)
    wall = time.monotonic() - start
    try:
        report = json.loads(proc.stdout)
    except json.JSONDecodeError:
        return [name, "?", m.group(1) if m else "?", f"error (exit {proc.returncode})",
                f"{wall:.1f}", "", "", proc.stderr.strip().splitlines()[-1:][0]
                if proc.stderr.strip() else ""]
    space = report.get("state_space", {})
    robots = re.search(r"fleet(\d+)", name)
    return [name, robots.group(1) if robots else "?", m.group(1) if m else "?",
            str(report.get("verdict", "?")).upper(), f"{wall:.1f}",
            f"{space.get('states', 0):,}", str(space.get("method", "")), technique(report)]


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--limit", type=float, default=60.0, help="--timeout of each run (s)")
    ap.add_argument("--only", default="", help="comma-separated spec names")
    ap.add_argument("--simulation", action="store_true",
                    help="with the random runs (default: --no-simulation)")
    args = ap.parse_args()
    names = [n for n in args.only.split(",") if n] or list(NAMES)
    head = ["spec", "robots", "expected", "verdict", "time s", "states", "method",
            "technique"]
    print("  ".join(head))
    for name in names:
        print("  ".join(run(name, args)), flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
