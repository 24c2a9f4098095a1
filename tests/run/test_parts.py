"""The pieces of `rssmc run` in-process: the start pose and the circle agree, the MuJoCo
device's measurements and observers, finding the rig in a system, the circle fit."""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from rssm_dsl.bindings import resolve
from rssm_dsl.diagnostics import Diagnostic
from rssm_dsl.interp.device import DeviceSpec
from rssm_dsl.interp.values import converter
from rssm_dsl.pipeline import compile_file
from rssm_dsl.run.metrics import fit_circle
from rssm_dsl.run.rig import Rig, damping_param, find_rig
from tests.conftest import EXAMPLES
from tests.run.conftest import LWR4


def _device(frequency: float = 1000.0, **options: str) -> Any:
    cls = resolve("rssm_stdlib.lwr4plus.device:MujocoLwr4Device", [])
    assert isinstance(cls, type)
    return cls(DeviceSpec("a1.E.lwr", "lwr", "LWR4Plus", "effector", frequency, {}, {}, {},
                          options=options, base_dir=Path(".")))


def test_start_pose_circle_start_and_lwr4_start_are_one_point() -> None:
    device = _device()
    ops = np.asarray(resolve("rssm_stdlib.lwr4plus.ops:CIRCLE_START", []))
    dynamics = resolve("rssm_stdlib.lwr4plus.dynamics:default_dynamics", [])
    assert callable(dynamics)
    q0 = resolve("rssm_stdlib.lwr4plus.device:START_POSE", [])
    pin_position = dynamics().ee_position(q0)
    assert np.abs(device.state["position"] - ops).max() < 1e-9          # MuJoCo
    assert np.abs(pin_position - ops).max() < 1e-9                        # Pinocchio
    comp = compile_file(LWR4)
    assert comp.system is not None
    const = next(c for c in comp.system.consts if c.name == "lwr4_start")
    text = comp.program.line(const.span.file, const.span.line)
    assert "[0.58, 0.0, 0.4]" in text and np.allclose(ops, [0.58, 0.0, 0.4], rtol=0, atol=0)
    rot = dynamics().data.oMf[dynamics().ee_frame_id].rotation
    assert np.allclose(rot[:, 2], [0.0, 0.0, -1.0], atol=1e-9)           # flange points down


def test_device_measures_read_only_state_and_calls_observers_before_each_step() -> None:
    device = _device()
    seen: list[tuple[float, np.ndarray[Any, Any]]] = []
    device.observers.append(lambda d: seen.append((float(d.arm.data.time),
                                                   d.state["position"])))
    lwr_state = converter(_lwr_state_type())
    tau = np.zeros(7)
    for _ in range(3):
        device.receive("torque", tau)           # no torque: the arm starts to fall
        device.step(0.001)
        state = device.measure()["state"]
        assert lwr_state(state) is not None
        for v in state.values():
            assert not v.flags.writeable and v.dtype == np.float64
    assert [round(t, 6) for t, _ in seen] == [0.0, 0.001, 0.002]
    assert float(device.arm.data.time) == pytest.approx(0.003)
    s = device.arm.state()                       # MuJoCo's own reading of the same instant
    state = device.measure()["state"]
    assert np.array_equal(state["q"], s.q) and np.array_equal(state["dq"], s.dq)
    assert np.array_equal(state["position"], s.ee_pos)
    assert np.allclose(state["velocity"], s.ee_vel, atol=1e-15)
    assert np.linalg.norm(state["velocity"]) > 0.0
    # each observer saw the state the step started from
    start = resolve("rssm_stdlib.lwr4plus.ops:CIRCLE_START", [])
    assert np.abs(seen[0][1] - start).max() < 1e-9
    assert not np.array_equal(seen[2][1], seen[0][1])


def test_device_steps_whole_model_steps_and_carries_the_rest() -> None:
    device = _device(frequency=400.0)            # 2.5 ms periods
    assert device.arm.timestep == 0.001
    device.step(0.0025)                          # 2 steps of 1 ms, 0.5 ms carried
    assert float(device.arm.data.time) == pytest.approx(0.002)
    device.step(0.0025)
    assert float(device.arm.data.time) == pytest.approx(0.005)
    fast = _device(frequency=2000.0)             # faster than the model: its own step
    assert fast.arm.timestep == 0.0005
    fast.step(0.0005)
    assert float(fast.arm.data.time) == pytest.approx(0.0005)


