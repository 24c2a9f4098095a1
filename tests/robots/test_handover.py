"""Two agents, two arms: examples/panda_handover.rssm run with `rssmc run`, the coordination
read from the joint series it writes (one CSV per arm: time, desired and measured joints, the
behaviour of the arm's control subsystem), not from what it prints."""

from __future__ import annotations

import csv
import json
import re
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from tests.conftest import EXAMPLES
from tests.robots.conftest import joint_constants, needs_robot_data
from tests.run.conftest import rssmc

SPEC = EXAMPLES / "panda_handover.rssm"
C = joint_constants(SPEC)
REACH_TOL = 0.01        # rad, the example's reach_tol
STILL = 2e-3            # rad: an arm holding a configuration stays this close to it


@dataclass(frozen=True)
class Arm:
    t: np.ndarray[Any, np.dtype[np.float64]]
    q: np.ndarray[Any, np.dtype[np.float64]]
    behaviour: np.ndarray[Any, np.dtype[np.str_]]

    def first(self, behaviour: str, after: float = -1.0) -> int:
        """The first sample in ``behaviour`` after time ``after``."""
        return int(np.flatnonzero((self.behaviour == behaviour) & (self.t > after))[0])

    def dist(self, name: str) -> np.ndarray[Any, np.dtype[np.float64]]:
        return np.asarray(np.linalg.norm(self.q - C[name], axis=1), dtype=np.float64)


def _arm(path: Path) -> Arm:
    with path.open(encoding="utf-8", newline="") as f:
        rows = list(csv.DictReader(f))
    return Arm(np.array([float(r["t"]) for r in rows]),
               np.array([[float(r[f"q{i}"]) for i in range(1, 8)] for r in rows]),
               np.array([r["behaviour"] for r in rows]))


@pytest.fixture(scope="module")
def handover(tmp_path_factory: pytest.TempPathFactory) -> tuple[dict[str, Any], Arm, Arm]:
    """One handover cycle: `rssmc run ... --switches 5` (the giver back at fetch)."""
    out = tmp_path_factory.mktemp("handover")
    proc = rssmc("run", SPEC, "-o", out, "--switches", "5", "--format", "json")
    assert proc.returncode == 0, proc.stderr
    assert sorted(p.name for p in out.iterdir()) == [
        "joints.png", "summary.json", "trajectory_giver_E_arm.csv",
        "trajectory_taker_E_arm.csv"]
    return (json.loads(proc.stdout), _arm(out / "trajectory_giver_E_arm.csv"),
            _arm(out / "trajectory_taker_E_arm.csv"))


@needs_robot_data
def test_the_run_reports_both_arms(handover: tuple[dict[str, Any], Arm, Arm]) -> None:
    summary, giver, taker = handover
    assert summary["reason"] == "switches"
    arms = summary["arms"]
    assert [a["system_rig"] for a in arms] == [
        {"control": f"{x}.c", "effector": f"{x}.e.arm", "device": f"{x}.E.arm",
         "robot": "panda"} for x in ("giver", "taker")]
    assert [(s["from"], s["to"]) for s in arms[0]["switches"]] == [
        ("fetch", "offer"), ("offer", "release"), ("release", "back"), ("back", "pause"),
        ("pause", "fetch")]
    assert [(s["from"], s["to"]) for s in arms[1]["switches"]] == [
        ("wait", "approach"), ("approach", "grasp"), ("grasp", "hold"), ("hold", "leave"),
        ("leave", "wait")]
    for arm, series in zip(arms, (giver, taker), strict=True):
        # the stated bound (docs/devices.md): joint RMS under 2 mrad, max under 6 mrad
        assert arm["rms_error_rad"] < 2e-3 and arm["max_error_rad"] < 6e-3, arm
        assert arm["samples"] == len(series.t) > 6900
    # each arm went where the protocol sends it: the giver from pick to meet and back, the
    # taker from place to meet and back
    assert giver.dist("pick")[0] < STILL and giver.dist("pick")[-1] < REACH_TOL
    assert taker.dist("place")[0] < STILL and taker.dist("place")[-1] < REACH_TOL
    assert giver.dist("meet").min() < STILL and taker.dist("meet").min() < STILL


