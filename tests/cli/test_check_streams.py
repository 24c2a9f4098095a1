"""Where `rssmc check` writes (the README's table of commands): the diagnostics and the
summary line on stderr in text, the JSON array alone on stdout with `--format json`, so
that `rssmc check F --format json | jq` gets data and nothing else."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
SPEC = """system s {
  agent a {
    control @ 10 Hz {
      memory stauts: 0..3 = 0
      behaviour run {
        update memory { status := 1 }
        terminal never when false
      }
      initial run
    }
  }
}
"""


def _check(tmp_path: Path, *args: str) -> subprocess.CompletedProcess[str]:
    spec = tmp_path / "typo.rssm"
    spec.write_text(SPEC)
    return subprocess.run([sys.executable, "-m", "rssm_dsl", "check", str(spec), *args],
                          capture_output=True, text=True, cwd=tmp_path, timeout=60)


def test_text_goes_to_stderr_with_a_summary(tmp_path: Path) -> None:
    run = _check(tmp_path)
    assert run.returncode == 1 and run.stdout == ""
    assert "error[E102]" in run.stderr
    assert run.stderr.rstrip().splitlines()[-1].endswith("typo.rssm: 1 error, 1 warning")


def test_json_goes_to_stdout_alone(tmp_path: Path) -> None:
    run = _check(tmp_path, "--format", "json")
    assert run.returncode == 1 and run.stderr == ""
    codes = sorted(d["code"] for d in json.loads(run.stdout))
    assert codes == ["E102", "W702"]
