"""The operations of robots.rssm: joint-space control and dynamics of a described robot.

``robot`` arrives as the enum member's name (``Robot.panda`` -> ``"panda"``) and names the
robot as :func:`~.dynamics.dynamics_of` finds it. States and set points are records (dicts of
read-only float64 arrays); results are fresh read-only arrays.

* ``joint_pd_gravity(robot, state, setpoint, kp, kd)``: ``tau = g(q) + kp (q_d - q) + kd (dq_d -
  dq)``, gains per joint, ``g`` by Pinocchio on the robot's model.
* ``gravity_torque(robot, q)``: ``g(q)``.
* ``ee_position(robot, q)``: the end-effector frame's position (m, world).
* ``min_jerk_joints(q_from, q_to, duration, t)``: the set point ``{q, dq}`` at ``t`` of the
  rest-to-rest minimum-jerk move from ``q_from`` to ``q_to`` in ``duration`` s (at ``q_from``
  before 0, at ``q_to`` after ``duration``).
"""

from __future__ import annotations

from typing import Any

import numpy as np

from .dynamics import Vector, dynamics_of


def _frozen(a: Vector) -> Vector:
    a.setflags(write=False)
    return a


def joint_pd_gravity(robot: str, state: Any, setpoint: Any, kp: Vector, kd: Vector) -> Vector:
    dyn = dynamics_of(robot)
    q = state["q"]
    with dyn.lock:
        tau = dyn.gravity(q)
    tau += kp * (setpoint["q"] - q) + kd * (setpoint["dq"] - state["dq"])
    return _frozen(tau)


def gravity_torque(robot: str, q: Vector) -> Vector:
    dyn = dynamics_of(robot)
    with dyn.lock:
        return _frozen(dyn.gravity(q))


def ee_position(robot: str, q: Vector) -> Vector:
    dyn = dynamics_of(robot)
    with dyn.lock:
        return _frozen(dyn.ee_position(q))


def min_jerk_joints(q_from: Vector, q_to: Vector, duration: float, t: float,
                    ) -> dict[str, Vector]:
    s = min(max(t / duration, 0.0), 1.0)
    shape = s * s * s * (10.0 - 15.0 * s + 6.0 * s * s)
    rate = 30.0 * s * s * (1.0 - s) * (1.0 - s) / duration
    delta = np.asarray(q_to, dtype=np.float64) - q_from
    return {"q": _frozen(q_from + shape * delta), "dq": _frozen(rate * delta)}
