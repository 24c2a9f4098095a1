"""LWR4+ dynamics operations computed with Pinocchio from the shipped MJCF model.

The controller runs these at 1 kHz, so every function does one or two Pinocchio calls and a few
small numpy operations. Vectors are ``float64`` numpy arrays; results are fresh arrays (callers
may keep them), the Pinocchio scratch data lives in a cached :class:`Lwr4Dynamics`.

Conventions: the Jacobian is 6x7, expressed in world-aligned axes at the end-effector site
(``pin.LOCAL_WORLD_ALIGNED``), rows ``[linear; angular]``. Circles: phase 0 is
``centre + radius * u`` where ``(u, v)`` are the plane's axes; a positive phase rate runs
counter-clockwise seen from the plane's positive normal ``u x v`` (for ``"xy"``: seen from
above), a negative one clockwise.
"""

from __future__ import annotations

import functools
import math
from pathlib import Path
from typing import Literal

import numpy as np
import pinocchio as pin  # type: ignore[import-untyped]
from numpy.typing import NDArray

Vector = NDArray[np.float64]
Matrix = NDArray[np.float64]
Gain = float | NDArray[np.float64]
"""A Cartesian gain: a scalar, a 3-vector (diagonal) or a 3x3 matrix."""

Plane = Literal["xy", "yz", "zx"]

MJCF_PATH: Path = Path(__file__).parent / "lwr4plus.xml"
EE_FRAME = "ee"

_AXES: dict[Plane, tuple[Vector, Vector]] = {
    "xy": (np.array([1.0, 0.0, 0.0]), np.array([0.0, 1.0, 0.0])),
    "yz": (np.array([0.0, 1.0, 0.0]), np.array([0.0, 0.0, 1.0])),
    "zx": (np.array([0.0, 0.0, 1.0]), np.array([1.0, 0.0, 0.0])),
}


class Lwr4Dynamics:
    """Pinocchio model and scratch data of the LWR4+ MJCF, with the operations we need."""

    __slots__ = ("data", "ee_frame_id", "model")

    def __init__(self, mjcf_path: Path = MJCF_PATH, ee_frame: str = EE_FRAME) -> None:
        self.model = pin.buildModelFromMJCF(str(mjcf_path))
        self.data = self.model.createData()
        if not self.model.existFrame(ee_frame):
            raise ValueError(f"{mjcf_path}: no frame {ee_frame!r}")
        self.ee_frame_id: int = self.model.getFrameId(ee_frame)

    @property
    def nv(self) -> int:
        return int(self.model.nv)

    def gravity(self, q: Vector) -> Vector:
        """Generalised gravity torques g(q) (N·m)."""
        return np.array(
            pin.computeGeneralizedGravity(self.model, self.data, q), dtype=np.float64
        )

    def jacobian(self, q: Vector) -> Matrix:
        """6 x nv end-effector Jacobian, world-aligned, rows [linear; angular]."""
        jac = pin.computeFrameJacobian(
            self.model, self.data, q, self.ee_frame_id, pin.LOCAL_WORLD_ALIGNED
        )
        return np.array(jac, dtype=np.float64)

    def ee_position(self, q: Vector) -> Vector:
        """Position of the end-effector site in the world frame (m)."""
        pin.forwardKinematics(self.model, self.data, q)
        placement = pin.updateFramePlacement(self.model, self.data, self.ee_frame_id)
        return np.array(placement.translation, dtype=np.float64)

    def ee_velocity(self, q: Vector, dq: Vector) -> Vector:
        """Linear velocity of the end-effector site in the world frame (m/s)."""
        return self.jacobian(q)[:3] @ dq

    def gravity_jacobian_position(self, q: Vector) -> tuple[Vector, Matrix, Vector]:
        """g(q), the 6 x nv Jacobian and the end-effector position in two Pinocchio calls."""
        g = self.gravity(q)
        jac = self.jacobian(q)  # computeFrameJacobian also updates data.oMf[ee]
        p = np.array(self.data.oMf[self.ee_frame_id].translation, dtype=np.float64)
        return g, jac, p


@functools.cache
def default_dynamics() -> Lwr4Dynamics:
    """The shared model of the shipped MJCF (built once per process)."""
    return Lwr4Dynamics()


def _apply_gain(gain: Gain, x: Vector) -> Vector:
    g = np.asarray(gain, dtype=np.float64)
    if g.ndim == 2:
        return g @ x
    return g * x


def cartesian_force(
    p: Vector,
    v: Vector,
    p_des: Vector,
    v_des: Vector,
    K: Gain,
    D: Gain,
    damp_velocity_error: bool = True,
) -> Vector:
    """Impedance force: K(p_des - p) + D(v_des - v), or the paper's K(p_des - p) - D v."""
    damped = v_des - v if damp_velocity_error else -v
    return _apply_gain(K, p_des - p) + _apply_gain(D, damped)


