"""Simulation as a falsifier (rssm_dsl.falsify): random runs find a stall the exhaustive
engines are starved of, the net confirms it, the report carries it in the verifier's words,
and `rssmc simulate --replay` reproduces it; nothing is found where there is nothing; the
same seed gives the same counterexample; a contradiction with a proof is never settled by
picking one side."""

from __future__ import annotations

import dataclasses
import json
import subprocess
import sys
from pathlib import Path
from typing import Any

import pytest

from rssm_dsl.falsify import Falsification, FalsifyOptions, falsify
from rssm_dsl.falsify.confirm import markings
from rssm_dsl.falsify.merge import apply
from rssm_dsl.falsify.runs import RANDOM_DEVICE
from rssm_dsl.hpn.flat import FlatNet, Role
from rssm_dsl.hpn.flatten import flatten
from rssm_dsl.interp.device import DeviceConfigError, DeviceSpec
from rssm_dsl.pipeline import Compilation, compile_file
from rssm_dsl.semantics.types import BOOL, FLOAT, EnumT, RangeT, RecordT
from rssm_dsl.verify import VerifyOptions, verify
from rssm_dsl.verify.budget import Budget
from rssm_dsl.verify.netbits import NetBits
from rssm_dsl.verify.report import Verdict
from tests.conftest import EXAMPLES, ROOT

SPECS = Path(__file__).parent / "specs"
RARE_END = SPECS / "rare_end.rssm"


def rssmc(*args: str | Path) -> subprocess.CompletedProcess[str]:
    return subprocess.run([sys.executable, "-m", "rssm_dsl", *map(str, args)], cwd=ROOT,
                          capture_output=True, text=True, timeout=600)


def compiled(path: Path) -> tuple[Compilation, FlatNet]:
    comp = compile_file(path)
    assert comp.ok and comp.hpn is not None
    return comp, flatten(comp.hpn)


def found(path: Path, **options: object) -> tuple[FlatNet, Falsification]:
    comp, net = compiled(path)
    opts = FalsifyOptions(**{"seconds": 30.0, **options})  # type: ignore[arg-type]
    return net, falsify(comp, net, Budget(60.0), opts)


# ---------------------------------------------------------------------- the random device
def random_device() -> Any:
    from rssm_dsl.bindings import resolve

    return resolve(RANDOM_DEVICE, [])


def _spec(outputs: dict[str, object], initial: dict[str, object],
          options: dict[str, str] | None = None) -> DeviceSpec:
    return DeviceSpec(id="a.R.d", name="d", device_type="D", kind="receptor", frequency=10.0,
                      inputs={}, outputs=outputs, initial=initial,  # type: ignore[arg-type]
                      options=options or {})


def test_random_device_draws_finite_parts_and_keeps_floats() -> None:
    RandomDevice = random_device()
    colour = EnumT("Colour", ("red", "green", "blue"))
    rec = RecordT("R", (("ok", BOOL), ("x", FLOAT)))
    dev = RandomDevice(_spec({"code": RangeT(0, 9), "c": colour, "r": rec, "f": FLOAT},
                             {"code": 0, "c": "red", "r": {"ok": False, "x": 1.5}, "f": 2.0}))
    seen = [dev.measure() for _ in range(200)]
    assert {m["code"] for m in seen} == set(range(10))
    assert {m["c"] for m in seen} == {"red", "green", "blue"}
    assert {m["r"]["ok"] for m in seen} == {False, True}
    assert {m["r"]["x"] for m in seen} == {1.5} and {m["f"] for m in seen} == {2.0}


def test_random_device_values_option_and_seed() -> None:
    RandomDevice = random_device()

    def draws(options: dict[str, str]) -> list[object]:
        dev = RandomDevice(_spec({"code": RangeT(0, 9), "f": FLOAT}, {"code": 0, "f": 0.0},
                                 options))
        return [dev.measure()["code"] for _ in range(50)]

    assert set(draws({"values": '{"code": [3, 7]}'})) == {3, 7}
    assert set(draws({"values": '{"code": 4}'})) == {4}
    assert draws({"seed": "5"}) == draws({"seed": "5"}) != draws({"seed": "6"})
    with pytest.raises(DeviceConfigError, match="code"):
        draws({"values": '{"code": [12]}'})
    with pytest.raises(DeviceConfigError, match="no output"):
        draws({"values": '{"nope": [1]}'})


