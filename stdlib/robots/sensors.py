"""The optional measurements of an arm (device.py): the end-effector frame's orientation and
the contact force the rest of the world exerts on the arm, read from MuJoCo's data."""

from __future__ import annotations

from typing import Any

import mujoco  # type: ignore[import-untyped]
import numpy as np
from numpy.typing import NDArray

from .model import Vector

ORIENTATION = "ee_orientation"
"""Output buffer ``float[4]``: the end-effector frame's orientation, world, ``(w, x, y, z)``."""
CONTACT = "contact_force"
"""Output buffer ``float[3]``: the sum of the contact forces on the arm (N, world)."""


def arm_bodies(model: Any) -> NDArray[np.bool_]:
    """Per body of ``model``: whether the robot's joints move it (the first joint's body and
    everything below it)."""
    root = int(model.jnt_bodyid[0])
    moved = np.zeros(model.nbody, dtype=bool)
    for b in range(model.nbody):
        a = b
        while a > 0 and a != root:
            a = int(model.body_parentid[a])
        moved[b] = a == root
    return moved


def orientation(model: Any, data: Any, site: int) -> Vector:
    """The site's orientation as a unit quaternion ``(w, x, y, z)`` in the world frame."""
    quat = np.empty(4)
    mujoco.mju_mat2Quat(quat, data.site_xmat[site])
    return quat


def contact_force(model: Any, data: Any, arm: NDArray[np.bool_]) -> Vector:
    """The sum of the forces of the active contacts between a geom of the arm and a geom of
    anything else (N, world frame), as the constraint solver last computed them: call it
    after ``mj_step2`` (or ``mj_forward``), while the contacts and their forces agree.
    Contacts between two parts of the arm are internal and left out."""
    total = np.zeros(3)
    f6 = np.empty(6)
    for i in range(data.ncon):
        c = data.contact[i]
        on1 = arm[model.geom_bodyid[c.geom1]]
        on2 = arm[model.geom_bodyid[c.geom2]]
        if on1 == on2 or c.efc_address < 0:
            continue
        mujoco.mj_contactForce(model, data, i, f6)
        # the frame's rows are the contact axes (normal first, from geom1 to geom2); f6 is
        # the force geom1 exerts on geom2 in that frame
        world = c.frame.reshape(3, 3).T @ f6[:3]
        total += world if on2 else -world
    return total
