"""Time to verdict of the properties stated in a spec, and the states per second of the
exploration that decides them (properties tracked: the values they read in the state): the
handover of examples/verify/ with two state invariants over its arm and base added (one
holds, one is violated), lockstep with its own two properties, and the two specs of
tests/verify/specs/ with properties (the mobile manipulator: two invariants, two response
properties; two independent subsystems); `rssmc verify` as a user runs it, in its own
process, compilation included, with `--reduction auto` (the full exploration's compact
encoding) and `--reduction on` (stubborn sets keeping the atoms visible).

    python bench/verify_properties.py [--reduction auto on]
"""

from __future__ import annotations

import argparse
import json
import re
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
HANDOVER_PROPERTIES = """
  property no_stale_clamp: always not (base.c in unload and base.c.clamped)
  property no_release_while_docking: always not (arm.c in release and base.c in dock)
}
"""


def run(spec: Path, reduction: str) -> tuple[dict[str, object], float]:
    start = time.monotonic()
    out = subprocess.run([sys.executable, "-m", "rssm_dsl", "verify", str(spec), "--format",
                          "json", "--reduction", reduction], capture_output=True, text=True,
                         cwd=ROOT, check=False)
    return json.loads(out.stdout), time.monotonic() - start


def rate(why: str) -> str:
    """The states and states per second a property's explanation gives."""
    found = re.search(r"\(([\d,]+) states of .*?; [a-z ]+, ([\d,]+) states/s", why)
    return f"{found.group(1)} states, {found.group(2)}/s" if found else "-"


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--reduction", nargs="*", default=["auto", "on"])
    args = ap.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        handover = Path(tmp) / "handover_with_properties.rssm"
        text = (ROOT / "examples" / "verify" / "handover.rssm").read_text(encoding="utf-8")
        handover.write_text(text.rstrip().removesuffix("}") + HANDOVER_PROPERTIES,
                            encoding="utf-8")
        specs = (handover, ROOT / "examples" / "verify" / "lockstep.rssm",
                 ROOT / "tests" / "verify" / "specs" / "mobile_manipulator_props.rssm",
                 ROOT / "tests" / "verify" / "specs" / "two_subsystems_props.rssm")
        print(f"{'spec':<28} {'reduction':<9} {'verdict':<9} {'time s':>7}  property: "
              "verdict (states explored, states/s)")
        for spec in specs:
            for reduction in args.reduction:
                report, seconds = run(spec, reduction)
                props = report.get("user_properties", [])
                assert isinstance(props, list)
                words = ", ".join(f"{p['name']}: "
                                  f"{ {True: 'holds', False: 'violated', None: 'open'}[p['holds']]}"
                                  f" ({rate(p['why'])})" for p in props)
                print(f"{spec.stem:<28} {reduction:<9} {report['verdict']!s:<9} {seconds:>7.1f}"
                      f"  {words}", flush=True)

if __name__ == "__main__":
    main()
