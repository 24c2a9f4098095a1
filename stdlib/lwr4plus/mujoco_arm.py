"""The simulated LWR4+: MuJoCo model and data of the shipped MJCF, driven by joint torques.

Stepping is split as MuJoCo's ``mj_step2`` (actuation, dynamics, integration) followed by
``mj_step1`` (positions and velocities of the new state), so that after :meth:`MujocoLwr4.step`
the site position and velocity read by :meth:`MujocoLwr4.state` belong to the same instant as
``qpos``/``qvel`` without an extra ``mj_forward``. Each call of ``step`` is equivalent to
``mj_step``.
"""

from __future__ import annotations

from pathlib import Path

import mujoco  # type: ignore[import-untyped]
import numpy as np
from numpy.typing import NDArray

from rssm_core.records import dataclass

from .dynamics import EE_FRAME, MJCF_PATH

Vector = NDArray[np.float64]


@dataclass(frozen=True, slots=True)
class ArmState:
    """One sample of the simulated arm (SI units, world frame)."""

    q: Vector
    dq: Vector
    ee_pos: Vector
    ee_vel: Vector
    time: float


class MujocoLwr4:
    """Torque-controlled LWR4+ simulated by MuJoCo (the real effector E_lwr)."""

    __slots__ = ("_site_id", "_vel6", "data", "model", "torque_high", "torque_low")

    def __init__(self, mjcf_path: Path = MJCF_PATH, ee_site: str = EE_FRAME) -> None:
        self.model = mujoco.MjModel.from_xml_path(str(mjcf_path))
        self.data = mujoco.MjData(self.model)
        site_id = int(mujoco.mj_name2id(self.model, mujoco.mjtObj.mjOBJ_SITE, ee_site))
        if site_id < 0:
            raise ValueError(f"{mjcf_path}: no site {ee_site!r}")
        self._site_id = site_id
        nv = int(self.model.nv)
        joint_of_actuator = np.asarray(self.model.actuator_trnid[:, 0])
        if self.model.nu != nv or not np.array_equal(joint_of_actuator, np.arange(nv)):
            raise ValueError(
                f"{mjcf_path}: expected one motor per joint, in joint order"
            )
        ctrlrange = np.asarray(self.model.actuator_ctrlrange, dtype=np.float64)
        self.torque_low: Vector = ctrlrange[:, 0].copy()
        self.torque_high: Vector = ctrlrange[:, 1].copy()
        self._vel6: Vector = np.zeros(6)
        self.reset(np.zeros(nv))

    @property
    def timestep(self) -> float:
        return float(self.model.opt.timestep)

    @property
    def time(self) -> float:
        return float(self.data.time)

    def reset(self, q0: Vector, dq0: Vector | None = None) -> None:
        """Time 0, joints at ``q0`` (rad) with velocity ``dq0`` (default at rest), no torque."""
        mujoco.mj_resetData(self.model, self.data)
        self.data.qpos[:] = q0
        self.data.qvel[:] = 0.0 if dq0 is None else dq0
        mujoco.mj_forward(self.model, self.data)

    def apply_torque(self, tau: Vector) -> Vector:
        """Command joint torques (N·m), clipped to the torque limits; returns what was applied."""
        # min/max rather than np.clip, which costs about 3x more on 7-vectors.
        applied = np.minimum(np.maximum(tau, self.torque_low), self.torque_high)
        self.data.ctrl[:] = applied
        return applied

    def step(self, n: int = 1) -> None:
        """Advance ``n`` time steps holding the commanded torques."""
        for _ in range(n):
            mujoco.mj_step2(self.model, self.data)
            mujoco.mj_step1(self.model, self.data)

    def ee_position(self) -> Vector:
        return np.array(self.data.site_xpos[self._site_id], dtype=np.float64)

    def ee_velocity(self) -> Vector:
        """Linear velocity of the end-effector site, world frame (m/s)."""
        mujoco.mj_objectVelocity(
            self.model,
            self.data,
            mujoco.mjtObj.mjOBJ_SITE,
            self._site_id,
            self._vel6,
            0,
        )
        return self._vel6[3:].copy()

    def state(self) -> ArmState:
        return ArmState(
            q=np.array(self.data.qpos, dtype=np.float64),
            dq=np.array(self.data.qvel, dtype=np.float64),
            ee_pos=self.ee_position(),
            ee_vel=self.ee_velocity(),
            time=self.time,
        )
