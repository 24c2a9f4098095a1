"""Time to verdict on mixed-mode rings of control subsystems, progress check on,
against SPIN on the same flat nets.

The rings are `rssm_dsl.synth.mixed_ring_system(n, links)`: c of a_k sends to c of a_{k+1}
in every iteration; the links cycle through ``links`` (B blocking on both ends, N
non-blocking on both, W non-blocking send and blocking receive); every third agent also
drives an effector with a device. A ring of B links loses progress (every c waits in its
send while the effectors and devices run on); BN and W rings are correct.

Per ring: the verdict of `verify` (compile and flatten included, default options: sliced
when the whole net is large), the states it explored and its wall time; then SPIN on the
flat net's Promela model (`--cross-check` uses the same; deadlocks and safeness only, since
SPIN's model has no progress property), spin + cc + pan included, and SPIN's time over
ours. SPIN runs only where it finishes within the limit (`gave up` otherwise).

    python bench/verify_rings.py [--sizes 5,50] [--links B,BN,W] [--limit 60] [--skip-spin]
"""

from __future__ import annotations

import argparse
import tempfile
import time
from pathlib import Path

from rssm_dsl.hpn.flatten import flatten
from rssm_dsl.pipeline import compile_file
from rssm_dsl.synth import mixed_ring_system
from rssm_dsl.verify import VerifyOptions, verify
from rssm_dsl.verify.promela import run_spin


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--sizes", default="5,50")
    ap.add_argument("--links", default="B,BN,W")
    ap.add_argument("--limit", type=float, default=60.0)
    ap.add_argument("--skip-spin", action="store_true")
    args = ap.parse_args()
    print(f"{'ring':<8} {'N':>4} {'places':>7} {'verdict':<13} {'lost':>5} {'states':>9} "
          f"{'ours s':>7} {'SPIN s':>8} {'SPIN states':>11} {'SPIN/ours':>9}")
    with tempfile.TemporaryDirectory() as tmpdir:
        for links in args.links.split(","):
            for n in (int(x) for x in args.sizes.split(",")):
                path = Path(tmpdir) / f"ring_{links}_{n}.rssm"
                path.write_text(mixed_ring_system(n, links), encoding="utf-8")
                start = time.monotonic()
                comp = compile_file(path)
                assert comp.ok and comp.hpn is not None
                net = flatten(comp.hpn)
                report = verify(net, VerifyOptions(time_limit=args.limit))
                ours = time.monotonic() - start
                lost = len({c.subsystem for c in report.progress})
                spin_cells = f"{'-':>8} {'-':>11} {'-':>9}"
                if not args.skip_spin:
                    spin = run_spin(net, timeout=args.limit)
                    if spin.ran and spin.complete:
                        spin_cells = (f"{spin.total_seconds:>8.2f} {spin.states_stored:>11} "
                                      f"{spin.total_seconds / ours:>9.2f}")
                    else:
                        spin_cells = f"{'gave up':>8} {spin.states_stored:>11} {'-':>9}"
                print(f"{links:<8} {n:>4} {len(net.places):>7} {report.verdict.value:<13} "
                      f"{lost:>5} {report.states:>9} {ours:>7.2f} {spin_cells}", flush=True)


if __name__ == "__main__":
    main()
