"""A guard that reads only parameters and constants is decided, never a free choice, in
the value-tracked nets the properties are checked on (the docs: parameters and constants
are never abstracted). The trial of issue 32 found `switch report -> end when reported and
work_time == 1` taken by a robot whose work_time is 2: a response property reported
violated, and its replay "reproduced" with the switch forced against the data."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
SPEC = ROOT / "tests" / "verify" / "specs" / "param_switch.rssm"


@pytest.mark.parametrize(("quick", "holds"), [("false", True), ("true", False)])
def test_a_guard_over_a_parameter_is_decided(tmp_path: Path, quick: str, holds: bool) -> None:
    spec = tmp_path / "p.rssm"
    spec.write_text(SPEC.read_text().replace("param quick: bool = false",
                                             f"param quick: bool = {quick}"))
    run = subprocess.run([sys.executable, "-m", "rssm_dsl", "verify", str(spec), "--format",
                          "json"], capture_output=True, text=True, cwd=ROOT, timeout=300)
    report = json.loads(run.stdout)
    props = {p["name"]: p["holds"] for p in report["user_properties"]}
    assert props == {"never_ends": holds, "stays": True}, report.get("why_undecided")
    if not holds:      # its counterexample replays with no firing forced against the data
        saved = tmp_path / "report.json"
        saved.write_text(run.stdout)
        replay = subprocess.run([sys.executable, "-m", "rssm_dsl", "simulate", str(spec),
                                 "--replay", str(saved), "--format", "json"],
                                capture_output=True, text=True, cwd=ROOT, timeout=300)
        out = json.loads(replay.stdout)
        assert out["replay"]["reproduced"] is True and out["replay"]["forced"] == 0, out


def test_a_report_with_properties_states_the_run_time_assumption() -> None:
    """The properties track values, so their verdicts assume that no operation fails at run
    time (a value out of its range is E802 in the interpreter): the report says so even
    when safeness, deadlocks and progress tracked none (the trial's `tries: 0..2` with
    three tries was VERIFIED without it)."""
    run = subprocess.run([sys.executable, "-m", "rssm_dsl", "verify", str(SPEC)],
                         capture_output=True, text=True, cwd=ROOT, timeout=300)
    assert "values tracked in the state" not in run.stdout
    assert "assuming no operation fails at run time (E802)" in run.stdout, run.stdout


@pytest.mark.parametrize(("quick", "verdict"), [("false", "verified"), ("true", "violated")])
def test_the_free_choices_pass_decides_a_guard_over_a_parameter(
        tmp_path: Path, quick: str, verdict: str) -> None:
    """The first pass takes every condition on data as a free choice, but never a
    parameter: `switch work -> end when done and quick` with quick = false never fires, so
    the boss waiting for every report never stalls (it was VIOLATED: the pass took the
    switch as a free choice, and with no value to track nothing checked it again); with
    quick = true the worker ends and the boss waits for ever, a deadlock that replays with
    nothing forced."""
    spec = tmp_path / "param_end.rssm"
    spec.write_text((ROOT / "tests" / "verify" / "specs" / "param_end.rssm").read_text()
                    .replace("param quick: bool = false", f"param quick: bool = {quick}"))
    run = subprocess.run([sys.executable, "-m", "rssm_dsl", "verify", str(spec), "--format",
                          "json"], capture_output=True, text=True, cwd=ROOT, timeout=300)
    report = json.loads(run.stdout)
    assert report["verdict"] == verdict, report
    free = json.dumps(report["conditions"]["free_choices"])
    assert "quick" not in free, free
    dead = json.dumps(report["dead_transitions"])
    assert ("done and quick" in dead) is (quick == "false"), dead
    if verdict == "violated":
        saved = tmp_path / "report.json"
        saved.write_text(run.stdout)
        replay = subprocess.run([sys.executable, "-m", "rssm_dsl", "simulate", str(spec),
                                 "--replay", str(saved), "--format", "json"],
                                capture_output=True, text=True, cwd=ROOT, timeout=300)
        out = json.loads(replay.stdout)["replay"]
        assert out["reproduced"] is True and out["forced"] == 0, out
