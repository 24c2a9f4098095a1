"""The specs a new user wrote with agent definitions from docs/ alone (the acceptance trial
of issue 32): a bucket-brigade chain of three stations of one definition, each naming its
neighbours through `agent` parameters (correct, and with a planted bug), and a coordinator
with seven workers of one definition. Each is checked clean, and verified to the verdict
its author worked out; the violations replay in the interpreter."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest

from rssm_dsl.pipeline import compile_file
from tests.conftest import ROOT

HERE = Path(__file__).parent / "instances"


def _rssmc(*args: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run([sys.executable, "-m", "rssm_dsl", *args], capture_output=True,
                          text=True, cwd=ROOT, timeout=900)


@pytest.mark.parametrize("name", ["chain", "chain_gap3", "workers"])
def test_the_trial_specs_check_clean(name: str) -> None:
    comp = compile_file(HERE / f"{name}.rssm")
    assert comp.ok and not [d for d in comp.diagnostics if d.is_error], comp.diagnostics
    assert comp.hpn is not None


@pytest.mark.slow
@pytest.mark.parametrize("name, verdict, props", [
    ("chain", "verified", {"st2_never_jams": True, "parts_reach_st3": True}),
    ("chain_gap3", "violated", {"st2_never_jams": False}),
])
def test_the_chain_gets_its_authors_verdict(name: str, verdict: str, props: dict[str, bool],
                                            tmp_path: Path) -> None:
    run = _rssmc("verify", str(HERE / f"{name}.rssm"), "--format", "json", "--timeout", "240")
    report = json.loads(run.stdout)
    assert report["verdict"] == verdict, report.get("why_undecided")
    got = {p["name"]: p["holds"] for p in report["user_properties"]}
    assert {k: got[k] for k in props} == props
    if verdict == "violated":
        saved = tmp_path / "report.json"
        saved.write_text(run.stdout, encoding="utf-8")
        replay = _rssmc("simulate", str(HERE / f"{name}.rssm"), "--replay", str(saved),
                        "--format", "json")
        assert json.loads(replay.stdout)["replay"]["reproduced"] is True


@pytest.mark.long
def test_the_workers_first_property_is_violated(tmp_path: Path) -> None:
    """The worker fleet: w1 may take its job before the coordinator leaves `dispatch` (the
    author's P1, violated) and the coordinator never closes while w7 works (P3, holds);
    P2 (w7 finishes) is explored on the whole net and may stay open."""
    run = _rssmc("verify", str(HERE / "workers.rssm"), "--format", "json", "--timeout", "120")
    report = json.loads(run.stdout)
    got = {p["name"]: p["holds"] for p in report["user_properties"]}
    assert got["w1_not_before_coord_leaves"] is False and got["closing_after_w7"] is True
    assert got["w7_finishes"] in (True, None)
    assert report["verdict"] == "violated"