def impedance_torque(
    q: Vector,
    dq: Vector,
    p_des: Vector,
    v_des: Vector,
    K: Gain,
    D: Gain,
    damp_velocity_error: bool = True,
    dynamics: Lwr4Dynamics | None = None,
) -> Vector:
    """Joint torques tau = g(q) + J_v(q)^T F of a Cartesian position impedance.

    ``F = K (p_des - p) - D p_dot`` (the paper's form) when ``damp_velocity_error`` is false,
    ``F = K (p_des - p) + D (v_des - p_dot)`` otherwise; ``J_v`` is the linear 3 x nv block.
    """
    dyn = dynamics if dynamics is not None else default_dynamics()
    model, data, frame = dyn.model, dyn.data, dyn.ee_frame_id
    # One RNEA for g(q) and one Jacobian (which also places the frame); both results are
    # views into the scratch data, used before the next Pinocchio call overwrites them.
    g = pin.computeGeneralizedGravity(model, data, q)
    jv = pin.computeFrameJacobian(model, data, q, frame, pin.LOCAL_WORLD_ALIGNED)[:3]
    p = data.oMf[frame].translation
    v = jv @ dq
    if isinstance(K, float | int) and isinstance(D, float | int):
        # scalar gains (the common case): no gain-shape dispatch
        damped = v_des - v if damp_velocity_error else -v
        force = K * (p_des - p) + D * damped
    else:
        force = cartesian_force(p, v, p_des, v_des, K, D, damp_velocity_error)
    tau: Vector = g + jv.T @ force
    return tau


def circle_point(
    centre: Vector, radius: float, phase: float, plane: Plane = "xy"
) -> Vector:
    """Point at ``phase`` (rad) on the circle of ``radius`` around ``centre`` in ``plane``."""
    u, v = _AXES[plane]
    return centre + radius * (math.cos(phase) * u + math.sin(phase) * v)


def circle_velocity(
    radius: float, phase: float, phase_rate: float, plane: Plane = "xy"
) -> Vector:
    """Velocity on the circle at ``phase`` when the phase changes at ``phase_rate`` (rad/s)."""
    u, v = _AXES[plane]
    return radius * phase_rate * (-math.sin(phase) * u + math.cos(phase) * v)


def min_jerk_phase(t: float, duration: float, sweep: float) -> tuple[float, float]:
    """Phase and phase rate of a rest-to-rest minimum-jerk sweep of ``sweep`` rad.

    The peak rate, at ``duration / 2``, is ``1.875 * sweep / duration``.
    """
    s = min(max(t / duration, 0.0), 1.0)
    shape = s * s * s * (10.0 - 15.0 * s + 6.0 * s * s)
    rate = 30.0 * s * s * (1.0 - s) * (1.0 - s) / duration
    return sweep * shape, sweep * rate


def cw_then_ccw_phase(t: float, period: float) -> tuple[float, float]:
    """One clockwise circle (phase 0 -> -2 pi) then one counter-clockwise (back to 0).

    Each circle is a minimum-jerk sweep of ``period`` seconds; before 0 and after
    ``2 * period`` the phase rests at 0.
    """
    if t < period:
        return min_jerk_phase(t, period, -2.0 * math.pi)
    phase, rate = min_jerk_phase(t - period, period, 2.0 * math.pi)
    return phase - 2.0 * math.pi, rate


def cw_then_ccw_constant_phase(t: float, period: float) -> tuple[float, float]:
    """The same two circles at a constant rate of 2 pi / ``period`` rad/s, reversing at
    once after the first (examples/lwr4_circle.rssm's control subsystem); at rest at 0 before
    0 and after ``2 * period``."""
    rate = 2.0 * math.pi / period
    if t < 0.0 or t >= 2.0 * period:
        return 0.0, 0.0
    if t < period:
        return -rate * t, -rate
    return rate * (t - period) - 2.0 * math.pi, rate


Profile = Literal["min-jerk", "constant"]


def circle_reference(
    t: float, centre: Vector, radius: float, period: float, plane: Plane = "xy",
    profile: Profile = "min-jerk",
) -> tuple[Vector, Vector]:
    """Desired position and velocity at time ``t`` of the cw-then-ccw circle."""
    if profile == "min-jerk":
        phase, rate = cw_then_ccw_phase(t, period)
    else:
        phase, rate = cw_then_ccw_constant_phase(t, period)
    return circle_point(centre, radius, phase, plane), circle_velocity(
        radius, phase, rate, plane
    )


def circle_peak_speed(radius: float, period: float) -> float:
    """Peak Cartesian speed (m/s) of one minimum-jerk circle of ``period`` seconds."""
    return radius * 1.875 * 2.0 * math.pi / period
