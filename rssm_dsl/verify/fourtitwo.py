"""Cross-check: the minimal P-semiflows computed by 4ti2 (``rays``) instead of by us.

The P-semiflows are the extreme rays of the cone ``{y >= 0 : C^T y = 0}``; 4ti2's ``rays``
computes exactly those from the matrix ``C^T`` (transitions x places; the default sign file
makes every variable non-negative). It runs in a temporary directory with arbitrary precision.
Debian package ``4ti2`` installs it as ``/usr/bin/4ti2-rays``; other builds call it ``rays``.
"""

from __future__ import annotations

import os
import shutil
import subprocess
import tempfile
import time
from typing import TYPE_CHECKING

from rssm_core.records import dataclass
from rssm_dsl.hpn.flat import FlatNet
from rssm_dsl.verify.budget import Budget, LimitReached, run_limited
from rssm_dsl.verify.datanet import track_new
from rssm_dsl.verify.valuenet import track_values

if TYPE_CHECKING:
    from rssm_dsl.verify.dataplan import ValuePlan
from rssm_dsl.verify.invariants import incidence_matrix

CANDIDATES = ("4ti2-rays", "rays", "/usr/lib/4ti2/bin/rays",
              "/usr/libexec/x86_64-linux-gnu/4ti2/bin/rays")


@dataclass(frozen=True)
class FourTiTwoResult:
    available: bool
    semiflows: tuple[tuple[int, ...], ...] = ()   # dense vectors over places, gcd 1, sorted
    seconds: float = 0.0
    message: str = ""
    command: tuple[str, ...] = ()


def find_rays() -> str | None:
    """The path of 4ti2's ``rays`` executable, or None when 4ti2 is not installed."""
    env = os.environ.get("RSSMC_4TI2_RAYS")
    for name in ((env,) if env else ()) + CANDIDATES:
        path = shutil.which(name)
        if path:
            return path
    return None


def semiflows_4ti2(net: FlatNet, timeout: float = 120.0, budget: Budget | None = None,
                   values: ValuePlan | None = None) -> FourTiTwoResult:
    """Run ``rays`` on the transposed incidence matrix of ``net`` (under the run's
    ``budget``, if any: killed at its deadline or on Ctrl-C), with new(x) in its places as
    the verifier explores it (``datanet``)."""
    net = track_values(track_new(net), values).net
    if budget is None:
        return _semiflows_4ti2(net, timeout, None)
    with budget.running("the 4ti2 cross-check"):
        try:
            return _semiflows_4ti2(net, timeout, budget)
        except LimitReached as e:
            return FourTiTwoResult(True, message=f"stopped: {e.stop.message}")


def _semiflows_4ti2(net: FlatNet, timeout: float, budget: Budget | None) -> FourTiTwoResult:
    exe = find_rays()
    if exe is None:
        return FourTiTwoResult(False, message="4ti2 not installed (no 4ti2-rays or rays)")
    c = incidence_matrix(net)
    nplaces, ntrans = c.shape
    if nplaces == 0:
        return FourTiTwoResult(True, message="no places")
    rows = [[int(c[p, t]) for p in range(nplaces)] for t in range(ntrans)]
    if not rows:                      # no transition: every place is a semiflow on its own
        rows = [[0] * nplaces]
    with tempfile.TemporaryDirectory(prefix="rssmc-4ti2-") as tmp:
        project = os.path.join(tmp, "net")
        with open(project + ".mat", "w") as f:
            f.write(f"{len(rows)} {nplaces}\n")
            for row in rows:
                f.write(" ".join(map(str, row)) + "\n")
        cmd = (exe, "-q", "-parb", project)
        start = time.monotonic()
        try:
            proc = run_limited(cmd, budget, timeout)
        except subprocess.TimeoutExpired:
            return FourTiTwoResult(True, message=f"4ti2 timed out after {timeout:g} s",
                                   command=cmd)
        seconds = time.monotonic() - start
        if proc.returncode != 0 or not os.path.exists(project + ".ray"):
            return FourTiTwoResult(
                True, seconds=seconds, command=cmd,
                message=f"4ti2 failed (exit {proc.returncode}): {proc.stderr.strip()[-500:]}")
        with open(project + ".ray") as f:
            flows = parse_matrix(f.read())
    return FourTiTwoResult(True, semiflows=tuple(sorted(flows)), seconds=seconds, command=cmd,
                           message=f"{len(flows)} minimal P-semiflows")


def parse_matrix(text: str) -> list[tuple[int, ...]]:
    """A 4ti2 matrix file: ``rows cols`` then the entries."""
    numbers = text.split()
    if not numbers:
        return []
    nrows, ncols = int(numbers[0]), int(numbers[1])
    values = [int(v) for v in numbers[2:2 + nrows * ncols]]
    return [tuple(values[r * ncols:(r + 1) * ncols]) for r in range(nrows)]
