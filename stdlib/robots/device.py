"""Any torque-controlled arm as a real effector, simulated by MuJoCo.

Bound by a device type such as robots.rssm's ``Arm7``::

    device effector Arm7 @ 1 kHz {
      input torque: JointVec7 nonblocking
      output state: ArmState7 nonblocking
      param robot: Robot = Robot.panda
      binding "rssm_stdlib.robots.device:MujocoArmDevice"
    }

Parameters of the device type (each instance may give its own, ``real effector left:
Arm7(robot = Robot.lwr4plus, q0 = [...])``):

- ``robot`` (an enum, required): the robot's name in ``robots.toml`` of the specification's
  folder or of the standard library (model.py): model file, joints, end-effector frame;
- ``q0`` (``float[n]``, optional): the start pose, instead of the table's.

Inputs: ``torque`` (``float[n]``, N·m, one per joint in the table's order; clipped to the
torque limits). Output ``state``, a record with ``q``, ``dq`` (``float[n]``: joint positions,
rad, and velocities, rad/s, from MuJoCo) and ``position``, ``velocity`` (``float[3]``: the
end-effector frame's position, m, and linear velocity, m/s, world frame, from MuJoCo), and
optionally ``time`` (``float``, s, MuJoCo's clock). Optional outputs, measured when the device
type declares them (robots.rssm's ``Arm7Sensing``; sensors.py):

- ``ee_orientation`` (``float[4]``): the end-effector frame's orientation, a unit quaternion
  ``(w, x, y, z)`` in the world frame;
- ``contact_force`` (``float[3]``, N, world frame): the sum of the contact forces the rest of
  the world exerts on the arm's links during the last physics step (zero without contacts:
  an MJCF's collision geoms, or a URDF's with ``collisions = true`` in robots.toml).

Each period the physics advances in the model's own steps (``timestep`` of the table, 1 ms by
default; the remainder carried to the next period; one step per period for a device faster
than that). Options (``--device-option ID:KEY=VALUE``): ``q0`` (comma-separated angles),
``robot`` (the robot's name, for a device type without the parameter: ``rssmc simulate
examples/lwr4_circle.rssm --device a1.E.lwr=rssm_stdlib.robots.device:MujocoArmDevice
--device-option a1.E.lwr:robot=lwr4plus`` runs the paper's experiment on this class).

Observers: callables appended to :attr:`MujocoArmDevice.observers` are called with the device
at the start of every step, before the physics advances (``device.state`` is the state the step
starts from, ``device.tau`` the torque about to be applied).
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from typing import Any

import mujoco  # type: ignore[import-untyped]
import numpy as np

from rssm_core.values import as_float64, joined
from rssm_dsl.interp.device import DeviceBase, DeviceConfigError, DeviceSpec

from .dynamics import register
from .model import RobotModelError, build_mujoco, ee_site_name, find_robot
from .model import Vector as Vector
from .sensors import CONTACT, ORIENTATION, arm_bodies, contact_force, orientation

_SITE = mujoco.mjtObj.mjOBJ_SITE


def _size(t: Any) -> int | None:
    """The size of an array type (duck-typed: the spec of a ROS 2 node carries the same
    types without needing rssmc's semantics)."""
    size = getattr(t, "size", None)
    return size if isinstance(size, int) else None


def _field(t: Any, name: str) -> Any:
    field = getattr(t, "field", None)
    return field(name) if callable(field) else None


class MujocoArmDevice(DeviceBase):
    """Torque in, state out; physics advanced in the model's own steps.

    A subclass may fix the robot (:attr:`ROBOT`, a robot of the standard library's table, for
    a device type without a ``robot`` parameter) and its start pose (:meth:`default_q0`).
    """

    ROBOT: str | None = None
    # step(dt) integrates dt of simulated physics: on ROS 2 with use_sim_time this device's
    # node is the clock of the system (rssm_dsl/ros2/runtime/simclock.py)
    simulation = True
    # every measurement is built the same way (fresh read-only arrays, a fresh dict): the
    # interpreter checks each output's first value only (rssm_dsl.interp.device)
    typed_measurements = True

    def __init__(self, spec: DeviceSpec) -> None:
        super().__init__(spec)
        name = spec.params.get("robot", self.option("robot", self.ROBOT))
        if not isinstance(name, str):
            raise DeviceConfigError(f"{spec.device_type} needs a parameter `robot` (an enum "
                                    "whose member names a robot of robots.toml), or the "
                                    "option robot=NAME")
        try:
            # a fixed robot is the standard library's; a parameter may name the spec's own
            self.robot = robot = find_robot(name, None if self.ROBOT else spec.base_dir)
            model, low, high = build_mujoco(robot)
        except RobotModelError as e:
            raise DeviceConfigError(f"robot {name}: {e}") from None
        n = robot.dof
        self._check_buffers(n)
        mj_names = [mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_JOINT, j)
                    for j in range(model.njnt)]
        if mj_names != list(robot.joints) or model.nq != n or model.nv != n:
            raise DeviceConfigError(f"robot {name}: the joints must be listed in the model's "
                                    f"order ({', '.join(mj_names)})")
        register(robot)
        self.model = model
        self.data = data = mujoco.MjData(model)
        self.torque_low, self.torque_high = low, high
        q0 = self.default_q0()
        if "q0" in spec.params:
            q0 = np.array(spec.params["q0"], dtype=np.float64)
        text = self.option("q0")
        if text is not None:
            try:
                q0 = np.array([float(x) for x in text.split(",")], dtype=np.float64)
            except ValueError as e:
                raise DeviceConfigError(f"option q0: {e}") from None
        if q0.shape != (n,):
            raise DeviceConfigError(f"q0 needs {n} joint angles, got {q0.size}")
        data.qpos[:] = q0
        mujoco.mj_forward(model, data)
        if spec.frequency is not None and spec.frequency * model.opt.timestep > 1.0:
            model.opt.timestep = 1.0 / spec.frequency
        self._h = float(model.opt.timestep)
        self.tau: Vector = np.zeros(n)
        self._clipped: Vector = np.zeros(n)
        self._ctrl: Vector = data.ctrl
        self.observers: list[Callable[[MujocoArmDevice], None]] = []
        self.site_id = int(mujoco.mj_name2id(model, _SITE, ee_site_name(robot, model)))
        self._vel6: Vector = np.zeros(6)
        self._parts = (data.qpos, data.qvel, data.site_xpos[self.site_id], self._vel6[3:])
        self._slices = (slice(0, n), slice(n, 2 * n), slice(2 * n, 2 * n + 3),
                        slice(2 * n + 3, 2 * n + 6))
        self._carry = 0.0
        self._arm = arm_bodies(model)
        self.contact_force: Vector = np.zeros(3)
        if self._with_contact:
            self.contact_force = contact_force(model, data, self._arm)
        self.state: dict[str, Any] = self._read()
        self._extra: dict[str, Any] = self._read_extra()

    def default_q0(self) -> Vector:
        """The start pose without a ``q0`` parameter or option: the table's."""
        return np.array(self.robot.q0, dtype=np.float64)

    def _check_buffers(self, n: int) -> None:
        spec = self.spec
        torque = spec.inputs.get("torque")
        if _size(torque) != n:
            raise DeviceConfigError(f"{spec.device_type} needs an input `torque: float[{n}]` "
                                    f"for robot {self.robot.name}, has {torque}")
        state = spec.outputs.get("state")
        sizes = {"q": n, "dq": n, "position": 3, "velocity": 3}
        if any(_size(_field(state, f)) != k for f, k in sizes.items()):
            raise DeviceConfigError(
                f"{spec.device_type} needs an output `state`, a record with q, dq: float[{n}] "
                f"and position, velocity: float[3] (robots.rssm's ArmState7 for 7 joints)")
        self._with_time = _field(state, "time") is not None
        for name, size in ((ORIENTATION, 4), (CONTACT, 3)):
            if name in spec.outputs and _size(spec.outputs[name]) != size:
                raise DeviceConfigError(f"{spec.device_type}: output `{name}` must be "
                                        f"float[{size}], not {spec.outputs[name]}")
        self._with_orientation = ORIENTATION in spec.outputs
        self._with_contact = CONTACT in spec.outputs
        self._extra_wanted = self._with_orientation or self._with_contact

    def _read(self) -> dict[str, Any]:
        mujoco.mj_objectVelocity(self.model, self.data, _SITE, self.site_id, self._vel6, 0)
        buf = joined(self._parts)
        q, dq, p, v = self._slices
        state: dict[str, Any] = {"q": buf[q], "dq": buf[dq], "position": buf[p],
                                 "velocity": buf[v]}
        if self._with_time:
            state["time"] = float(self.data.time)
        return state

    def _read_extra(self) -> dict[str, Any]:
        """The optional outputs the device type declares."""
        extra: dict[str, Any] = {}
        if self._with_orientation:
            quat = orientation(self.model, self.data, self.site_id)
            quat.setflags(write=False)
            extra[ORIENTATION] = quat
        if self._with_contact:
            force = self.contact_force.copy()
            force.setflags(write=False)
            extra[CONTACT] = force
        return extra

    def receive(self, buffer: str, value: Any) -> None:
        if buffer == "torque":
            self.tau = as_float64(value)

    def step(self, dt: float) -> None:
        for observe in self.observers:
            observe(self)
        h = self._h
        self._carry += dt
        k = int(self._carry / h + 1e-9)
        if k:
            self._carry -= k * h
            np.maximum(self.tau, self.torque_low, out=self._clipped)
            np.minimum(self._clipped, self.torque_high, out=self._ctrl)
            model, data = self.model, self.data
            for _ in range(k - 1):   # mj_step2 + mj_step1 = mj_step, state read consistent
                mujoco.mj_step2(model, data)
                mujoco.mj_step1(model, data)
            mujoco.mj_step2(model, data)
            if self._with_contact:   # the contacts of the step and their solved forces
                self.contact_force = contact_force(model, data, self._arm)
            mujoco.mj_step1(model, data)
            self.state = self._read()
            if self._extra_wanted:
                self._extra = self._read_extra()
        self.time += dt

    def measure(self) -> Mapping[str, Any]:
        if self._extra:
            return {"state": self.state, **self._extra}
        return {"state": self.state}
