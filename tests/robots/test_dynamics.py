"""Pinocchio's dynamics of a described robot (stdlib/robots/dynamics.py) agree with MuJoCo's
simulation of the same description: gravity torque = qfrc_bias at zero velocity, bias with
velocity, mass matrix = mj_fullM (armature included), J dq = the site's velocity, the frame's
position = the site's."""

from __future__ import annotations

from pathlib import Path

import mujoco
import numpy as np
import pytest

from stdlib.robots.dynamics import RobotDynamics, dynamics_of
from stdlib.robots.model import RobotDescription, build_mujoco, ee_site_name, find_robot
from stdlib.robots.ops import gravity_torque, joint_pd_gravity, min_jerk_joints
from tests.robots.conftest import HAS_ROBOT_DATA, write_robots

ROBOTS = ["short", "urdf_arm", "lwr4plus",
          pytest.param("panda", marks=pytest.mark.skipif(
              not HAS_ROBOT_DATA,
              reason="example-robot-data is not installed: pip install 'rssmc[robots]'"))]


def _robot(name: str, folder: Path) -> RobotDescription:
    return find_robot(name, write_robots(folder))


@pytest.mark.parametrize("name", ROBOTS)
def test_pinocchio_agrees_with_mujoco(name: str, tmp_path: Path) -> None:
    robot = _robot(name, tmp_path)
    model, _, _ = build_mujoco(robot)
    data = mujoco.MjData(model)
    dyn = RobotDynamics(robot)
    n = robot.dof
    assert dyn.nv == n == model.nv
    site = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_SITE, ee_site_name(robot, model))
    rng = np.random.default_rng(7)
    low = np.where(model.jnt_limited, model.jnt_range[:, 0], -np.pi)
    high = np.where(model.jnt_limited, model.jnt_range[:, 1], np.pi)
    for _ in range(5):
        q = rng.uniform(low, high)
        dq = rng.uniform(-1.0, 1.0, n)
        data.qpos[:], data.qvel[:] = q, 0.0
        mujoco.mj_forward(model, data)
        scale = max(1.0, float(np.abs(data.qfrc_bias).max()))
        assert np.allclose(dyn.gravity(q), data.qfrc_bias, atol=1e-9 * scale)
        assert np.allclose(dyn.ee_position(q), data.site_xpos[site], atol=1e-9)
        full = np.zeros((n, n))
        mujoco.mj_fullM(model, data, full)
        assert np.allclose(dyn.mass_matrix(q), full, atol=1e-9)
        data.qvel[:] = dq
        mujoco.mj_forward(model, data)
        assert np.allclose(dyn.bias(q, dq), data.qfrc_bias, atol=1e-8 * scale)
        vel6 = np.zeros(6)
        mujoco.mj_objectVelocity(model, data, mujoco.mjtObj.mjOBJ_SITE, site, vel6, 0)
        jac = dyn.jacobian(q)
        assert np.allclose(jac[:3] @ dq, vel6[3:], atol=1e-9)
        assert np.allclose(jac[3:] @ dq, vel6[:3], atol=1e-9)


def test_gravity_is_not_trivially_zero(tmp_path: Path) -> None:
    dyn = RobotDynamics(_robot("short", tmp_path))
    # the short arm tilted by q1: gravity pulls it further, torque = -m g l sin q (about +y)
    g = dyn.gravity(np.array([0.5, 0.0]))
    expected = -9.81 * (2.0 * 0.15 + 1.0 * (0.3 + 0.15)) * np.sin(0.5)
    assert g[0] == pytest.approx(expected, rel=1e-9)


def test_operations(tmp_path: Path) -> None:
    write_robots(tmp_path)
    q = np.array([0.0, -0.599242668249, 0.0, 1.402190110099, 0.0, -1.14016, 0.0])
    g = gravity_torque("lwr4plus", q)
    assert np.array_equal(g, dynamics_of("lwr4plus").gravity(q)) and not g.flags.writeable
    state = {"q": q, "dq": np.zeros(7)}
    setpoint = {"q": q + 0.1, "dq": np.ones(7)}
    tau = joint_pd_gravity("lwr4plus", state, setpoint, np.full(7, 100.0), np.full(7, 10.0))
    assert np.allclose(tau, g + 100.0 * 0.1 + 10.0 * 1.0)
    a, b = np.zeros(7), np.arange(7.0)
    start, mid, end = (min_jerk_joints(a, b, 2.0, t) for t in (-1.0, 1.0, 5.0))
    assert np.array_equal(start["q"], a) and np.array_equal(end["q"], b)
    assert np.allclose(mid["q"], b / 2) and np.allclose(mid["dq"], 1.875 * b / 2.0)
    assert np.array_equal(end["dq"], np.zeros(7))
