"""`rssmc simulate` end to end, as a subprocess like a user would run it."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from rssm_dsl.hpn.flatten import flatten
from rssm_dsl.interp.trace import read_trace
from rssm_dsl.verify import VerifyOptions, verify
from tests.conftest import sigint_default
from tests.interp.conftest import EXAMPLES, LWR_STATE, ROOT, SPECS, compiled

CONSTANT = "a1.E.lwr=rssm_stdlib.devices.constant:ConstantDevice"


def rssmc(*args: str | Path, cwd: Path | None = None) -> subprocess.CompletedProcess[str]:
    return subprocess.run([sys.executable, "-m", "rssm_dsl", *map(str, args)], cwd=cwd or ROOT,
                          capture_output=True, text=True, timeout=120)


def test_simulate_lwr4_with_a_trace(tmp_path: Path) -> None:
    trace = tmp_path / "t.jsonl"
    r = rssmc("simulate", EXAMPLES / "lwr4_circle.rssm", "--until", "0.1", "--device", CONSTANT,
              "--device-option", f"a1.E.lwr:values={json.dumps({'state': LWR_STATE})}",
              "--trace", trace)
    assert r.returncode == 0, r.stderr
    assert "a1.e.lwr  move" in r.stdout and "i=101" in r.stdout
    assert "reached t = 0.1 s" in r.stderr and "events written" in r.stderr
    events = read_trace(trace)
    assert events[0]["event"] == "start" and events[-1]["event"] == "end"
    kinds = {e["event"] for e in events}
    assert {"fire", "enter", "send", "receive"} <= kinds
    fire = next(e for e in events if e["event"] == "fire")
    assert fire["transition"].startswith("t") and ".rssm:" in fire["span"]


MOTOR = """
device effector Motor {
  input command: float nonblocking
  output angle: float nonblocking
  binding "no_such_module_here:Motor"
}
system s {
  agent a1 {
    control c { output goal: float to e.m nonblocking
      behaviour b { update goal { goal := 1.0 } terminal never when false } initial b }
    effector m {
      input goal: float from c nonblocking
      input angle: float from E.motor nonblocking
      output command: float to E.motor nonblocking
      behaviour b { update command { command := goal - angle } terminal never when false }
      initial b
    }
    real effector motor: Motor
  }
}
"""


def test_missing_device_binding_is_a_clean_e801(tmp_path: Path) -> None:
    spec = tmp_path / "motor.rssm"
    spec.write_text(MOTOR)
    r = rssmc("simulate", spec, "--steps", "10")
    assert r.returncode == 1 and "Traceback" not in r.stderr
    assert "[E801]" in r.stderr and "--device a1.E.motor=" in r.stderr
    assert "real effector motor: Motor" in r.stderr            # the spec line is shown
    r = rssmc("simulate", spec, "--steps", "200", "--device",
              "a1.E.motor=rssm_stdlib.devices.echo:EchoDevice")
    assert r.returncode == 0 and "stopped after 200 firings" in r.stderr


def test_usage_errors() -> None:
    r = rssmc("simulate", EXAMPLES / "relay_blocking.rssm", "--device", "a9.E.x=m:C")
    assert r.returncode == 2 and "no device a9.E.x" in r.stderr
    r = rssmc("simulate", EXAMPLES / "relay_blocking.rssm", "--mode", "fast")
    assert r.returncode == 2
    r = rssmc("simulate", EXAMPLES / "relay_blocking.rssm", "--replay", "/nonexistent.json")
    assert r.returncode == 2 and "cannot read" in r.stderr


def test_deadlock_exit_code_and_json(tmp_path: Path) -> None:
    r = rssmc("simulate", SPECS / "handshake_deadlock.rssm", "--until", "1", "-f", "json")
    assert r.returncode == 3          # the run cannot go on (not an error of the spec)
    out = json.loads(r.stdout)
    assert out["reason"] == "deadlock" and out["diagnostics"][0]["code"] == "E805"
    assert "p[1,c,greet,snd,1,wait]" in out["marking"]
    assert {w["subsystem"] for w in out["waiting"]} == {"a1.c", "a2.c"}


def test_controllers_that_block_each_other_while_the_rest_runs_are_reported(
        tmp_path: Path) -> None:
    """Two controllers send to each other in blocking mode before receiving: they freeze at
    once while their effectors and motors tick on at 100 Hz (no global deadlock). The run
    stops after 5 periods of the slowest subsystem (10 Hz: 0.5 s), names both controllers,
    their behaviours and the buffers they wait on, writes the trace up to there, exits 3."""
    trace = tmp_path / "t.jsonl"
    r = rssmc("simulate", EXAMPLES / "handover_stall.rssm", "--until", "30", "--trace", trace,
              "-f", "json")
    assert r.returncode == 3, r.stderr
    out = json.loads(r.stdout)
    assert out["reason"] == "stalled" and out["time"] == 0.5
    [diag] = [d for d in out["diagnostics"] if d["code"] == "E809"]
    assert "giver.c (hold) waits in blocking send of ready" in diag["message"]
    assert "taker.c (wait) waits in blocking send of ready" in diag["message"]
    assert diag["span"]["line"] == 12                        # `output ready: ...` of giver.c
    assert any(x["span"]["line"] == 40 for x in diag["related"])   # and of taker.c
    assert {w["subsystem"] for w in out["waiting"]} == {"giver.c", "taker.c"}
    events = read_trace(trace)
    assert [e["event"] for e in events[-2:]] == ["stalled", "end"]
    assert events[-1]["reason"] == "stalled"
    # the effectors did run meanwhile: this is no deadlock
    arms = {s["id"]: s["i"] for s in out["summary"]["subsystems"]}
    assert arms["giver.e.arm"] >= 50 and arms["giver.c"] == 0
    # a longer allowance: the same stall, later; 0 turns the watch off (the bound ends it)
    r = rssmc("simulate", EXAMPLES / "handover_stall.rssm", "--until", "30", "--stall-periods",
              "20", "-f", "json")
    assert r.returncode == 3 and json.loads(r.stdout)["time"] == 2.0
    r = rssmc("simulate", EXAMPLES / "handover_stall.rssm", "--until", "3", "--stall-periods",
              "0", "-q")
    assert r.returncode == 0, r.stderr
    # the concurrent mode watches too (wall-clock periods)
    r = rssmc("simulate", EXAMPLES / "handover_stall.rssm", "--mode", "concurrent", "--until",
              "20", "-f", "json")
    assert r.returncode == 3, r.stderr
    out = json.loads(r.stdout)
    assert out["reason"] == "stalled"      # before the bound: the effectors worked meanwhile


def test_a_process_that_gets_no_cpu_is_not_stalled() -> None:
    """A busy machine, made certain: the concurrent run is stopped (SIGSTOP) for 1 s, twenty
    times the stall allowance of relay_blocking (5 periods of 100 Hz). Wall-clock time passed
    but nothing ran, no other subsystem either: no stall (E809), the run reaches its bound."""
    p = subprocess.Popen([sys.executable, "-m", "rssm_dsl", "simulate",
                          str(EXAMPLES / "relay_blocking.rssm"), "--mode", "concurrent",
                          "--until", "4", "-f", "json"], cwd=ROOT, stdout=subprocess.PIPE,
                         stderr=subprocess.PIPE, text=True)
    time.sleep(1.5)             # started (imports done on an idle machine), then frozen
    p.send_signal(signal.SIGSTOP)
    time.sleep(1.0)
    p.send_signal(signal.SIGCONT)
    out, err = p.communicate(timeout=60)
    assert p.returncode == 0, err
    assert json.loads(out)["reason"] == "until"


def test_a_consumer_that_ends_starves_its_blocking_producer(tmp_path: Path) -> None:
    """x switches to `end` after 3 values; c then waits for ever in its blocking send to x
    while y runs on: c is stalled (x has ended: it is not)."""
    r = rssmc("simulate", SPECS / "starve.rssm", "-f", "json")
    assert r.returncode == 3, r.stderr
    out = json.loads(r.stdout)
    assert out["reason"] == "stalled"
    [diag] = [d for d in out["diagnostics"] if d["code"] == "E809"]
    assert diag["message"].startswith("1 subsystem(s) stalled")
    assert "a1.c (run) waits in blocking send of to_x" in diag["message"]
    assert "a1.e.x" not in [w["subsystem"] for w in out["waiting"]]


def test_a_slow_producer_is_no_stall(tmp_path: Path) -> None:
    """A 100 Hz consumer that receives, blocking, from a 1 Hz producer waits 100 of its own
    periods for each value: the system's rhythm, not a stall (the allowance counts periods
    of the slowest paced subsystem)."""
    spec = tmp_path / "slow.rssm"
    spec.write_text(SLOW)
    r = rssmc("simulate", spec, "--until", "8", "-f", "json")
    assert r.returncode == 0, r.stdout
    out = json.loads(r.stdout)
    assert out["reason"] == "until"


def test_a_run_without_a_bound_stops_at_the_default_one(tmp_path: Path) -> None:
    spec = tmp_path / "slow.rssm"
    spec.write_text(SLOW)
    r = rssmc("simulate", spec, "-f", "json")
    assert r.returncode == 0
    out = json.loads(r.stdout)
    assert out["reason"] == "until" and out["time"] == 60.0
    assert "default bound" in out["message"]


SLOW = """
system slow {
  agent a {
    control c @ 1 Hz {
      memory k: int = 0
      output v: int to e.fast blocking
      behaviour tick {
        update v { v := k }
        update memory { k := k + 1 }
        terminal never when false
      }
      initial tick
    }
    effector fast @ 100 Hz {
      input v: int from c blocking
      memory last: int = 0
      behaviour take {
        update memory { last := v }
        terminal never when false
      }
      initial take
    }
  }
}
"""


def test_replay_of_a_verifier_report(tmp_path: Path) -> None:
    comp = compiled(SPECS / "handshake_deadlock.rssm")
    assert comp.hpn is not None
    report = verify(flatten(comp.hpn), VerifyOptions(check_progress=False))
    path = tmp_path / "report.json"
    path.write_text(json.dumps(report.to_json()))
    r = rssmc("simulate", SPECS / "handshake_deadlock.rssm", "--replay", path)
    assert r.returncode == 1, r.stderr
    assert "replay: deadlock reproduced" in r.stderr and "[E805]" in r.stderr


def test_concurrent_mode_runs_on_the_wall_clock() -> None:
    t0 = time.monotonic()
    r = rssmc("simulate", EXAMPLES / "relay_blocking.rssm", "--mode", "concurrent",
              "--until", "0.5", "-f", "json")
    assert r.returncode == 0, r.stderr
    out = json.loads(r.stdout)
    assert out["reason"] == "until" and out["time"] >= 0.5
    assert time.monotonic() - t0 >= 0.5
    a1 = next(s for s in out["summary"]["subsystems"] if s["id"] == "a1.c")
    assert 10 <= a1["i"] <= 52            # 100 Hz for 0.5 s (loaded machines lag behind)


def test_ctrl_c_flushes_the_trace(tmp_path: Path) -> None:
    trace = tmp_path / "t.jsonl"
    p = subprocess.Popen([sys.executable, "-m", "rssm_dsl", "simulate",
                          str(EXAMPLES / "relay_blocking.rssm"), "--mode", "concurrent",
                          "--trace", str(trace)], cwd=ROOT, stdout=subprocess.PIPE,
                         stderr=subprocess.PIPE, text=True,
                         preexec_fn=sigint_default)
    deadline = time.monotonic() + 30
    while (not trace.exists() or trace.stat().st_size == 0) and time.monotonic() < deadline:
        time.sleep(0.1)
    time.sleep(0.5)
    p.send_signal(signal.SIGINT)
    _, err = p.communicate(timeout=30)
    assert p.returncode == 130, err
    assert "interrupted" in err and "Traceback" not in err
    events = read_trace(trace)
    assert events[-1]["event"] == "end" and events[-1]["reason"] == "interrupted"
    assert os.path.getsize(trace) > 0


def test_device_patterns_and_the_live_summary(tmp_path: Path) -> None:
    from rssm_dsl.synth import ring_system

    spec = tmp_path / "ring2.rssm"
    spec.write_text(ring_system(2))
    r = rssmc("simulate", spec, "--until", "30", "--device", "*.E.*=rssm_stdlib.devices.echo:"
              "EchoDevice", "--live")
    assert r.returncode == 0, r.stderr
    assert "\x1b[" in r.stderr and "system ring2:" in r.stderr      # redrawn in place
    assert "device a2.E.right" in r.stdout
    r = rssmc("simulate", spec, "--device", "*.R.*=m:C")
    assert r.returncode == 2 and "no device *.R.*" in r.stderr


@pytest.mark.parametrize("steps", [["t[nope]"], ["t[in]", "t[in]"]], ids=["unknown", "not-enabled"])
def test_a_replay_that_diverges_reproduces_nothing(tmp_path: Path, steps: list[str]) -> None:
    """A step that is no transition of the net, or is not enabled, is E806: the replay
    reproduces nothing, exit 2 (1 would say a violation was reproduced)."""
    path = tmp_path / "r.json"
    path.write_text(json.dumps(steps), encoding="utf-8")
    r = rssmc("simulate", EXAMPLES / "relay_blocking.rssm", "--replay", path, "-q")
    assert r.returncode == 2, r.stderr
    assert "E806" in r.stderr


def test_one_stall_period_is_refused_two_see_no_false_stall() -> None:
    """A subsystem at the slowest rate completes each iteration at its next tick: one
    period would call it stalled (E890, exit 2); two see the relay run on (exit 0)."""
    r = rssmc("simulate", EXAMPLES / "relay_blocking.rssm", "--stall-periods", "1")
    assert r.returncode == 2 and "E890" in r.stderr, r.stderr
    r = rssmc("simulate", EXAMPLES / "relay_blocking.rssm", "--stall-periods", "2",
              "--until", "2", "-q")
    assert r.returncode == 0, r.stderr
