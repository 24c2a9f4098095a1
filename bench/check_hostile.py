"""Hostile input: wall time and peak memory of `rssmc check` on inputs of about --size bytes
(1 MB by default) of several shapes, each run in a subprocess (peak RSS from os.wait4), and
their ratios to the baseline, the same agents declared one per line (the machine is shared
and noisy: compare the ratios). The goal (tests/front/test_hostile_parse.py, issue "Hostile
input"): any 1 MB input in under 5 s and 500 MB.

    python bench/check_hostile.py [--size 1000000] [--runs 1] [--keep DIR] [--timeout 120]
"""

from __future__ import annotations

import argparse
import os
import random
import subprocess
import sys
import tempfile
import threading
import time
from collections.abc import Callable
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
RSSMC = [sys.executable, "-m", "rssm_dsl", "check"]
ENV = {k: v for k, v in os.environ.items() if k != "PYTHONDONTWRITEBYTECODE"}

AGENT = ("agent a{i} {{ control @ 10 Hz {{ memory m: int = 0 param p: int = {i} "
         "behaviour b {{ update memory {{ m := m + p }} terminal t when m > 3 }} "
         "initial b switch b -> end when t }} }}")
# a syntax error in each (a memory variable without its value)
BROKEN = "agent a{i} {{ control @ 10 Hz {{ memory m: int = }} }}"
# well formed, but each names an undeclared variable and has no behaviour (2 errors each)
UNDECLARED = "agent a{i} {{ control {{ memory m: int = x }} }}"


def repeat(item: str, size: int, sep: str) -> str:
    """``item`` formatted with i = 0, 1, ... and joined by ``sep`` until ``size`` chars."""
    out: list[str] = []
    n = i = 0
    while n < size:
        s = item.format(i=i) + sep
        out.append(s)
        n += len(s)
        i += 1
    return "".join(out)


def system(item: str, size: int, sep: str) -> str:
    return "system s {" + sep + repeat(item, size, sep) + "}\n"


def dense_consts(size: int) -> str:
    """Valid, and as many tokens per byte as a spec can have: 60-term sums."""
    line = "const k{i}: int = " + "+".join(["1"] * 60)
    return repeat(line, size, "\n")


def printable_garbage(size: int) -> str:
    rng = random.Random(0)
    alphabet = [chr(c) for c in range(0x21, 0x7F)] + list("é×≤\u2212\u00a0 \n")
    return "".join(rng.choice(alphabet) for _ in range(size))


def binary_garbage(size: int) -> bytes:
    return random.Random(0).randbytes(size)


SHAPES: list[tuple[str, Callable[[int], str | bytes]]] = [
    ("valid agents, one per line (baseline)", lambda n: system(AGENT, n, "\n")),
    ("valid agents, one line", lambda n: system(AGENT, n, " ")),
    ("broken agents, one per line", lambda n: system(BROKEN, n, "\n")),
    ("broken agents, one line", lambda n: system(BROKEN, n, " ")),
    ("undeclared names, one line", lambda n: system(UNDECLARED, n, " ")),
    ("1+1+...+1", lambda n: "const k: int = " + "1+" * (n // 2) + "1\n"),
    ("100,000 nested parentheses", lambda n: "const k: int = " + "(" * 100_000 + "1"
     + ")" * 100_000 + "\n"),
    ("if 1 then 1 else if ...", lambda n: "const k: int = " + "if 1 then 1 else " * (n // 17)
     + "1\n"),
    ("unclosed /* after every value", lambda n: system("agent a{i} {{ control {{ memory m: "
                                                        "int = 1 /*", n, " ")),
    ("unclosed strings", lambda n: '"\\' * (n // 2)),
    ("60-term sums (valid, dense)", dense_consts),
    ("printable garbage", printable_garbage),
    ("binary garbage", binary_garbage),
]


def run(path: Path, timeout: float) -> tuple[float, float, int, str]:
    """(seconds, peak RSS in MB, exit code, summary line) of `rssmc check path`, killed
    after ``timeout`` seconds."""
    with tempfile.TemporaryFile() as err:
        start = time.perf_counter()
        proc = subprocess.Popen([*RSSMC, str(path)], cwd=ROOT, env=ENV,
                                stdout=subprocess.DEVNULL, stderr=err)
        timer = threading.Timer(timeout, proc.kill)
        timer.start()
        _, status, usage = os.wait4(proc.pid, 0)
        timer.cancel()
        elapsed = time.perf_counter() - start
        proc.returncode = os.waitstatus_to_exitcode(status)
        err.seek(0)
        lines = err.read().decode("utf-8", "replace").splitlines()
    if proc.returncode < 0:
        return elapsed, usage.ru_maxrss / 1024, proc.returncode, f"killed after {timeout:g} s"
    first = next((ln for ln in lines if "error[" in ln), lines[-1] if lines else "")
    code = first.split("error[", 1)[1][:4] if "error[" in first else "-"
    summary = (lines[-1].rsplit(": ", 1)[-1] if lines else "") + f" (first {code})"
    return elapsed, usage.ru_maxrss / 1024, proc.returncode, summary


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--size", type=int, default=1_000_000, help="bytes per input")
    ap.add_argument("--runs", type=int, default=1, help="runs per shape (the best is shown)")
    ap.add_argument("--keep", type=Path, help="write the inputs to this folder and keep them")
    ap.add_argument("--timeout", type=float, default=120.0, help="seconds before a run is killed")
    args = ap.parse_args()
    folder = args.keep or Path(tempfile.mkdtemp(prefix="rssmc-hostile-"))
    folder.mkdir(parents=True, exist_ok=True)
    subprocess.run([*RSSMC, "--help"], cwd=ROOT, env=ENV, capture_output=True, check=False)
    print(f"{'input':<40} {'KB':>6} {'s':>6} {'MB':>6} {'x time':>7} {'x mem':>6}  exit  result")
    base: tuple[float, float] | None = None
    for i, (label, make) in enumerate(SHAPES):
        data = make(args.size)
        path = folder / f"hostile{i:02d}.rssm"
        if isinstance(data, bytes):
            path.write_bytes(data)
        else:
            path.write_text(data, encoding="utf-8")
        runs = [run(path, args.timeout) for _ in range(args.runs)]
        t, mem, code, summary = min(runs)
        if base is None:
            base = (t, mem)
        print(f"{label:<40} {path.stat().st_size // 1000:>6} {t:>6.2f} {mem:>6.0f} "
              f"{t / base[0]:>7.2f} {mem / base[1]:>6.2f}  {code:>4}  {summary}", flush=True)
    if args.keep is None:
        for p in folder.iterdir():
            p.unlink()
        folder.rmdir()


if __name__ == "__main__":
    main()
