"""The optional measurements of the arm device (stdlib/robots/sensors.py) against physics:
the contact force on a link resting on a support balances the moments of gravity and of the
motor's torque about the hinge; the end-effector orientation is the rotation the joints make
(MuJoCo) and the one Pinocchio computes from the same file."""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from rssm_dsl.interp import SimOptions, Simulator
from tests.robots.conftest import joint_constants, needs_robot_data, runtime

MASS, COM, LENGTH, G = 2.0, 0.25, 0.5, 9.81

# A horizontal link on a hinge about y at 0.55 m; only its tip (a sphere) collides, with a
# box whose top is level with the tip's underside. Gravity and a positive torque push the
# tip down (rotation about +y takes +x towards -z).
LINK_MJCF = f"""<mujoco model="lever">
  <option timestep="0.001" gravity="0 0 -{G}"/>
  <worldbody>
    <geom name="support" type="box" pos="{LENGTH} 0 0.48" size="0.05 0.05 0.05"/>
    <body name="link" pos="0 0 0.55">
      <joint name="hinge" type="hinge" axis="0 1 0" damping="0.5"/>
      <inertial pos="{COM} 0 0" mass="{MASS}" diaginertia="0.002 0.05 0.05"/>
      <geom type="capsule" fromto="0 0 0 {LENGTH} 0 0" size="0.01" contype="0"
            conaffinity="0"/>
      <site name="tip" pos="{LENGTH} 0 0"/>
      <geom name="tip_ball" type="sphere" pos="{LENGTH} 0 0" size="0.02"/>
    </body>
  </worldbody>
</mujoco>
"""

# The same lever as URDF: the support a link fixed to the base, collision elements kept.
LINK_URDF = f"""<?xml version="1.0"?>
<robot name="lever_urdf">
  <link name="base"/>
  <link name="support">
    <collision><origin xyz="{LENGTH} 0 0.48"/><geometry><box size="0.1 0.1 0.1"/></geometry>
    </collision>
  </link>
  <link name="lever">
    <inertial><origin xyz="{COM} 0 0"/><mass value="{MASS}"/>
      <inertia ixx="0.002" iyy="0.05" izz="0.05" ixy="0" ixz="0" iyz="0"/></inertial>
    <collision><origin xyz="{LENGTH} 0 0"/><geometry><sphere radius="0.02"/></geometry>
    </collision>
  </link>
  <link name="tool"/>
  <joint name="support_joint" type="fixed"><parent link="base"/><child link="support"/>
  </joint>
  <joint name="hinge" type="revolute">
    <parent link="base"/><child link="lever"/><origin xyz="0 0 0.55"/><axis xyz="0 1 0"/>
    <limit effort="50" lower="-3" upper="3" velocity="5"/><dynamics damping="0.5"/>
  </joint>
  <joint name="tool_joint" type="fixed"><parent link="lever"/><child link="tool"/>
    <origin xyz="{LENGTH} 0 0"/></joint>
</robot>
"""

TABLE = """
[lever]
model = "lever.xml"
joints = ["hinge"]
ee = "tip"
q0 = [-0.05]

[lever_urdf]
model = "lever.urdf"
joints = ["hinge"]
ee = "tool"
q0 = [-0.05]
collisions = true

[lever_urdf_bare]
model = "lever.urdf"
joints = ["hinge"]
ee = "tool"
q0 = [-0.05]
"""

