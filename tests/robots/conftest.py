"""Shared by the tests of stdlib/robots: small arms written here (MJCF and URDF), specifications
using them, and whether example-robot-data (the Panda) is installed."""

from __future__ import annotations

import importlib.metadata
import re
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from rssm_dsl.interp import RunConfig, build_runtime
from rssm_dsl.interp.program import Runtime
from rssm_dsl.pipeline import compile_file

try:
    importlib.metadata.distribution("example-robot-data")
    HAS_ROBOT_DATA = True
except importlib.metadata.PackageNotFoundError:
    HAS_ROBOT_DATA = False

needs_robot_data = pytest.mark.skipif(
    not HAS_ROBOT_DATA,
    reason="example-robot-data is not installed: pip install 'rssmc[robots]'")

# A planar two-link arm swinging about y (MJCF); link lengths given per file.
MJCF = """<mujoco model="two_link_{L1}">
  <compiler angle="radian" inertiafromgeom="false"/>
  <option timestep="0.001" gravity="0 0 -9.81"/>
  <worldbody>
    <body name="link1" pos="0 0 0.5">
      <joint name="shoulder" type="hinge" axis="0 1 0" damping="0.1"/>
      <inertial pos="0 0 {H1}" mass="2.0" diaginertia="0.02 0.02 0.002"/>
      <geom type="capsule" fromto="0 0 0 0 0 {L1}" size="0.03" contype="0" conaffinity="0"/>
      <body name="link2" pos="0 0 {L1}">
        <joint name="elbow" type="hinge" axis="0 1 0" damping="0.1"/>
        <inertial pos="0 0 0.15" mass="1.0" diaginertia="0.01 0.01 0.001"/>
        <geom type="capsule" fromto="0 0 0 0 0 0.3" size="0.025" contype="0" conaffinity="0"/>
        <site name="tip" pos="0 0 0.3"/>
      </body>
    </body>
  </worldbody>
</mujoco>
"""

# The same kind of arm as URDF (links and joints; no meshes), with a fixed tool link.
URDF = """<?xml version="1.0"?>
<robot name="two_link_urdf">
  <link name="base"/>
  <link name="upper">
    <inertial><origin xyz="0 0 0.2"/><mass value="2.0"/>
      <inertia ixx="0.02" iyy="0.02" izz="0.002" ixy="0" ixz="0" iyz="0"/></inertial>
  </link>
  <link name="lower">
    <inertial><origin xyz="0 0 0.15"/><mass value="1.0"/>
      <inertia ixx="0.01" iyy="0.01" izz="0.001" ixy="0" ixz="0" iyz="0"/></inertial>
  </link>
  <link name="tool"/>
  <joint name="shoulder" type="revolute">
    <parent link="base"/><child link="upper"/><origin xyz="0 0 0.5"/><axis xyz="0 1 0"/>
    <limit effort="30" lower="-3" upper="3" velocity="5"/>
  </joint>
  <joint name="elbow" type="revolute">
    <parent link="upper"/><child link="lower"/><origin xyz="0 0 0.4"/><axis xyz="0 1 0"/>
    <limit effort="20" lower="-3" upper="3" velocity="5"/>
  </joint>
  <joint name="tool_joint" type="fixed">
    <parent link="lower"/><child link="tool"/><origin xyz="0 0 0.3"/>
  </joint>
</robot>
"""

TABLE = """
[short]
model = "models/short.xml"
joints = ["shoulder", "elbow"]
ee = "tip"
q0 = [0.3, 0.5]

[long]
model = "models/long.xml"
joints = ["shoulder", "elbow"]
ee = "tip"
q0 = [-0.2, 0.1]
torque_limits = [5.0, 3.0]

[urdf_arm]
model = "models/two_link.urdf"
joints = ["shoulder", "elbow"]
ee = "tool"
q0 = [0.4, -0.6]
armature = 0.01
"""

SPEC = """import std.types

enum Bot { short, long, urdf_arm }
type JointVec2 = float[2]
record ArmState2 {
  q: JointVec2
  dq: JointVec2
  position: Vec3
  velocity: Vec3
}

device effector Arm2 @ 1 kHz {
  input torque: JointVec2 nonblocking
  output state: ArmState2 nonblocking
  param robot: Bot = Bot.short
  binding "rssm_stdlib.robots.device:MujocoArmDevice"
}

system arms {
  agent a1 {
    control c @ 10 Hz {
      memory n: float = 0.0
      output count: float to e.hold nonblocking
      behaviour idle {
        update count { count := n }
        update memory { n := n + 1.0 }
        send count
        terminal never when false
      }
      initial idle
    }
    effector hold @ 1 kHz {
      param tau: JointVec2 = [TAU1, TAU2]
      input count: float from c nonblocking
      input left_state: ArmState2 from E.left nonblocking
      input right_state: ArmState2 from E.right nonblocking
      output left: JointVec2 to E.left nonblocking
      output right: JointVec2 to E.right nonblocking
      behaviour push {
        update left { left := tau + 0.0 * left_state.q * count }
        update right { right := tau + 0.0 * right_state.q }
        terminal never when false
        send left; right
        receive count; left_state; right_state
      }
      initial push
    }
    real effector left: Arm2LEFT
    real effector right: Arm2RIGHT
  }
}
"""


def write_robots(folder: Path, table: str = TABLE) -> Path:
    """The models and robots.toml in ``folder``; returns ``folder``."""
    models = folder / "models"
    models.mkdir(parents=True, exist_ok=True)
    (models / "short.xml").write_text(MJCF.format(L1=0.3, H1=0.15), encoding="utf-8")
    (models / "long.xml").write_text(MJCF.format(L1=0.5, H1=0.25), encoding="utf-8")
    (models / "two_link.urdf").write_text(URDF, encoding="utf-8")
    (folder / "robots.toml").write_text(table, encoding="utf-8")
    return folder


def write_spec(folder: Path, left: str = "", right: str = "(robot = Bot.long)",
               tau: tuple[float, float] = (0.0, 0.0)) -> Path:
    text = (SPEC.replace("Arm2LEFT", "Arm2" + left).replace("Arm2RIGHT", "Arm2" + right)
            .replace("TAU1", repr(tau[0])).replace("TAU2", repr(tau[1])))
    path = folder / "arms.rssm"
    path.write_text(text, encoding="utf-8")
    return path


def runtime(path: Path) -> Runtime:
    comp = compile_file(path)
    assert comp.ok, [d.message for d in comp.diagnostics]
    return build_runtime(comp, RunConfig(base_dir=path.parent))


def joint_constants(path: Path) -> dict[str, np.ndarray[Any, np.dtype[np.float64]]]:
    """The `const NAME: JointVec7 = [...]` of a specification, as arrays."""
    found = re.findall(r"^const (\w+): JointVec7 = \[([^\]]*)\]", path.read_text("utf-8"),
                       re.MULTILINE)
    return {name: np.array([float(x) for x in values.split(",")]) for name, values in found}
