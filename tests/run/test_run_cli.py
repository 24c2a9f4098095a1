"""`rssmc run` end to end, as a subprocess like a user runs it: the paper's experiment on the
simulated LWR4+ completes a clockwise and a counter-clockwise circle, tracks them within the
bounds, and writes what it says it writes."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np

from rssm_dsl.interp.trace import read_trace
from tests.conftest import EXAMPLES
from tests.run.conftest import LWR4, Run, read_csv, rssmc

CENTRE = (0.53, 0.0)       # the example's circle: r = 0.05 m, phase 0 at (0.58, 0, 0.40) m
RADIUS = 0.05


def kasa_fit(xy: np.ndarray) -> tuple[float, float, float]:
    """Least-squares circle through points: centre x, centre y, radius."""
    x, y = xy[:, 0], xy[:, 1]
    a = np.column_stack([2 * x, 2 * y, np.ones_like(x)])
    (cx, cy, c), *_ = np.linalg.lstsq(a, x * x + y * y, rcond=None)
    return float(cx), float(cy), float(math.sqrt(c + cx * cx + cy * cy))


def test_the_example_completes_cw_then_ccw_with_the_switches_in_the_trace(
        default_run: Run) -> None:
    s = default_run.summary
    assert s["reason"] == "switches", s["message"]
    assert [(w["from"], w["to"]) for w in s["switches"]] == [("cw", "ccw"), ("ccw", "cw")]
    # each circle takes 2.0 s at 100 Hz (201 iterations with the phase's rounding)
    assert [round(w["time_s"], 2) for w in s["switches"]] == [2.0, 4.0]
    events = read_trace(default_run.trace)
    switches = [(e["subsystem"], e["from"], e["to"], e["time"]) for e in events
                if e["event"] == "switch"]
    assert [x[:3] for x in switches] == [("a1.c", "cw", "ccw"), ("a1.c", "ccw", "cw")]
    assert [x[3] for x in switches] == [w["time_s"] for w in s["switches"]]
    assert any(e["event"] == "enter" and e["subsystem"] == "a1.c" and e["behaviour"] == "cw"
               for e in events)
    end = events[-1]
    assert end["event"] == "end" and end["reason"] == "switches"
    # the set points went from c to e and the torques from e to the robot all along
    sends = {e["channel"] for e in events if e["event"] == "send"}
    assert sends == {"a1.c.cmd->a1.e.lwr.setpoint", "a1.e.lwr.torque->a1.E.lwr.torque",
                     "a1.E.lwr.state->a1.e.lwr.state"}


def test_tracking_error_stays_under_the_bounds(default_run: Run) -> None:
    s = default_run.summary
    assert 0.0 < s["rms_error_m"] < 1.0e-3
    assert s["max_error_m"] < 8.0e-3          # the reversal at speed (paper's c) is the worst
    traj = read_csv(default_run.out / "trajectory.csv")
    err = np.linalg.norm(traj.desired - traj.actual, axis=1)
    assert np.allclose(err, traj.error, atol=2e-9)
    assert math.isclose(float(np.sqrt(np.mean(err**2))), s["rms_error_m"], rel_tol=1e-5)
    assert len(traj.t) == s["samples"] and s["device_steps"] >= len(traj.t)
    assert np.allclose(np.diff(traj.t), 1e-3)   # one sample per 1 kHz device step
    assert s["simulated_s"] > 4.0 and s["real_time_factor"] > 0


def test_outputs_exist_and_the_plotted_data_is_the_circle(default_run: Run) -> None:
    out = default_run.out
    assert sorted(p.name for p in out.iterdir()) == ["fig19.png", "summary.json",
                                                     "trajectory.csv"]
    png = (out / "fig19.png").read_bytes()
    assert png.startswith(b"\x89PNG\r\n\x1a\n") and len(png) > 20_000
    assert json.loads((out / "summary.json").read_text())["rms_error_m"] == \
        default_run.summary["rms_error_m"]
    traj = read_csv(out / "trajectory.csv")
    cx, cy, r = kasa_fit(traj.actual[:, :2])
    assert math.hypot(cx - CENTRE[0], cy - CENTRE[1]) < 1e-3
    assert abs(r - RADIUS) < 1e-3
    assert np.abs(traj.actual[:, 2] - 0.40).max() < 1e-3      # a horizontal circle
    dist = np.hypot(traj.actual[:, 0] - cx, traj.actual[:, 1] - cy)
    assert np.abs(dist - r).max() < 2e-3
    # clockwise while c is in cw, counter-clockwise in ccw: one whole turn each
    behaviour = np.array(traj.behaviour)
    angle = np.unwrap(np.arctan2(traj.actual[:, 1] - cy, traj.actual[:, 0] - cx))
    for name, sign in (("cw", -1.0), ("ccw", 1.0)):
        rows = np.flatnonzero(behaviour == name)
        block = rows[rows < np.flatnonzero(behaviour == "ccw")[-1] + 1]   # the first cw
        turned = angle[block[-1]] - angle[block[0]]
        assert sign * turned > 2 * math.pi - 0.1, (name, turned)
    assert behaviour[0] == "cw" and "ccw" in behaviour


def test_the_paper_damping_tracks_worse(default_run: Run, tmp_path: Path) -> None:
    r = rssmc("run", LWR4, "-o", tmp_path / "paper", "--damping", "paper", "--format", "json")
    assert r.returncode == 0, r.stderr
    paper = json.loads(r.stdout)
    assert paper["effector_params"]["damp_velocity_error"] is False
    assert default_run.summary["effector_params"]["damp_velocity_error"] is True
    assert [w["to"] for w in paper["switches"]] == ["ccw", "cw"]
    assert paper["rms_error_m"] > 3 * default_run.summary["rms_error_m"]


def test_a_run_without_trace_is_the_same_run(default_run: Run, tmp_path: Path) -> None:
    r = rssmc("run", LWR4, "-o", tmp_path / "plain", "-q")
    assert r.returncode == 0 and r.stdout == "", r.stderr
    assert (tmp_path / "plain" / "trajectory.csv").read_bytes() == \
        (default_run.out / "trajectory.csv").read_bytes()


def test_text_summary_default_output_folder_and_viewer_without_display(
        tmp_path: Path) -> None:
    r = rssmc("run", LWR4, "--until", "0.2", "--switches", "0", "--viewer", cwd=tmp_path,
              env={"DISPLAY": "", "WAYLAND_DISPLAY": ""})
    assert r.returncode == 0, r.stderr
    assert "W872" in r.stderr and "no display" in r.stderr      # and the run went on
    for word in ("simulated  0.200 s", "real time", "tracking   RMS", "switches   a1.c: none",
                 "damp_velocity_error = true", "out/lwr4_circle-run"):
        assert word in r.stdout, (word, r.stdout)
    assert (tmp_path / "out" / "lwr4_circle-run" / "fig19.png").is_file()
    assert len(read_csv(tmp_path / "out" / "lwr4_circle-run" / "trajectory.csv").t) == 200


NO_DAMPING_PARAM = """import std.types
import lwr4plus