SPEC = """import std.types
import robots

enum Lever { lever, lever_urdf, lever_urdf_bare }
type JointVec1 = float[1]
record ArmState1 { q: JointVec1  dq: JointVec1  position: Vec3  velocity: Vec3 }

device effector Lever1 @ 1 kHz {
  input torque: JointVec1 nonblocking
  output state: ArmState1 nonblocking
  output ee_orientation: Quat nonblocking
  output contact_force: Vec3 nonblocking
  param robot: Lever = Lever.lever
  binding "rssm_stdlib.robots.device:MujocoArmDevice"
}

system press {
  agent a1 {
    control c @ 10 Hz {
      memory n: float = 0.0
      output count: float to e.push nonblocking
      behaviour idle {
        update count { count := n }
        update memory { n := n + 1.0 }
        terminal never when false
      }
      initial idle
    }
    effector push @ 1 kHz {
      input count: float from c nonblocking
      input state: ArmState1 from E.lever nonblocking
      input ee_orientation: Quat from E.lever nonblocking
      input contact_force: Vec3 from E.lever nonblocking
      output torque: JointVec1 to E.lever nonblocking
      behaviour push {
        update torque { torque := [TAU] }
        terminal never when false
      }
      initial push
    }
    real effector lever: Lever1(robot = Lever.ROBOT)
  }
}
"""


def _lever(tmp_path: Path, robot: str, tau: float) -> Any:
    (tmp_path / "lever.xml").write_text(LINK_MJCF, encoding="utf-8")
    (tmp_path / "lever.urdf").write_text(LINK_URDF, encoding="utf-8")
    (tmp_path / "robots.toml").write_text(TABLE, encoding="utf-8")
    spec = tmp_path / "press.rssm"
    spec.write_text(SPEC.replace("TAU", repr(tau)).replace("ROBOT", robot), encoding="utf-8")
    return runtime(spec)


@pytest.mark.parametrize("robot", ["lever", "lever_urdf"])
@pytest.mark.parametrize("tau", [0.0, 3.0])
def test_the_contact_force_balances_the_moments_about_the_hinge(
        tmp_path: Path, robot: str, tau: float) -> None:
    rt = _lever(tmp_path, robot, tau)
    result = Simulator(rt, SimOptions(seed=0, until=1.0)).run()   # settles on the support
    try:
        assert result.ok, result.message
        dev = rt.devices["a1.E.lever"].impl
        out = dev.measure()
        q = float(dev.state["q"][0])
        assert abs(q) < 0.01 and abs(float(dev.state["dq"][0])) < 1e-3   # at rest, level
        # moments about the hinge: the support's push N at the tip, LENGTH from the hinge,
        # holds gravity's pull on the centre of mass and the motor's torque
        normal = (MASS * G * COM * math.cos(q) + tau) / (LENGTH * math.cos(q))
        force = out["contact_force"]
        assert force[2] == pytest.approx(normal, rel=0.01), (force, normal)
        assert abs(force[0]) < 0.02 * normal and abs(force[1]) < 1e-9
        # the device's state is what the rest of the run reads
        assert np.array_equal(rt.channels["a1.E.lever.contact_force->a1.e.push.contact_force"]
                              .value, force)
    finally:
        rt.close_devices()


def test_without_collision_geometry_there_is_no_contact_force(tmp_path: Path) -> None:
    rt = _lever(tmp_path, "lever_urdf_bare", 0.0)      # the URDF's collisions dropped
    result = Simulator(rt, SimOptions(seed=0, until=0.3)).run()
    try:
        assert result.ok, result.message
        dev = rt.devices["a1.E.lever"].impl
        assert np.array_equal(dev.measure()["contact_force"], np.zeros(3))
        assert float(dev.state["q"][0]) > 0.3           # it fell through the support
    finally:
        rt.close_devices()


def test_the_orientation_is_the_hinge_rotation(tmp_path: Path) -> None:
    rt = _lever(tmp_path, "lever", 0.0)
    try:
        dev = rt.devices["a1.E.lever"].impl
        # rotation by q about +y: (cos q/2, 0, sin q/2, 0)
        q = float(dev.state["q"][0])
        assert np.allclose(dev.measure()["ee_orientation"],
                           [math.cos(q / 2), 0.0, math.sin(q / 2), 0.0], atol=1e-12)
    finally:
        rt.close_devices()


