"""Time to verdict of `rssmc verify` on the specs new users wrote from the docs alone
(tests/verify/acceptance/*.rssm; each states its author's verdict in its header, and
tests/verify/test_acceptance_specs.py pins what the tool gives).

    python bench/verify_acceptance.py [--limit 120] [--only pickup,warehouse]

Each spec is verified by the CLI as a user runs it (`rssmc verify SPEC --format json
--timeout LIMIT`, the random runs included) in its own process, one at a time. Per spec:
the author's verdict, the tool's, the wall time of the process (Python's start and the
compilation included), and its properties: how many hold, are violated, are not decided.
It is a benchmark, not a test: it exits 0 whatever the verdicts.
"""

from __future__ import annotations

import argparse
import json
import re
import subprocess
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
SPECS = ROOT / "tests" / "verify" / "acceptance"
EXPECTED = re.compile(r"^// expected: ([A-Z]+)", re.MULTILINE)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--limit", type=float, default=120.0, help="--timeout of each run (s)")
    ap.add_argument("--only", default="", help="comma-separated spec names")
    args = ap.parse_args(argv)
    names = [p.stem for p in sorted(SPECS.glob("*.rssm"))]
    if args.only:
        names = [n for n in names if n in args.only.split(",")]
    print(f"{'spec':<28} {'author':<9} {'rssmc':<13} {'time s':>7}  properties "
          "(holds/violated/open)")
    for name in names:
        path = SPECS / f"{name}.rssm"
        found = EXPECTED.search(path.read_text(encoding="utf-8"))
        expected = found.group(1) if found else "?"
        start = time.monotonic()
        run = subprocess.run([sys.executable, "-m", "rssm_dsl", "verify", str(path),
                              "--format", "json", "--timeout", f"{args.limit:g}"],
                             capture_output=True, text=True, cwd=ROOT, check=False)
        took = time.monotonic() - start
        try:
            report = json.loads(run.stdout)
        except json.JSONDecodeError:
            print(f"{name:<28} {expected:<9} {'(no report)':<13} {took:7.1f}  exit "
                  f"{run.returncode}")
            continue
        props = [p.get("holds") for p in report.get("user_properties", [])]
        counts = (f"{props.count(True)}/{props.count(False)}/{props.count(None)}"
                  if props else "-")
        print(f"{name:<28} {expected:<9} {report['verdict'].upper():<13} {took:7.1f}  "
              f"{counts}", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
