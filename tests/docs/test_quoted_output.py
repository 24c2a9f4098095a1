"""The README quotes what its first command prints: that block is compared with a fresh run
of the same command, number by number (counts exactly, measured values within 1 %), except
the `wall` line, which depends on the machine and says so."""

from __future__ import annotations

import re
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
NUMBER = re.compile(r"-?\d[\d,]*(?:\.\d+)?")


def _quoted_run_output() -> list[str]:
    text = (ROOT / "README.md").read_text(encoding="utf-8")
    block = re.search(r"```\n(lwr4_circle: .*?)```", text, re.S)
    assert block is not None, "README.md no longer quotes the output of `rssmc run`"
    return block.group(1).rstrip("\n").splitlines()


def _numbers(line: str) -> list[float]:
    return [float(n.replace(",", "")) for n in NUMBER.findall(line)]


def test_the_readme_quotes_what_rssmc_run_prints(tmp_path: Path) -> None:
    quoted = _quoted_run_output()
    run = subprocess.run([sys.executable, "-m", "rssm_dsl", "run",
                          str(ROOT / "examples" / "lwr4_circle.rssm"), "-o", str(tmp_path)],
                         capture_output=True, text=True, timeout=600, cwd=ROOT)
    assert run.returncode == 0, run.stderr
    printed = [line for line in run.stdout.splitlines() if line.strip()]
    assert len(printed) == len(quoted), (printed, quoted)
    for want, got in zip(quoted, printed, strict=True):
        key = want.split()[0]
        assert got.split()[0] == key, (want, got)
        if key in ("wall", "wrote"):        # the machine's speed; the output folder
            continue
        assert NUMBER.sub("#", got) == NUMBER.sub("#", want), (want, got)
        for a, b in zip(_numbers(want), _numbers(got), strict=True):
            assert abs(a - b) <= max(0.01 * abs(a), 1e-3), (key, a, b, want, got)
