"""Hand-written baseline of the paper's LWR4+ experiment: a plain Python 1 kHz loop.

MuJoCo plays the robot, Pinocchio gives g(q) and J(q); every 1 ms step the controller reads the
state, computes the desired point of the circle (10 cm diameter, horizontal, one turn clockwise
then one counter-clockwise, each a 2.5 s minimum-jerk sweep: peak speed 0.236 m/s), the
Cartesian impedance torque, and steps the simulation once.

Run ``python bench/lwr4_handloop.py`` to print the figures for both damping forms.
"""

from __future__ import annotations

import math
import sys
import time
from collections.abc import Callable
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import TypedDict

import numpy as np
from numpy.typing import NDArray

_REPO = Path(__file__).resolve().parents[1]
if str(_REPO) not in sys.path:
    sys.path.insert(0, str(_REPO))

from stdlib.lwr4plus.dynamics import (  # noqa: E402
    Lwr4Dynamics,
    Plane,
    Profile,
    circle_peak_speed,
    circle_point,
    circle_reference,
    impedance_torque,
)
from stdlib.lwr4plus.mujoco_arm import MujocoLwr4  # noqa: E402

Vector = NDArray[np.float64]


def _default_q0() -> Vector:
    # Elbow bent, flange pointing straight down at (0.580, 0, 0.400) m (circle centre
    # (0.530, 0, 0.400) m): far from the stretched-arm and wrist singularities (singular
    # values of the 3x7 position Jacobian 0.72/0.68/0.26 m) and from every joint limit.
    return np.array([0.0, -0.6, 0.0, 1.4, 0.0, 0.6 + 1.4 - math.pi, 0.0])


@dataclass(frozen=True, slots=True)
class LoopConfig:
    """Gains, start pose and circle of the experiment (SI units)."""

    stiffness: float = 3000.0  # K, N/m (isotropic)
    damping: float = 100.0  # D, N·s/m (isotropic)
    q0: Vector = field(default_factory=_default_q0)
    radius: float = 0.05
    period: float = 2.5  # one circle, s
    plane: Plane = "xy"
    settle: float = 0.0  # extra time at rest after the two circles, s
    # "min-jerk": rest-to-rest sweeps; "constant": constant rate, reversing at speed (the
    # control subsystem of examples/lwr4_circle.rssm)
    profile: Profile = "min-jerk"

    @property
    def duration(self) -> float:
        return 2.0 * self.period + self.settle


class HandLoopResult(TypedDict):
    us_per_step: float
    real_time_factor: float
    rms_error_m: float
    max_error_m: float
    steps: int
    centre: Vector
    t: Vector  # (n,)
    p: Vector  # (n, 3) end-effector position measured by MuJoCo
    p_des: Vector  # (n, 3)
    q: Vector  # (n, 7)
    tau: Vector  # (n, 7) applied (clipped) torques


def run_hand_loop(
    duration_s: float | None = None,
    damp_velocity_error: bool = True,
    config: LoopConfig | None = None,
    clock: Callable[[], float] = time.perf_counter,
) -> HandLoopResult:
    """Run the circle experiment; the circle starts at the initial end-effector position.

    The loop is timed with ``clock`` (wall time by default; bench/lwr4.py passes CPU time).
    """
    cfg = config if config is not None else LoopConfig()
    arm = MujocoLwr4()
    dyn = Lwr4Dynamics()
    arm.reset(cfg.q0)
    p0 = arm.ee_position()
    # The circle's phase-0 point is the start position: no initial jump.
    centre = p0 - circle_point(np.zeros(3), cfg.radius, 0.0, cfg.plane)
    duration = cfg.duration if duration_s is None else duration_s
    n = round(duration / arm.timestep)

    t_log = np.empty(n)
    p_log = np.empty((n, 3))
    pd_log = np.empty((n, 3))
    q_log = np.empty((n, arm.model.nq))
    tau_log = np.empty((n, arm.model.nu))

    start = clock()
    for i in range(n):
        s = arm.state()
        p_des, v_des = circle_reference(
            s.time, centre, cfg.radius, cfg.period, cfg.plane, cfg.profile
        )
        tau = impedance_torque(
            s.q,
            s.dq,
            p_des,
            v_des,
            cfg.stiffness,
            cfg.damping,
            damp_velocity_error,
            dyn,
        )
        tau_log[i] = arm.apply_torque(tau)
        t_log[i] = s.time
        p_log[i] = s.ee_pos
        pd_log[i] = p_des
        q_log[i] = s.q
        arm.step()
    wall = clock() - start

    err = np.linalg.norm(p_log - pd_log, axis=1)
    return HandLoopResult(
        us_per_step=wall / n * 1e6,
        real_time_factor=n * arm.timestep / wall,
        rms_error_m=float(np.sqrt(np.mean(err**2))),
        max_error_m=float(err.max()),
        steps=n,
        centre=centre,
        t=t_log,
        p=p_log,
        p_des=pd_log,
        q=q_log,
        tau=tau_log,
    )


def _report(cfg: LoopConfig) -> None:
    print(f"K = {cfg.stiffness:g} N/m, D = {cfg.damping:g} N·s/m")
    for damp_velocity_error, label in (
        (True, "D·(v_des − v)"),
        (False, "−D·v (paper)"),
    ):
        r = run_hand_loop(damp_velocity_error=damp_velocity_error, config=cfg)
        print(
            f"  {label:14s} {r['us_per_step']:6.1f} µs/step"
            f"  {r['real_time_factor']:5.1f}× real time"
            f"  RMS {r['rms_error_m'] * 1e3:5.2f} mm  max {r['max_error_m'] * 1e3:5.2f} mm"
            f"  ({r['steps']} steps)"
        )


def main() -> None:
    cfg = LoopConfig()
    print(
        f"LWR4+ hand loop at 1 kHz: circle r = {cfg.radius} m in {cfg.plane}, "
        f"{cfg.period} s per turn (peak {circle_peak_speed(cfg.radius, cfg.period):.3f} m/s), "
        "cw then ccw"
    )
    _report(cfg)
    print("paper's gains:", end=" ")
    _report(replace(cfg, stiffness=2000.0, damping=100.0))


if __name__ == "__main__":
    main()