@needs_robot_data
def test_the_taker_moves_only_once_the_giver_is_at_the_meeting_pose(
        handover: tuple[dict[str, Any], Arm, Arm]) -> None:
    _, giver, taker = handover
    # the first sample where the taker has left its outfeed
    moved = int(np.flatnonzero(taker.dist("place") > STILL)[0])
    offered = giver.first("offer")
    assert giver.t[offered] <= taker.t[moved]
    # until then the taker held still, and when it moves the giver is at the meeting pose,
    # offering, and stays there (within reach_tol) until the taker holds the bar
    assert taker.t[moved] > 1.5               # the giver's move took that long
    held = taker.first("hold")
    k_from, k_to = np.searchsorted(giver.t, [taker.t[moved], taker.t[held]])
    assert set(giver.behaviour[k_from:k_to]) == {"offer"}
    assert giver.dist("meet")[k_from:k_to].max() < REACH_TOL


@needs_robot_data
def test_the_giver_lets_go_only_once_the_taker_holds_the_bar(
        handover: tuple[dict[str, Any], Arm, Arm]) -> None:
    _, giver, taker = handover
    released = giver.first("release")          # the giver opens its gripper
    back = giver.first("back")
    leaves = int(np.flatnonzero((giver.dist("meet") > STILL) & (giver.t > giver.t[released]))[0])
    held = taker.first("hold")
    assert taker.t[held] <= giver.t[released] < giver.t[back] <= giver.t[leaves]
    # all the while the gripper opens, the giver is at the meeting pose and the taker there,
    # holding the bar
    assert giver.dist("meet")[released:back].max() < REACH_TOL
    k_from, k_to = np.searchsorted(taker.t, [giver.t[released], giver.t[back]])
    assert set(taker.behaviour[k_from:k_to]) == {"hold"}
    assert taker.dist("meet")[k_from:k_to].max() < REACH_TOL


@needs_robot_data
def test_the_giver_comes_back_only_once_the_taker_is_clear(
        handover: tuple[dict[str, Any], Arm, Arm]) -> None:
    summary, giver, taker = handover
    # the run stopped at the giver's fifth switch, pause -> fetch: the next bar
    again = summary["arms"][0]["switches"][-1]
    assert (again["from"], again["to"]) == ("pause", "fetch")
    clear = taker.first("wait", after=taker.t[taker.first("leave")])
    assert taker.t[clear] <= again["time"]
    assert taker.dist("place")[clear:].max() < REACH_TOL
    assert set(giver.behaviour[giver.first("pause"):]) == {"pause"}


@needs_robot_data
def test_the_two_grippers_meet_at_the_bar_s_ends() -> None:
    # bases 1.3 m apart facing each other: the taker's base frame is the giver's turned by pi
    # about z and moved 1.3 m along x
    from stdlib.robots.dynamics import dynamics_of

    tcp = dynamics_of("panda").ee_position(C["meet"])
    giver_tcp = tcp
    taker_tcp = np.array([1.3 - tcp[0], -tcp[1], tcp[2]])
    assert np.allclose(taker_tcp - giver_tcp, [0.3, 0.0, 0.0], atol=2e-3)
    assert tcp[2] == pytest.approx(0.3, abs=1e-3)


def _verify(tmp_path: Path, edits: tuple[tuple[str, str], ...] = ()) -> dict[str, Any]:
    """`rssmc verify` of the example with its state invariants only (the response properties
    need the slice's full state space: docs/devices.md quotes that run), after ``edits``."""
    text = re.sub(r"\n  property \w+: whenever [^\n]*", "", SPEC.read_text(encoding="utf-8"))
    for old, new in edits:
        assert old in text
        text = text.replace(old, new)
    spec = tmp_path / SPEC.name
    spec.write_text(text, encoding="utf-8")
    proc = rssmc("verify", spec, "--format", "json")
    assert proc.returncode in (0, 1), proc.stderr
    return dict(json.loads(proc.stdout))


def test_the_protocol_s_invariants_hold(tmp_path: Path) -> None:
    report = _verify(tmp_path)
    assert report["verdict"] == "verified", report["verdict"]
    assert {p["name"]: p["holds"] for p in report["user_properties"]} == {
        "taker_waits_for_the_offer": True, "released_only_when_held": True,
        "one_arm_enters_at_a_time": True}


@pytest.mark.parametrize(("edit", "broken"), [
    # a taker that goes as soon as it is ready, offered or not
    (("terminal told when offering", "terminal told when true"),
     "taker_waits_for_the_offer"),
    # a giver that lets go as soon as the taker is on its way
    (("terminal taken when taker == TakerState.holding",
      "terminal taken when taker != TakerState.clear"), "released_only_when_held"),
])
def test_a_broken_protocol_violates_its_property(tmp_path: Path, edit: tuple[str, str],
                                                 broken: str) -> None:
    report = _verify(tmp_path, (edit,))
    assert report["verdict"] == "violated"
    holds = {p["name"]: p["holds"] for p in report["user_properties"]}
    assert holds[broken] is False, holds
