"""Time to verdict, ours against SPIN's (C compile included), on nets of 1e4 to 1e6 states.

Run: python tests/verify/bench_spin.py   (not collected by pytest)
"""

from __future__ import annotations

import os
import sys
import time

sys.path.insert(0, os.path.dirname(__file__))

from netkit import hpn_like, pipeline_ring

from rssm_dsl.hpn.flat import FlatNet
from rssm_dsl.verify import VerifyOptions, verify
from rssm_dsl.verify.netbits import NetBits
from rssm_dsl.verify.promela import run_spin
from rssm_dsl.verify.statespace import explore_full


def bench(name: str, net: FlatNet) -> None:
    t = time.monotonic()
    full = explore_full(NetBits.of(net), keep_graph=False)
    explore = time.monotonic() - t
    t = time.monotonic()
    report = verify(net, VerifyOptions(reduction="off"))
    total = time.monotonic() - t
    t = time.monotonic()
    reduced = verify(net, VerifyOptions(reduction="on"))
    red = time.monotonic() - t
    spin = run_spin(net)
    print(f"{name:<16} states {full.states:>9}  explore {explore:6.2f} s "
          f"({full.states / explore:>9,.0f} st/s)  verify {total:6.2f} s "
          f"[{report.verdict.value}]  stubborn {red:5.2f} s ({reduced.states} st)  |  "
          f"SPIN {spin.states_stored:>9} st  compile {spin.compile_seconds:4.2f} s  "
          f"run {spin.run_seconds:5.2f} s  (pan: {spin.rate:>9,.0f} st/s)  "
          f"total {spin.total_seconds:5.2f} s [{spin.message}]", flush=True)


if __name__ == "__main__":
    bench("hpn_like(3,2,2)", hpn_like(3, 2, 2))
    bench("ring(8, BB)", pipeline_ring(8, "BB"))
    bench("hpn_like(3,2,3)", hpn_like(3, 2, 3))
    bench("ring(9, BB)", pipeline_ring(9, "BB"))
    if "--large" in sys.argv:
        bench("ring(10, BB)", pipeline_ring(10, "BB"))
        bench("ring(6, NN)", pipeline_ring(6, "NN"))