@needs_robot_data
def test_the_panda_orientation_is_pinocchio_s(tmp_path: Path) -> None:
    import pinocchio as pin

    from stdlib.robots.dynamics import dynamics_of

    system = SPEC[SPEC.index("system press"):]
    spec = tmp_path / "panda.rssm"
    spec.write_text("import std.types\nimport robots\n" + system
                    .replace("Lever1(robot = Lever.ROBOT)", "Arm7Sensing")
                    .replace("ArmState1", "ArmState7").replace("JointVec1", "JointVec7")
                    .replace("[TAU]", "[0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0]"),
                    encoding="utf-8")
    rt = runtime(spec)
    try:
        assert Simulator(rt, SimOptions(seed=0, until=0.2)).run().ok
        dev = rt.devices["a1.E.lever"].impl
        dyn = dynamics_of("panda")
        pin.framesForwardKinematics(dyn.model, dyn.data, dev.state["q"])
        w, x, y, z = dev.measure()["ee_orientation"]
        rotation = pin.Quaternion(w, x, y, z).toRotationMatrix()
        assert np.allclose(rotation, dyn.data.oMf[dyn.ee_frame_id].rotation, atol=1e-9)
        # the Panda of robots.toml has no collision geometry: no contact
        assert np.array_equal(dev.measure()["contact_force"], np.zeros(3))
    finally:
        rt.close_devices()


def test_a_sensor_buffer_of_the_wrong_size_is_E801(tmp_path: Path) -> None:
    from rssm_dsl.interp import RunConfig, build_runtime
    from rssm_dsl.interp.errors import SetupError
    from rssm_dsl.pipeline import compile_file

    _lever(tmp_path, "lever", 0.0).close_devices()
    spec = tmp_path / "press.rssm"
    spec.write_text(spec.read_text(encoding="utf-8").replace(
        "ee_orientation: Quat", "ee_orientation: Vec3"), encoding="utf-8")
    comp = compile_file(spec)
    assert comp.ok
    with pytest.raises(SetupError) as err:
        build_runtime(comp, RunConfig(base_dir=tmp_path))
    [d] = err.value.diagnostics
    assert d.code == "E801"
    assert "Lever1: output `ee_orientation` must be float[4], not float[3]" in d.message


def test_a_missing_collision_mesh_is_named(tmp_path: Path) -> None:
    from stdlib.robots.model import RobotModelError, build_mujoco, find_robot

    (tmp_path / "lever.urdf").write_text(LINK_URDF.replace(
        '<sphere radius="0.02"/>', '<mesh filename="package://lever_meshes/tip.stl"/>'),
        encoding="utf-8")
    (tmp_path / "robots.toml").write_text(TABLE.replace("model = \"lever.xml\"",
                                                        "model = \"lever.urdf\""),
                                          encoding="utf-8")
    with pytest.raises(RobotModelError, match=r"lever\.urdf: mesh 'package://lever_meshes/"
                                              r"tip\.stl' not found \(no folder lever_meshes"):
        build_mujoco(find_robot("lever_urdf", tmp_path))
    # without collisions the mesh is not read
    assert build_mujoco(find_robot("lever_urdf_bare", tmp_path))[0].ngeom == 0


@needs_robot_data
def test_the_panda_with_collisions_does_not_touch_itself_in_the_handover() -> None:
    # the Panda's collision meshes (package:// paths of example-robot-data) are read, and the
    # handover example's moves (examples/panda_handover.rssm) bring no two links into contact
    import dataclasses

    import mujoco

    from stdlib.robots.model import build_mujoco, find_robot
    from stdlib.robots.ops import min_jerk_joints
    from stdlib.robots.sensors import arm_bodies
    from tests.conftest import EXAMPLES

    model, _, _ = build_mujoco(dataclasses.replace(find_robot("panda", None), collisions=True))
    assert model.nmesh == 9 and arm_bodies(model).sum() == model.nbody - 2  # world, link0
    consts = joint_constants(EXAMPLES / "panda_handover.rssm")
    data = mujoco.MjData(model)
    for start in ("pick", "place"):
        for t in np.linspace(0.0, 2.0, 41):
            data.qpos[:] = min_jerk_joints(consts[start], consts["meet"], 2.0, float(t))["q"]
            mujoco.mj_forward(model, data)
            assert data.ncon == 0, (start, t)
