"""Specs a new user wrote from README.md and docs/ alone in the acceptance trial of issue 33
(reliability), kept as tests: every command runs cleanly on them, and verify gives the
verdict worked out by hand (tests/cli/acceptance/*.rssm state it in their headers)."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest

from tests.conftest import ROOT

HERE = Path(__file__).resolve().parent / "acceptance"


def rssmc(*args: str | Path, cwd: Path = ROOT) -> subprocess.CompletedProcess[str]:
    return subprocess.run([sys.executable, "-m", "rssm_dsl", *map(str, args)], cwd=cwd,
                          capture_output=True, text=True, timeout=600)


@pytest.mark.slow
@pytest.mark.parametrize("name", ["gripper", "handover"])
def test_every_command_runs_cleanly(tmp_path: Path, name: str) -> None:
    spec = HERE / f"{name}.rssm"
    for args in (("check", spec), ("simulate", spec, "--until", "1", "-q"),
                 ("compile", spec, "-o", tmp_path / "c", "-q"),
                 ("render", spec, "-o", tmp_path / "r", "-q"),
                 ("ros2", spec, "-o", tmp_path / "ws", "-q")):
        r = rssmc(*args)
        assert r.returncode == 0, (args, r.stderr)
        assert "Traceback" not in r.stderr


@pytest.mark.slow
def test_the_verdicts_their_author_worked_out() -> None:
    r = rssmc("verify", HERE / "gripper.rssm", "--format", "json")
    assert r.returncode == 0 and json.loads(r.stdout)["verdict"] == "verified", r.stdout[-800:]
    r = rssmc("verify", HERE / "handover.rssm", "--format", "json")
    report = json.loads(r.stdout)
    assert r.returncode == 1 and report["deadlock_free"] is True and report["progress_ok"]
    [prop] = report["user_properties"]
    # the only violation: before taker.c entered `take`, in the initial marking
    assert prop["name"] == "taker_always" and prop["holds"] is False
    steps = prop["counterexample"]["steps"]
    assert not any(s["role"] == "switch" and "taker.c" in s["label"] for s in steps), steps
