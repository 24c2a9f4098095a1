"""The values a property's slice tracks are those that can decide something there: of what a
guard or a computed value reads, only what can change it once the rest (a value from
outside the slice) is unknown (rssm_dsl/verify/valuenet.py, ``_Relevance``).

The spec: a dispatcher handing jobs to the first free of three robots, whose transition
function and terminal condition read every robot's acknowledgement. Robot r1's property
needs only the dispatcher and r1. Before, the slice tracked for the dispatcher's guard the
other robots' values too, which its transition function could not carry (too many
valuations): r1's job and acknowledgement were left untracked, the correct spec took a
slice five times larger, and the bug was not decided within 120 s (the whole net)."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path
from typing import Any

import pytest

ROOT = Path(__file__).resolve().parents[2]
SPEC = ROOT / "tests" / "verify" / "specs" / "dispatch3.rssm"
CORRECT = "job1 := if pending > 0 and ack1 == job1 then 1 - job1 else job1"
# the bug: job1 flips while r1 has not acknowledged the last one, so r1, back in idle with
# job != ack... or in work on a job that was flipped back to its ack
BUG = "job1 := if pending > 0 then 1 - job1 else job1"


def _verify(tmp_path: Path, text: str) -> tuple[dict[str, Any], str]:
    spec = tmp_path / "dispatch3.rssm"
    spec.write_text(text)
    run = subprocess.run([sys.executable, "-m", "rssm_dsl", "verify", str(spec), "--format",
                          "json", "--timeout", "200"], capture_output=True, text=True,
                         cwd=ROOT, timeout=400)
    return json.loads(run.stdout), run.stdout


@pytest.mark.parametrize("bug", [False, True])
def test_the_robots_property_is_decided_on_its_slice(tmp_path: Path, bug: bool) -> None:
    text = SPEC.read_text()
    assert CORRECT in text
    report, raw = _verify(tmp_path, text.replace(CORRECT, BUG) if bug else text)
    (prop,) = report["user_properties"]
    assert prop["name"] == "r1_works_on_open_job"
    assert prop["holds"] is (not bug), prop
    # decided on the dispatcher and r1 alone, not on the whole net
    assert "the slice of disp.c, r1.c;" in prop["why"], prop["why"]
    assert report["verdict"] == ("violated" if bug else "verified"), report["verdict"]
    if bug:     # the counterexample replays in the interpreter with nothing forced
        saved = tmp_path / "report.json"
        saved.write_text(raw)
        replay = subprocess.run([sys.executable, "-m", "rssm_dsl", "simulate",
                                 str(tmp_path / "dispatch3.rssm"), "--replay", str(saved),
                                 "--format", "json"],
                                capture_output=True, text=True, cwd=ROOT, timeout=300)
        out = json.loads(replay.stdout)
        assert out["replay"]["reproduced"] is True and out["replay"]["forced"] == 0, out