# ---------------------------------------------------------------------- the falsifier
def test_a_stall_is_found_and_confirmed_as_the_verifier_would() -> None:
    net, result = found(RARE_END)
    f = result.finding
    assert f is not None and f.kind == "progress" and f.subsystem == "line.c"
    assert result.found_by is not None and result.found_by.reason == "stalled"
    nb = NetBits.of(net)
    # a lasso of the net: the prefix fires, the cycle comes back to its marking, and the
    # stalled consumer completes no iteration in it
    end = markings(nb, [*f.steps, *f.to_cycle])[-1]
    assert end == f.cycle_marking
    assert markings(nb, [*f.steps, *f.to_cycle, *f.cycle])[-1] == end
    assert not any(net.transitions[t].role is Role.ITERATION
                   and net.transitions[t].subsystem == "line.c" for t in f.cycle)
    assert "found a loss of progress of line.c" in result.text()


def test_same_seed_same_counterexample_other_seed_other_run() -> None:
    _, a = found(RARE_END, seed=3)
    _, b = found(RARE_END, seed=3)
    _, c = found(RARE_END, seed=4)
    assert a.finding is not None and a.finding == b.finding
    assert a.found_by is not None and b.found_by is not None and c.found_by is not None
    assert list(a.found_by.sequence) == list(b.found_by.sequence)
    assert list(a.found_by.sequence) != list(c.found_by.sequence)


def test_values_option_that_rules_out_the_rare_value_finds_nothing() -> None:
    _, result = found(RARE_END, seconds=0.5, max_runs=2,
                      device_options={"cell.R.*": {"values": '{"reading": [0, 1, 2]}'}})
    assert result.finding is None and result.runs >= 1
    assert "found nothing" in result.text()


def test_a_deadlock_is_found_and_confirmed() -> None:
    net, result = found(EXAMPLES / "verify" / "deadlock_pair.rssm")
    f = result.finding
    assert f is not None and f.kind == "deadlock"
    nb = NetBits.of(net)
    end = markings(nb, f.steps)[-1]
    assert end == f.marking and not nb.enabled(end) and not nb.is_final(end)


def test_a_cancelled_budget_makes_no_run() -> None:
    comp, net = compiled(RARE_END)
    budget = Budget(60.0)
    budget.cancel()
    result = falsify(comp, net, budget, FalsifyOptions())
    assert result.runs == 0 and result.finding is None


def test_a_contradiction_with_a_proof_is_reported_never_settled() -> None:
    """A verifier that proved progress while a confirmed run loses it: one of them has a
    bug. The verdict is not VERIFIED, not silently VIOLATED: INCONCLUSIVE with the note."""
    net, result = found(RARE_END)
    proved = dataclasses.replace(verify(net, VerifyOptions(max_states=10, reduction="off")),
                                 verdict=Verdict.VERIFIED, safe=True, deadlock_free=True,
                                 progress_ok=True)
    merged = apply(proved, net, result)
    assert merged.verdict is Verdict.INCONCLUSIVE
    assert merged.simulation is not None and merged.simulation.consistent is False
    assert any("INTERNAL INCONSISTENCY" in n for n in merged.notes)
    assert merged.to_json()["simulation"]["consistent"] is False