system hold {
  agent a1 {
    control c @ 100 Hz {
      output cmd: CartesianSetpoint to e.lwr nonblocking
      behaviour stay {
        update cmd {
          cmd := lwr4_start
        }
        terminal never when false
        send cmd
      }
      initial stay
    }
    effector lwr @ 1 kHz {
      input setpoint: CartesianSetpoint from c nonblocking
      input state: LwrState from E.lwr nonblocking
      output torque: JointVec7 to E.lwr nonblocking
      behaviour move {
        update torque {
          case new(state):
            torque := impedance(state, setpoint, 3000.0, 100.0)
          otherwise:
            skip
        }
        terminal never when false
        send torque
        receive setpoint; state
      }
      initial move
    }
    real effector lwr: LWR4Plus
  }
}
"""


def test_another_rig_runs_but_cannot_take_damping(tmp_path: Path) -> None:
    spec = tmp_path / "hold.rssm"
    spec.write_text(NO_DAMPING_PARAM, encoding="utf-8")
    r = rssmc("run", spec, "-o", tmp_path / "out", "--until", "0.3", "--format", "json")
    assert r.returncode == 0, r.stderr
    s = json.loads(r.stdout)
    assert s["reason"] == "until" and s["switches"] == [] and s["control"] == "a1.c"
    assert s["max_error_m"] < 1e-3              # holding the start pose
    r = rssmc("run", spec, "-o", tmp_path / "out2", "--damping", "paper")
    assert r.returncode == 2 and "E871" in r.stderr and "damp_velocity_error" in r.stderr
    assert not (tmp_path / "out2").exists()


def test_usage_and_specification_errors(tmp_path: Path) -> None:
    r = rssmc("run", LWR4, "--damping", "critical", "-o", tmp_path / "a")
    assert r.returncode == 2 and "--damping must be" in r.stderr
    r = rssmc("run", LWR4, "--video", tmp_path / "v.avi", "-o", tmp_path / "a")
    assert r.returncode == 2 and "MP4" in r.stderr
    r = rssmc("run", EXAMPLES / "relay_blocking.rssm", "-o", tmp_path / "a")
    assert r.returncode == 1 and "E870" in r.stderr and "LWR4+" in r.stderr
    assert "Traceback" not in r.stderr
    assert not (tmp_path / "a").exists()
