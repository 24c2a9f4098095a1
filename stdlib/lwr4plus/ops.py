"""The operations of the LWR4+ controller, as the externs of lwr4plus.rssm bind them.

Records arrive as the interpreter represents them (dicts of read-only float64 arrays, see
rssm_dsl.interp.values) and results are returned the same way (read-only arrays).

* ``impedance(state, setpoint, stiffness, damping)``: the virtual effector's torque
  ``tau = g(q) + J_v(q)^T (K (p_des - p) + D (v_des - p_dot))`` with isotropic gains,
  computed by Pinocchio on the shipped model (dynamics.impedance_torque); ``p`` and ``p_dot``
  come from ``q``, ``dq`` through the model, the measured ``position``/``velocity`` of the
  state are not needed.
* ``cartesian_impedance(state, setpoint, stiffness, damping, damp_velocity_error)``: the same
  with the damping form chosen: ``D (v_des - p_dot)`` when ``damp_velocity_error`` is true,
  the paper's ``- D p_dot`` (tau = tau_grav + J^T (K dP - D dP/dt)) when it is false.
* ``circle_setpoint(radius, period, phase, direction)``: the point of a horizontal circle
  at ``phase`` (rad), travelled at ``2 pi / period`` rad/s, clockwise seen from above for
  ``direction = -1``, counter-clockwise for ``+1``. Phase 0 is :data:`CIRCLE_START`, the
  end-effector position of the experiment's start pose, so the circle starts where the arm is.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from rssm_core.values import freeze

from .dynamics import Vector, circle_point, circle_velocity, default_dynamics, impedance_torque

# Flange position (m, world) of the start pose of the experiment (bench/lwr4_handloop.py:
# elbow bent, flange pointing down): phase 0 of every circle; `lwr4_start` in lwr4plus.rssm.
CIRCLE_START: Vector = np.array([0.580, 0.0, 0.400])


def cartesian_impedance(state: Any, setpoint: Any, stiffness: float, damping: float,
                        damp_velocity_error: bool) -> Vector:
    """Joint torques (N·m) of the Cartesian impedance for an LwrState and a set point.

    Called at every iteration of the effector: the gains arrive as the interpreter's floats
    and the flag as its bool (impedance_torque takes any real gains and tests the flag's
    truth), and the result is made read-only in place (what ``freeze`` does, one call less)."""
    tau: Vector = impedance_torque(state["q"], state["dq"], setpoint["position"],
                                   setpoint["velocity"], stiffness, damping,
                                   damp_velocity_error, default_dynamics())
    tau.setflags(False)
    return tau


def impedance(state: Any, setpoint: Any, stiffness: float, damping: float) -> Vector:
    """:func:`cartesian_impedance` with velocity-error damping."""
    return cartesian_impedance(state, setpoint, stiffness, damping, True)


def circle_setpoint(radius: float, period: float, phase: float,
                    direction: float) -> dict[str, Vector]:
    """Position and velocity on the circle (see the module docstring)."""
    angle = direction * phase
    centre = CIRCLE_START - circle_point(np.zeros(3), radius, 0.0)
    rate = direction * 2.0 * math.pi / period
    return {"position": freeze(circle_point(centre, radius, angle)),
            "velocity": freeze(circle_velocity(radius, angle, rate))}