# ---------------------------------------------------------------------- the command
def test_verify_starved_of_states_reports_the_stall_and_it_replays(tmp_path: Path) -> None:
    r = rssmc("verify", RARE_END, "--max-states", "10", "--reduction", "off", "--format", "json")
    assert r.returncode == 1, r.stdout + r.stderr
    report = json.loads(r.stdout)
    assert report["verdict"] == "violated" and report["progress_ok"] is False
    assert report["simulation"]["found"] == "progress"
    assert report["simulation"]["consistent"] is True
    (cx,) = report["progress"]
    assert cx["subsystem"] == "line.c" and cx["cycle"]
    assert all(s["file"].endswith("rare_end.rssm") and s["line"] > 0 for s in cx["steps"])
    saved = tmp_path / "report.json"
    saved.write_text(r.stdout)
    replay = rssmc("simulate", RARE_END, "--replay", saved, "--format", "json")
    assert replay.returncode == 1, replay.stdout + replay.stderr   # reproduced
    assert json.loads(replay.stdout)["replay"]["reproduced"] is True

    text = rssmc("verify", RARE_END, "--max-states", "10", "--reduction", "off")
    assert "loss of progress: line.c never completes an iteration again" in text.stdout
    assert "simulation: 1 random run(s) (seed 0)" in text.stdout
    assert "(tests/falsify/specs/rare_end.rssm:39)" in text.stdout     # file:line of steps


def test_no_simulation_leaves_it_inconclusive() -> None:
    r = rssmc("verify", RARE_END, "--max-states", "10", "--reduction", "off", "--no-simulation", "--format", "json")
    assert r.returncode == 3, r.stdout + r.stderr
    assert json.loads(r.stdout)["simulation"] is None


def test_a_correct_spec_keeps_its_verdict_and_says_what_the_runs_did() -> None:
    spec = EXAMPLES / "verify" / "lockstep.rssm"
    off = json.loads(rssmc("verify", spec, "--no-simulation", "--format", "json").stdout)
    on = rssmc("verify", spec, "--format", "json")
    report = json.loads(on.stdout)
    assert on.returncode == 0 and report["verdict"] == off["verdict"] == "verified"
    sim = report["simulation"]
    assert sim["ran"] is True and sim["found"] is None and sim["consistent"] is True
    assert sim["runs"] >= 1 and sim["firings"] > 0 and "found nothing" in sim["text"]


def test_bad_device_option_is_a_usage_error() -> None:
    r = rssmc("verify", RARE_END, "--device-option", "nonsense")
    assert r.returncode == 2 and "--device-option" in r.stderr


@pytest.mark.parametrize("spec", ["rare_end.rssm", "rare_end_range.rssm"])
def test_the_exhaustive_engines_agree_with_the_runs(spec: str) -> None:
    """Whatever the runs find, the engines alone find too (the int condition is a free
    choice; the range's values are tracked in the state, the dial's draws included)."""
    _, runs = found(SPECS / spec)
    assert runs.finding is not None and runs.finding.subsystem == "line.c"
    r = rssmc("verify", SPECS / spec, "--no-simulation", "--format", "json")
    report = json.loads(r.stdout)
    assert report["verdict"] == "violated" and report["progress_ok"] is False, r.stdout


def test_the_seed_option_gives_the_same_counterexample_again() -> None:
    def counterexample(seed: str) -> object:
        r = rssmc("verify", RARE_END, "--max-states", "10", "--reduction", "off", "--seed", seed,
                  "--format", "json")
        sim = json.loads(r.stdout)["simulation"]
        assert sim["seed"] == int(seed) and sim["found"] == "progress", r.stdout
        return sim["counterexample"]

    assert counterexample("7") == counterexample("7")


def test_a_device_option_naming_no_device_is_a_usage_error() -> None:
    """As `rssmc simulate` says it: exit 2 and the devices there are, nothing verified."""
    root = Path(__file__).resolve().parents[2]
    run = subprocess.run([sys.executable, "-m", "rssm_dsl", "verify",
                          str(root / "examples" / "verify" / "handover.rssm"),
                          "--device-option", "nosuch:values=[1]"],
                         capture_output=True, text=True, cwd=root, timeout=300)
    assert run.returncode == 2, run.stdout + run.stderr
    assert "no device nosuch in system handover" in run.stderr
    assert "Traceback" not in run.stderr and run.stdout == ""