def test_device_options_start_pose_and_record(tmp_path: Path) -> None:
    q0 = [0.1, -0.5, 0.0, 1.2, 0.0, 0.5, 0.0]
    record = tmp_path / "arm.csv"
    device = _device(q0=",".join(map(str, q0)), record=str(record))
    assert np.allclose(device.state["q"], q0)
    device.step(0.001)
    device.measure()
    device.close()
    lines = record.read_text().splitlines()
    assert lines[0] == "t,q1,q2,q3,q4,q5,q6,q7,x,y,z" and len(lines) == 2
    assert float(lines[1].split(",")[0]) == pytest.approx(0.001)
    with pytest.raises(Exception, match="7 joint angles"):
        _device(q0="0.1,0.2")


def _lwr_state_type() -> Any:
    comp = compile_file(LWR4)
    assert comp.system is not None
    device = comp.system.devices()[0]
    return device.outputs[0].type


def test_find_rig_in_the_example_and_what_is_missing_elsewhere() -> None:
    comp = compile_file(LWR4)
    assert comp.system is not None
    rig = find_rig(comp.system)
    assert rig == Rig(device="a1.E.lwr", effector="a1.e.lwr", control="a1.c",
                      setpoint_channel="a1.c.cmd->a1.e.lwr.setpoint", has_velocity=True,
                      control_frequency=100.0, device_frequency=1000.0)
    assert damping_param(comp.system, rig)
    relay = compile_file(EXAMPLES / "relay_blocking.rssm")
    assert relay.system is not None
    missing = find_rig(relay.system)
    assert isinstance(missing, Diagnostic) and missing.code == "E870"


def test_fit_circle_recovers_a_circle_and_rejects_a_line() -> None:
    rng = np.random.default_rng(3)
    angles = rng.uniform(0.0, 2 * math.pi, 500)
    pts = np.column_stack([0.53 + 0.05 * np.cos(angles), -0.01 + 0.05 * np.sin(angles),
                           np.full(500, 0.4)])
    fit = fit_circle(pts)
    assert fit is not None
    assert fit.centre == pytest.approx((0.53, -0.01), abs=1e-12)
    assert fit.radius == pytest.approx(0.05, abs=1e-12) and fit.residual < 1e-12
    assert fit.height == pytest.approx(0.4) and fit.height_spread < 1e-12
    noisy = fit_circle(pts + rng.normal(0.0, 1e-4, pts.shape))
    assert noisy is not None and abs(noisy.radius - 0.05) < 5e-5
    assert 5e-5 < noisy.residual < 2e-4
    assert fit_circle(pts[:2]) is None


def test_cartesian_impedance_forms_and_the_scalar_gain_fast_path() -> None:
    ops_impedance = resolve("rssm_stdlib.lwr4plus.ops:impedance", [])
    cartesian = resolve("rssm_stdlib.lwr4plus.ops:cartesian_impedance", [])
    torque = resolve("rssm_stdlib.lwr4plus.dynamics:impedance_torque", [])
    assert callable(ops_impedance) and callable(cartesian) and callable(torque)
    rng = np.random.default_rng(8)
    q = np.asarray(resolve("rssm_stdlib.lwr4plus.device:START_POSE", [])) + \
        rng.normal(0.0, 0.1, 7)
    dq = rng.normal(0.0, 0.5, 7)
    state = {"q": q, "dq": dq, "position": np.zeros(3), "velocity": np.zeros(3)}
    sp = {"position": np.array([0.57, 0.02, 0.41]), "velocity": np.array([0.0, -0.15, 0.0])}
    velocity_error = cartesian(state, sp, 3000.0, 100.0, True)
    paper = cartesian(state, sp, 3000.0, 100.0, False)
    assert not velocity_error.flags.writeable and velocity_error.shape == (7,)
    assert np.array_equal(velocity_error, ops_impedance(state, sp, 3000.0, 100.0))
    # the general (matrix gain) path of the dynamics library gives the same torques
    eye = np.eye(3)
    for flag, tau in ((True, velocity_error), (False, paper)):
        general = torque(q, dq, sp["position"], sp["velocity"], 3000.0 * eye, 100.0 * eye, flag)
        assert np.allclose(tau, general, rtol=0.0, atol=1e-10)
    # the two forms differ by D J_v^T v_des
    dyn = resolve("rssm_stdlib.lwr4plus.dynamics:default_dynamics", [])
    assert callable(dyn)
    jv = dyn().jacobian(q)[:3]
    assert np.allclose(velocity_error - paper, jv.T @ (100.0 * sp["velocity"]), atol=1e-10)
