"""How long after its --timeout `rssmc verify` ends, in each phase.

Two kinds of runs, each a fresh process, its wall time measured from outside (the Python
start included) and printed minus the timeout:

- each phase of the front end and the verifier slowed by a pure-Python loop of 10 minutes
  that never checks the budget (the watchdog must interrupt it): compilation, flattening,
  value plan, slicing, data tracking, place invariants, full exploration;
- real specs: ``synth.lean_ring_system(N)`` (slow to compile and flatten) and
  ``synth.ring_system(16)`` (a state space no engine finishes) at a few timeouts.

    python bench/verify_limits.py [--timeout S] [--agents N]
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import tempfile
import textwrap
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
SPEC = ROOT / "examples" / "verify" / "deadlock_pair.rssm"
PHASES = [
    ("rssm_dsl.pipeline", "compile_file", None),
    ("rssm_dsl.hpn.flatten", "flatten", None),
    ("rssm_dsl.verify.dataplan", "value_plan", None),
    ("rssm_dsl.verify.verifier", "blocking_groups", None),
    ("rssm_dsl.verify.verifier", "track_new", None),
    ("rssm_dsl.verify.verifier", "one_token_semiflows", None),
    ("rssm_dsl.verify.verifier", "explore_full", "the full exploration"),
]
SLOWED = textwrap.dedent("""
    import importlib, sys, time
    from rssm_dsl.cli import entry
    from rssm_dsl.verify.budget import Budget

    module, name, phase = sys.argv[1], sys.argv[2], sys.argv[3] or None
    mod = importlib.import_module(module)
    real = getattr(mod, name)

    def spin():
        end = time.monotonic() + 600
        while time.monotonic() < end:
            sum(range(1000))

    def slowed(*args, **kwargs):
        if phase is None:
            spin()
        else:
            budget = next(a for a in (*args, *kwargs.values()) if isinstance(a, Budget))
            with budget.running(phase):
                spin()
        return real(*args, **kwargs)

    setattr(mod, name, slowed)
    sys.argv = ["rssmc", "verify", *sys.argv[4:]]
    entry()
""")


def run(cmd: list[str]) -> tuple[float, dict[str, object]]:
    t = time.monotonic()
    r = subprocess.run(cmd, cwd=ROOT, capture_output=True, text=True, timeout=1800)
    wall = time.monotonic() - t
    try:
        report = json.loads(r.stdout)
    except json.JSONDecodeError:
        report = {"headline": f"(not JSON, exit {r.returncode}) {r.stderr[-200:]}"}
    report["exit"] = r.returncode
    return wall, report


def line(what: str, timeout: float, wall: float, report: dict[str, object]) -> None:
    stop = report.get("stopped_by") or {}
    assert isinstance(stop, dict)
    print(f"{what:<34} timeout {timeout:>4g} s  wall {wall:6.2f} s  after the deadline "
          f"{wall - timeout:5.2f} s  exit {report['exit']}  stopped in "
          f"{stop.get('phase', '-')}", flush=True)


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--timeout", type=float, default=5.0)
    ap.add_argument("--agents", type=int, default=3000)
    args = ap.parse_args()
    t = args.timeout
    with tempfile.TemporaryDirectory() as tmp:
        script = Path(tmp) / "slowed.py"
        script.write_text(SLOWED)
        for module, name, phase in PHASES:
            wall, report = run([sys.executable, str(script), module, name, phase or "", str(SPEC),
                                "--timeout", f"{t:g}", "--format", "json"])
            line(f"slowed {name}", t, wall, report)
        from rssm_dsl.synth import lean_ring_system, ring_system

        lean = Path(tmp) / f"lean{args.agents}.rssm"
        lean.write_text(lean_ring_system(args.agents))
        ring = Path(tmp) / "ring16.rssm"
        ring.write_text(ring_system(16))
        for spec, timeouts in ((lean, (t, 4 * t)), (ring, (t,))):
            for limit in timeouts:
                wall, report = run([sys.executable, "-m", "rssm_dsl", "verify", str(spec),
                                    "--timeout", f"{limit:g}", "--format", "json"])
                line(spec.stem, limit, wall, report)


if __name__ == "__main__":
    main()
