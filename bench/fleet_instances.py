"""The fleet written with an agent definition (examples/fleet.rssm: a coordinator and eight
robots of one definition): its size as written and as a net, the compile time, and the time
to verdict of `rssmc verify` (issue 32: "a fleet of eight robots ... compiles into a net of a
few thousand places at most, in under 2 s, and verifies within the first issue's limits").

    python bench/fleet_instances.py [--spec examples/fleet.rssm] [--repeat 3] [--limit 60]

Compile: `compile_file` in this process, the first run (the grammar loaded) and the best of
``--repeat`` (what the process has cached by then).
Verify: the CLI (`rssmc verify SPEC --format json --timeout LIMIT`) in its own process, its
wall time (Python's start and the compilation included). A benchmark, not a test: it exits 0
whatever the verdict.
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

from rssm_dsl.hpn.flatten import flatten  # noqa: E402
from rssm_dsl.pipeline import compile_file  # noqa: E402


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--spec", default=str(ROOT / "examples" / "fleet.rssm"))
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--limit", default="60")
    args = ap.parse_args()
    spec = Path(args.spec)
    text = spec.read_text(encoding="utf-8")
    times: list[float] = []
    comp = None
    for _ in range(args.repeat):
        t0 = time.perf_counter()
        comp = compile_file(spec)
        times.append(time.perf_counter() - t0)
    assert comp is not None and comp.system is not None and comp.hpn is not None
    net = flatten(comp.hpn)
    print(f"spec: {spec.name}, {len(text.splitlines())} lines, "
          f"{len(comp.system.agents)} agents "
          f"({sum(1 for a in comp.system.agents if a.name != 'coord')} of one definition)")
    print(f"net: {len(comp.hpn.pages)} pages, {len(comp.hpn.places)} places (flat: "
          f"{len(net.places)} places, {len(net.transitions)} transitions)")
    print(f"compile: {times[0]:.2f} s the first time (the grammar loaded), "
          f"{min(times[1:] or times):.2f} s again (best of {args.repeat})")
    t0 = time.perf_counter()
    run = subprocess.run([sys.executable, "-m", "rssm_dsl", "verify", str(spec), "--format",
                          "json", "--timeout", args.limit], capture_output=True, text=True,
                         cwd=ROOT)
    wall = time.perf_counter() - t0
    try:
        report = json.loads(run.stdout)
    except json.JSONDecodeError:
        print(f"verify: no report (exit {run.returncode}) after {wall:.1f} s")
        return 0
    props = {p["name"]: p["holds"] for p in report.get("user_properties", [])}
    print(f"verify: {report['verdict'].upper()} in {wall:.1f} s (limit {args.limit} s); "
          f"properties: " + ", ".join(f"{k} {'holds' if v else 'violated' if v is False else 'open'}"
                                      for k, v in props.items()))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
