"""The real effector E_{1,lwr} of the paper's experiment: a KUKA LWR4+ simulated by MuJoCo.

Bound by `device effector LWR4Plus { binding "rssm_stdlib.lwr4plus.device:MujocoLwr4Device" }`
(lwr4plus.rssm). Each period the interpreter delivers the commanded joint torques
(`torque`), lets the device integrate the physics for the period (1 ms steps of the MJCF
model, the remainder carried to the next period; one step per period for a device faster
than 1 kHz; torques clipped to the LWR4+ limits) and reads the measured `state`: joint
positions and velocities, and the end-effector position and linear velocity from MuJoCo (not
from Pinocchio: the controller's model and the simulated robot stay independent).

Options (`--device-option a1.E.lwr:KEY=VALUE`): `q0` (comma-separated start joint angles, rad),
`record` (a CSV file the device writes: t, q1..q7, x, y, z).

Observers: a tool running the device (``rssmc run``'s recorder, a viewer) appends callables to
:attr:`MujocoLwr4Device.observers`; each is called with the device at the start of every
step, before the physics advances, so it sees the state the step starts from (``arm.time``,
``arm.data``) and the torque about to be applied (``tau``).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping
from pathlib import Path
from typing import Any, TextIO

import mujoco  # type: ignore[import-untyped]
import numpy as np

from rssm_core.values import as_float64, joined
from rssm_dsl.interp.device import DeviceBase, DeviceConfigError, DeviceSpec

from .dynamics import EE_FRAME
from .mujoco_arm import MujocoLwr4, Vector

# The start pose of the experiment: elbow bent, flange pointing straight down at exactly
# (0.580, 0, 0.400) m (ops.CIRCLE_START, `lwr4_start` in lwr4plus.rssm), well away from
# singularities and joint limits. Joints 2 and 4 are solved for that point (within 1e-12 m);
# joint 6 keeps the flange vertical. (bench/lwr4_handloop.py's rounder -0.6/1.4 puts the
# flange 0.6 mm away from that point.)
_Q2, _Q4 = -0.599242668249, 1.402190110099
START_POSE: Vector = np.array([0.0, _Q2, 0.0, _Q4, 0.0, -_Q2 + _Q4 - math.pi, 0.0])
_SITE = mujoco.mjtObj.mjOBJ_SITE


class MujocoLwr4Device(DeviceBase):
    """Torque in, state out; physics advanced in the model's own 1 ms steps.

    :attr:`state` is the last measurement (read-only arrays: ``q``, ``dq``, ``position``,
    ``velocity``), taken when the physics last advanced, so an observer reads the state a
    step starts from without computing it again.
    """

    # step(dt) integrates dt of simulated physics: on ROS 2 with use_sim_time this device's
    # node is the clock of the system (rssm_dsl/ros2/runtime/simclock.py)
    simulation = True
    # every measurement is built the same way (fresh read-only arrays, a fresh dict): the
    # interpreter checks each output's first value only (rssm_dsl.interp.device)
    typed_measurements = True

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
        self.observers: list[Callable[[MujocoLwr4Device], None]] = []
        # MuJoCo's arrays are fixed views into MjData: fetched once, not at every step
        arm = self.arm
        model, data = arm.model, arm.data
        if spec.frequency is not None and spec.frequency * arm.timestep > 1.0:
            # a device faster than the model's 1 ms: one physics step per period
            model.opt.timestep = 1.0 / spec.frequency
        self._model, self._data = model, data
        self._h = arm.timestep
        self._low, self._high = arm.torque_low, arm.torque_high
        self._clipped: Vector = np.zeros(7)
        self._ctrl: Vector = data.ctrl
        self._qpos: Vector = data.qpos
        self._qvel: Vector = data.qvel
        self._site_id = int(mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_SITE, EE_FRAME))
        self._site_pos: Vector = data.site_xpos[self._site_id]
        self._vel6: Vector = np.zeros(6)
        # what _read concatenates: fixed views (MuJoCo and mj_objectVelocity write in place)
        self._parts: tuple[Vector, ...] = (self._qpos, self._qvel, self._site_pos,
                                           self._vel6[3:])
        self._carry = 0.0
        self.state: dict[str, Vector] = self._read()
        self._record: TextIO | None = None
        path = self.option("record")
        if path is not None:
            target = Path(path)
            if not target.is_absolute():
                target = spec.base_dir / target
            self._record = target.open("w", encoding="utf-8")
            self._record.write("t,q1,q2,q3,q4,q5,q6,q7,x,y,z\n")

    def _read(self) -> dict[str, Vector]:
        """The current state as read-only arrays (what ``measure`` reports): views of one
        fresh read-only copy (one copy costs less than four)."""
        mujoco.mj_objectVelocity(self._model, self._data, _SITE, self._site_id, self._vel6, 0)
        buf = joined(self._parts)
        return {"q": buf[0:7], "dq": buf[7:14], "position": buf[14:17], "velocity": buf[17:20]}

    def receive(self, buffer: str, value: Any) -> None:
        if buffer == "torque":
            self.tau = as_float64(value)

    def step(self, dt: float) -> None:
        for observe in self.observers:
            observe(self)
        # integrate `dt` in whole model steps, carrying the remainder to the next period
        h = self._h
        carry = self._carry + dt
        n = int(carry / h + 1e-9)
        if n:
            carry -= n * h
            # the torque limits (min/max: np.clip costs about 3x more on 7-vectors)
            np.maximum(self.tau, self._low, out=self._clipped)
            np.minimum(self._clipped, self._high, out=self._ctrl)
            model, data = self._model, self._data
            for _ in range(n):       # mj_step2 + mj_step1 = mj_step (see mujoco_arm.py)
                mujoco.mj_step2(model, data)
                mujoco.mj_step1(model, data)
            self.state = self._read()
        self._carry = carry
        self.time += dt

    def measure(self) -> Mapping[str, Any]:
        s = self.state
        if self._record is not None:
            row = [float(self._data.time), *s["q"], *s["position"]]
            self._record.write(",".join(f"{v:.9g}" for v in row) + "\n")
        return {"state": s}

    def close(self) -> None:
        if self._record is not None:
            self._record.close()
            self._record = None
