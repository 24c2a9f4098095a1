"""Run `rssmc` in a subprocess and measure its wall time and peak memory.

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
import time
from dataclasses import dataclass
from pathlib import Path

from tests.conftest import ROOT

_WRAPPER = """
import json, os, subprocess, sys
proc = subprocess.Popen(sys.argv[2:], stdout=subprocess.DEVNULL, stderr=open(sys.argv[1], "wb"))
_, status, usage = os.wait4(proc.pid, 0)
print(json.dumps([os.waitstatus_to_exitcode(status), usage.ru_maxrss]))
"""


@dataclass(frozen=True)
class Run:
    code: int          # exit code of rssmc
    stderr: str
    seconds: float     # wall time, the wrapper's start included (about 50 ms)
    peak_mb: float     # peak resident memory of rssmc alone


def rssmc(*args: str | Path, cwd: Path, timeout: float = 300) -> Run:
    """``rssmc ARGS`` run in ``cwd`` (stdout discarded)."""
    err = cwd / ".rssmc-stderr"
    start = time.perf_counter()
    out = subprocess.run(
        [sys.executable, "-c", _WRAPPER, str(err), sys.executable, "-m", "rssm_dsl",
         *map(str, args)],
        cwd=cwd, capture_output=True, text=True, timeout=timeout,
        env={**os.environ, "PYTHONPATH": str(ROOT)}, check=True)
    seconds = time.perf_counter() - start
    code, maxrss = json.loads(out.stdout)
    stderr = err.read_text(encoding="utf-8", errors="replace")
    err.unlink()
    return Run(code, stderr, seconds, maxrss / 1024)
