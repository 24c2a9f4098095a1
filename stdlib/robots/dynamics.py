"""Dynamics of a described robot, computed by Pinocchio from the same model file MuJoCo runs.

Conventions (as the LWR4+'s dynamics.py): vectors are ``float64`` arrays in the order of the
robot's ``joints``; the Jacobian is 6 x n at the end-effector frame in world-aligned axes
(``pin.LOCAL_WORLD_ALIGNED``), rows ``[linear; angular]``; the mass matrix includes the
description's armature (as MuJoCo's does).

The operations of a specification find a robot by name (:func:`dynamics_of`): a robot a device
of the run has loaded (from the specification's ``robots.toml`` or the standard library's),
else the standard library's table.
"""

from __future__ import annotations

import threading
from pathlib import Path

import numpy as np
import pinocchio as pin  # type: ignore[import-untyped]
from numpy.typing import NDArray

from .model import RobotDescription, RobotModelError, build_pinocchio, find_robot

Vector = NDArray[np.float64]
Matrix = NDArray[np.float64]


class RobotDynamics:
    """Pinocchio model and scratch data of one robot description."""

    __slots__ = ("data", "ee_frame_id", "lock", "model", "robot")

    def __init__(self, robot: RobotDescription) -> None:
        self.robot = robot
        self.model, self.ee_frame_id = build_pinocchio(robot)
        self.data = self.model.createData()
        self.lock = threading.Lock()   # the scratch data, in the concurrent mode

    @property
    def nv(self) -> int:
        return int(self.model.nv)

    def gravity(self, q: Vector) -> Vector:
        """Generalised gravity torques g(q) (N·m)."""
        return np.array(pin.computeGeneralizedGravity(self.model, self.data, q),
                        dtype=np.float64)

    def bias(self, q: Vector, dq: Vector) -> Vector:
        """Coriolis, centrifugal and gravity torques C(q, dq) dq + g(q) (N·m)."""
        return np.array(pin.nonLinearEffects(self.model, self.data, q, dq), dtype=np.float64)

    def mass_matrix(self, q: Vector) -> Matrix:
        """The joint-space mass matrix M(q) (symmetric, armature included)."""
        m = np.array(pin.crba(self.model, self.data, q), dtype=np.float64)
        return np.triu(m) + np.triu(m, 1).T

    def jacobian(self, q: Vector) -> Matrix:
        """6 x n end-effector Jacobian, world-aligned, rows [linear; angular]."""
        return np.array(pin.computeFrameJacobian(self.model, self.data, q, self.ee_frame_id,
                                                 pin.LOCAL_WORLD_ALIGNED), dtype=np.float64)

    def ee_position(self, q: Vector) -> Vector:
        """Position of the end-effector frame in the world (m)."""
        pin.forwardKinematics(self.model, self.data, q)
        placement = pin.updateFramePlacement(self.model, self.data, self.ee_frame_id)
        return np.array(placement.translation, dtype=np.float64)


_loaded: dict[str, RobotDescription] = {}
_dynamics: dict[RobotDescription, RobotDynamics] = {}
_guard = threading.Lock()


def register(robot: RobotDescription) -> None:
    """Make ``robot`` the one operations mean by its name (a device loaded it)."""
    with _guard:
        _loaded[robot.name] = robot


def dynamics_of(name: str, spec_dir: Path | None = None) -> RobotDynamics:
    """The (cached) dynamics of robot ``name``: the one a device registered, else the one of
    the tables (:func:`~.model.find_robot`)."""
    with _guard:
        robot = _loaded.get(name)
    if robot is None:
        robot = find_robot(name, spec_dir)
    with _guard:
        dyn = _dynamics.get(robot)
    if dyn is None:
        dyn = RobotDynamics(robot)
        with _guard:
            dyn = _dynamics.setdefault(robot, dyn)
    return dyn


__all__ = ["RobotDynamics", "RobotModelError", "dynamics_of", "register"]
