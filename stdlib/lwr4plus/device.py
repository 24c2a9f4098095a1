"""The real effector E_{1,lwr} of the paper's experiment: a KUKA LWR4+ simulated by MuJoCo.

Bound by `device effector LWR4Plus { binding "rssm_stdlib.lwr4plus.device:MujocoLwr4Device" }`
(lwr4plus.rssm). Each period the interpreter delivers the commanded joint torques
(`torque`), lets the device integrate the physics for the period (1 ms steps of the MJCF
model, torques clipped to the LWR4+ limits) and reads the measured `state`: joint positions
and velocities, and the end-effector position and linear velocity from MuJoCo (not from
Pinocchio: the controller's model and the simulated robot stay independent).

Options (`--device-option a1.E.lwr:KEY=VALUE`): `q0` (comma-separated start joint angles, rad),
`record` (a CSV file the device writes: t, q1..q7, x, y, z).
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from pathlib import Path
from typing import Any, TextIO

import numpy as np

from rssm_dsl.interp.device import DeviceBase, DeviceConfigError, DeviceSpec

from .mujoco_arm import MujocoLwr4, Vector

# The start pose of the experiment: elbow bent, flange pointing straight down at
# (0.580, 0, 0.400) m, well away from singularities and joint limits (bench/lwr4_handloop.py).
START_POSE: Vector = np.array([0.0, -0.6, 0.0, 1.4, 0.0, 0.6 + 1.4 - math.pi, 0.0])


def _frozen(a: Vector) -> Vector:
    a.flags.writeable = False
    return a


class MujocoLwr4Device(DeviceBase):
    """Torque in, state out; physics advanced in the model's own 1 ms steps."""

    def __init__(self, spec: DeviceSpec) -> None:
        super().__init__(spec)
        self.arm = MujocoLwr4()
        q0 = START_POSE
        text = self.option("q0")
        if text is not None:
            try:
                q0 = np.array([float(x) for x in text.split(",")], dtype=np.float64)
            except ValueError as e:
                raise DeviceConfigError(f"q0: {e}") from None
            if q0.shape != (7,):
                raise DeviceConfigError(f"q0 needs 7 joint angles, got {q0.size}")
        self.arm.reset(q0)
        self.tau: Vector = np.zeros(7)
        self._carry = 0.0
        self._record: TextIO | None = None
        path = self.option("record")
        if path is not None:
            target = Path(path)
            if not target.is_absolute():
                target = spec.base_dir / target
            self._record = target.open("w", encoding="utf-8")
            self._record.write("t,q1,q2,q3,q4,q5,q6,q7,x,y,z\n")

    def receive(self, buffer: str, value: Any) -> None:
        if buffer == "torque":
            self.tau = np.asarray(value, dtype=np.float64)

    def step(self, dt: float) -> None:
        # integrate `dt` in whole model steps, carrying the remainder to the next period
        h = self.arm.timestep
        self._carry += dt
        n = int(self._carry / h + 1e-9)
        self._carry -= n * h
        if n:
            self.arm.apply_torque(self.tau)
            self.arm.step(n)
        self.time += dt

    def measure(self) -> Mapping[str, Any]:
        s = self.arm.state()
        if self._record is not None:
            row = [s.time, *s.q, *s.ee_pos]
            self._record.write(",".join(f"{v:.9g}" for v in row) + "\n")
        return {"state": {"q": _frozen(s.q), "dq": _frozen(s.dq),
                          "position": _frozen(s.ee_pos), "velocity": _frozen(s.ee_vel)}}

    def close(self) -> None:
        if self._record is not None:
            self._record.close()
            self._record = None
