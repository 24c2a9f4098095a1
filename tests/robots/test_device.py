"""The generic MuJoCo arm device (stdlib/robots/device.py) against real MuJoCo models: what it
measures is what MuJoCo computes, the torques it is sent are what MuJoCo applies, and two
instances of one device type in one specification get their own robots."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import mujoco
import numpy as np
import pytest

from rssm_dsl.interp import SimOptions, Simulator
from tests.robots.conftest import runtime, write_robots, write_spec


def _device(rt: Any, name: str) -> Any:
    return rt.devices[f"a1.E.{name}"].impl


def test_two_instances_get_their_own_robots(tmp_path: Path) -> None:
    rt = runtime(write_spec(write_robots(tmp_path)))
    left, right = _device(rt, "left"), _device(rt, "right")
    try:
        assert left.robot.name == "short" and right.robot.name == "long"
        assert left.robot.model == (tmp_path / "models" / "short.xml").resolve()
        # each starts at its own q0, with its own link length: the tip where MuJoCo puts it
        assert np.allclose(left.state["q"], [0.3, 0.5])
        assert np.allclose(right.state["q"], [-0.2, 0.1])
        for dev, l1 in ((left, 0.3), (right, 0.5)):
            q1, q2 = dev.state["q"]
            # rotation about +y: a vector (0, 0, l) goes to (l sin q, 0, l cos q)
            x = l1 * np.sin(q1) + 0.3 * np.sin(q1 + q2)
            z = 0.5 + l1 * np.cos(q1) + 0.3 * np.cos(q1 + q2)
            assert np.allclose(dev.state["position"], [x, 0.0, z], atol=1e-12)
        assert np.allclose(right.torque_high, [5.0, 3.0])      # the table's limits
        assert np.all(np.isinf(left.torque_high))              # none for `short`
    finally:
        rt.close_devices()


def test_sensors_read_back_what_mujoco_says(tmp_path: Path) -> None:
    rt = runtime(write_spec(write_robots(tmp_path), tau=(1.5, -0.5)))
    seen: list[tuple[float, np.ndarray[Any, Any]]] = []
    left = _device(rt, "left")
    left.observers.append(lambda dev: seen.append((dev.time, dev.tau.copy())))
    result = Simulator(rt, SimOptions(seed=0, until=0.2)).run()
    assert result.ok, result.message
    try:
        for name in ("left", "right"):
            dev = _device(rt, name)
            m, d = dev.model, dev.data
            s = dev.state
            assert np.array_equal(s["q"], d.qpos) and np.array_equal(s["dq"], d.qvel)
            assert np.array_equal(s["position"], d.site_xpos[dev.site_id])
            jac = np.zeros((3, m.nv))
            mujoco.mj_jacSite(m, d, jac, None, dev.site_id)
            assert np.allclose(s["velocity"], jac @ d.qvel, atol=1e-12)
            assert np.linalg.norm(s["dq"]) > 0.1              # the arm moved
            assert d.time == pytest.approx(0.2, abs=2e-3)      # 1 ms steps for 0.2 s
        # the torques sent are applied (the right arm's limits clip nothing here)
        right = _device(rt, "right")
        assert np.allclose(right.data.ctrl, [1.5, -0.5])
        assert np.allclose(right.data.qfrc_actuator, [1.5, -0.5])
        assert any(np.allclose(tau, [1.5, -0.5]) for _, tau in seen)
    finally:
        rt.close_devices()


def test_torques_are_clipped_to_the_limits(tmp_path: Path) -> None:
    rt = runtime(write_spec(write_robots(tmp_path), tau=(50.0, -50.0)))
    assert Simulator(rt, SimOptions(seed=0, until=0.05)).run().ok
    try:
        assert np.allclose(_device(rt, "right").data.qfrc_actuator, [5.0, -3.0])
        assert np.allclose(_device(rt, "left").data.qfrc_actuator, [50.0, -50.0])
    finally:
        rt.close_devices()


def test_urdf_robot(tmp_path: Path) -> None:
    rt = runtime(write_spec(write_robots(tmp_path), right="(robot = Bot.urdf_arm)"))
    right = _device(rt, "right")
    try:
        q1, q2 = 0.4, -0.6
        assert np.allclose(right.state["q"], [q1, q2])
        # the fixed tool link kept as a body: the end effector 0.3 m past the elbow
        x = 0.4 * np.sin(q1) + 0.3 * np.sin(q1 + q2)
        z = 0.5 + 0.4 * np.cos(q1) + 0.3 * np.cos(q1 + q2)
        assert np.allclose(right.state["position"], [x, 0.0, z], atol=1e-12)
        assert np.allclose(right.torque_high, [30.0, 20.0])   # the URDF's effort limits
        assert np.allclose(right.model.dof_armature, [0.01, 0.01])
    finally:
        rt.close_devices()
