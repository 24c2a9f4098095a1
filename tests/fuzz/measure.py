"""Run `rssmc` in a subprocess and measure its CPU time and peak memory.

CPU time (user + system), not wall time: a busy machine stretches the wall time of a command
by whatever else runs beside it, and a bound on it would fail there; the work the command does
is what its CPU time counts.

The peak resident memory (ru_maxrss) of a child counts the memory of the process it was
forked from until it execs, so a child of a large test process (hypothesis, megabytes of
inputs) reports the test process's size. The command therefore runs under a small Python
wrapper that forks it and reports the child's own ru_maxrss (os.wait4).
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
from dataclasses import dataclass
from pathlib import Path

from tests.conftest import ROOT

_WRAPPER = """
import json, os, subprocess, sys
proc = subprocess.Popen(sys.argv[2:], stdout=subprocess.DEVNULL, stderr=open(sys.argv[1], "wb"))
_, status, usage = os.wait4(proc.pid, 0)
print(json.dumps([os.waitstatus_to_exitcode(status), usage.ru_maxrss,
                  usage.ru_utime + usage.ru_stime]))
"""


@dataclass(frozen=True)
class Run:
    code: int          # exit code of rssmc
    stderr: str
    seconds: float     # CPU time of rssmc alone (user + system)
    peak_mb: float     # peak resident memory of rssmc alone


def rssmc(*args: str | Path, cwd: Path, timeout: float = 300) -> Run:
    """``rssmc ARGS`` run in ``cwd`` (stdout discarded)."""
    err = cwd / ".rssmc-stderr"
    out = subprocess.run(
        [sys.executable, "-c", _WRAPPER, str(err), sys.executable, "-m", "rssm_dsl",
         *map(str, args)],
        cwd=cwd, capture_output=True, text=True, timeout=timeout,
        env={**os.environ, "PYTHONPATH": str(ROOT)}, check=True)
    code, maxrss, seconds = json.loads(out.stdout)
    stderr = err.read_text(encoding="utf-8", errors="replace")
    err.unlink()
    return Run(code, stderr, seconds, maxrss / 1024)
