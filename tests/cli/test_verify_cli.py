"""`rssmc verify` end to end: verdicts, exit codes and counterexamples in the user's words."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

from tests.conftest import EXAMPLES, ROOT


def verify(*args: str | Path) -> subprocess.CompletedProcess[str]:
    return subprocess.run([sys.executable, "-m", "rssm_dsl", "verify", *map(str, args)],
                          cwd=ROOT, capture_output=True, text=True, timeout=600)


def test_lwr4_example_is_safe_and_deadlock_free() -> None:
    r = verify(EXAMPLES / "lwr4_circle.rssm", "--format", "json")
    assert r.returncode == 0, r.stdout + r.stderr
    report = json.loads(r.stdout)
    assert report["verdict"] == "verified"
    assert report["safe"] is True and report["deadlock_free"] is True
    assert report["progress_ok"] is True
    assert report["invariants"]["list"], "the place invariants are listed"
    assert report["invariants"]["uncovered_places"] == []


def test_blocking_pair_deadlocks_with_both_sends_named() -> None:
    spec = EXAMPLES / "verify" / "deadlock_pair.rssm"
    r = verify(spec)
    assert r.returncode == 1, r.stdout
    assert "VIOLATED" in r.stdout and "deadlock 1 of 1" in r.stdout
    text = r.stdout.split("deadlock 1 of 1")[1].split("place invariants")[0]
    # the counterexample points at both blocking send declarations (lines 8 and 25)
    assert "deadlock_pair.rssm:8)" in text and "deadlock_pair.rssm:25)" in text
    assert "left.c (exchange) waits in blocking send of mine" in text
    assert "right.c (exchange) waits in blocking send of mine" in text
    report = json.loads(verify(spec, "--format", "json").stdout)
    assert report["deadlock_count"] == 1 and report["progress"] == []


def test_blocking_pair_in_a_running_system_loses_progress() -> None:
    r = verify(EXAMPLES / "verify" / "progress_triple.rssm", "--format", "json")
    assert r.returncode == 1
    report = json.loads(r.stdout)
    assert report["deadlock_free"] is True  # the conveyor keeps running
    stuck = {c["subsystem"] for c in report["progress"]}
    assert stuck == {"left.c", "right.c"}


def test_state_limit_gives_inconclusive() -> None:
    r = verify(EXAMPLES / "lwr4_circle.rssm", "--max-states", "50", "--reduction", "off",
               "--no-invariants")
    assert r.returncode == 3, r.stdout
    assert "INCONCLUSIVE" in r.stdout


def test_bad_input_is_exit_2_with_diagnostics(tmp_path: Path) -> None:
    bad = tmp_path / "bad.rssm"
    bad.write_text("system s { agent a { control { behaviour b { } } } }\n")
    r = verify(bad)
    assert r.returncode == 2 and "error[" in r.stderr and "Traceback" not in r.stderr


def test_too_large_to_explore_is_verified_by_slices() -> None:
    # camera_tracker has over 5 million reachable markings, but nobody in it waits on
    # anybody: each subsystem is verified on its own (its slice explored whole)
    r = verify(EXAMPLES / "camera_tracker.rssm", "--format", "json")
    assert r.returncode == 0, r.stdout + r.stderr
    report = json.loads(r.stdout)
    assert report["verdict"] == "verified"
    assert report["state_space"]["method"] == "sliced(full)"
    assert report["progress_ok"] is True and len(report["progress_checked"]) == 5
    assert report["unreachable_behaviours"] == []


def test_compositional_reduction_reports_loss_of_progress() -> None:
    r = verify(EXAMPLES / "verify" / "progress_triple.rssm", "--reduction", "compositional")
    assert r.returncode == 1, r.stdout + r.stderr
    assert "2 subsystem(s) can get stuck" in r.stdout
    assert "loss of progress: left.c" in r.stdout and "loss of progress: right.c" in r.stdout


def test_a_ring_of_agents_is_verified_compositionally(tmp_path: Path) -> None:
    # 24 agents, each a control subsystem, two effectors and their devices, the control
    # subsystems passing a token round the ring: far beyond explicit exploration
    from rssm_dsl.synth import lean_ring_system

    spec = tmp_path / "ring.rssm"
    spec.write_text(lean_ring_system(24))
    r = verify(spec, "--reduction", "compositional", "--no-progress-check", "--format", "json")
    assert r.returncode == 4, r.stdout + r.stderr      # verified, progress not checked
    report = json.loads(r.stdout)
    assert report["verdict"] == "verified_without_progress" and report["deadlock_free"] is True
    assert report["state_space"]["method"] == "compositional"


def test_the_report_states_what_progress_assumes() -> None:
    spec = EXAMPLES / "verify" / "deadlock_pair.rssm"
    report = json.loads(verify(spec, "--format", "json").stdout)
    assert report["progress_assumption"]["fairness"] == "strong"
    assert "assuming:   strong fairness" in verify(spec).stdout
    off = json.loads(verify(spec, "--format", "json", "--no-progress-check").stdout)
    assert off["progress_assumption"] is None


def test_lockstep_values_properties_and_fairness_through_the_cli() -> None:
    """The data decides lockstep's verdict, its two properties hold, and the report says
    what it tracked and what fairness it assumed; a bad --fairness is an input error."""
    spec = EXAMPLES / "verify" / "lockstep.rssm"
    r = verify(spec, "--format", "json")
    assert r.returncode == 0, r.stdout + r.stderr
    report = json.loads(r.stdout)
    assert report["verdict"] == "verified"
    assert "robot.c.x" in report["conditions"]["tracked_values"]
    assert {p["name"]: p["holds"] for p in report["user_properties"]} == {
        "flag_is_memory": True, "alternates": True}
    assert report["progress_assumption"]["fairness"] == "strong"
    weak = json.loads(verify(spec, "--format", "json", "--fairness", "weak").stdout)
    assert weak["progress_assumption"]["fairness"] == "weak" and weak["verdict"] == "verified"
    bad = verify(spec, "--fairness", "fair")
    assert bad.returncode == 2 and "--fairness must be strong or weak" in bad.stderr
    assert "Traceback" not in bad.stderr
