"""Standard messages on the data topics, without building: the default mapping of buffer
types to std_msgs / geometry_msgs, the explicit ROS type of a buffer named in
<spec>.ros2.toml and its diagnostics (E862 a type that does not fit, E863 a file that names no
buffer), and the conversions between values and standard messages (runtime/messages.py)."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from catkin_pkg.package import parse_package_string

from rssm_dsl.pipeline import compile_file
from rssm_dsl.ros2.generator import Workspace, generate
from rssm_dsl.ros2.runtime.messages import from_msg, to_msg
from rssm_dsl.ros2.stdtypes import KNOWN, default_name
from rssm_dsl.semantics.types import BOOL, FLOAT, INT, ArrayT, EnumT, RangeT, RecordT
from tests.conftest import ROOT

V3 = ArrayT(FLOAT, 3)

SPEC = """
record Motion {
  linear: float[3]
  angular: float[3]
}
record Arm {
  position: float[7]
  velocity: float[7]
}
system robot {
  agent a1 {
    control c {
      memory k: float = 0.0
      output level: float to e.arm nonblocking
      output where: float[3] to e.arm nonblocking
      output joints: float[7] to e.arm nonblocking
      output arm: Arm to e.arm nonblocking
      output motion: Motion to e.arm blocking
      behaviour go {
        update level { level := k }
        update where { where := [k, 0.0, 1.0] }
        update joints { joints := [k, k, k, k, k, k, k] }
        update arm { arm := {position: joints, velocity: joints} }
        update motion { motion := {linear: where, angular: where} }
        update memory { k := k + 1.0 }
        terminal done when k > 3.0
        send level ; where ; joints ; arm ; motion
      }
      initial go
      switch go -> end when done
    }
    effector arm {
      input level: float from c nonblocking
      input where: float[3] from c nonblocking
      input joints: float[7] from c nonblocking
      input arm: Arm from c nonblocking
      input motion: Motion from c blocking
      memory seen: float = 0.0
      behaviour take {
        update memory {
          seen := level + where[0] + joints[1] + arm.velocity[2] + motion.linear[0]
        }
        terminal done when seen > 20.0
        receive level ; where ; joints ; arm ; motion
      }
      initial take
      switch take -> end when done
    }
  }
}
"""


def generate_with(tmp_path: Path, types: str | None, spec: str = SPEC) -> Workspace | list[Any]:
    path = tmp_path / "robot.rssm"
    path.write_text(spec, encoding="utf-8")
    if types is not None:
        (tmp_path / "robot.ros2.toml").write_text(types, encoding="utf-8")
    comp = compile_file(path)
    assert comp.ok, [str(d) for d in comp.diagnostics]
    return generate(comp)


def topic_types(ws: Workspace) -> dict[str, str]:
    """topic -> message, from the workspace README's table."""
    out = {}
    for line in ws.files["README.md"].splitlines():
        cells = [c.strip() for c in line.split("|")]
        if len(cells) == 8 and cells[3] == "out":
            out[cells[4]] = cells[5]
    return out


def test_default_standard_types() -> None:
    assert default_name(FLOAT) == "std_msgs/msg/Float64"
    assert default_name(INT) == "std_msgs/msg/Int64"
    assert default_name(RangeT(0, 3)) == "std_msgs/msg/Int64"
    assert default_name(BOOL) == "std_msgs/msg/Bool"
    assert default_name(V3) == "geometry_msgs/msg/Vector3"
    twist = RecordT("M", (("linear", V3), ("angular", V3)))
    wrench = RecordT("W", (("torque", V3), ("force", V3)))
    pose = RecordT("P", (("position", V3), ("orientation", ArrayT(FLOAT, 4))))
    assert default_name(twist) == "geometry_msgs/msg/TwistStamped"
    assert default_name(wrench) == "geometry_msgs/msg/WrenchStamped"
    assert default_name(pose) == "geometry_msgs/msg/PoseStamped"
    # no standard counterpart: the generated message stays
    setpoint = RecordT("CartesianSetpoint", (("position", V3), ("velocity", V3)))
    for t in (setpoint, ArrayT(FLOAT, 7), ArrayT(FLOAT, 4), ArrayT(INT, 3),
              EnumT("Phase", ("a", "b")), RecordT("M", (("linear", V3),))):
        assert default_name(t) is None, t


def test_generated_workspace_uses_standard_messages(tmp_path: Path) -> None:
    ws = generate_with(tmp_path, None)
    assert not isinstance(ws, list)
    assert topic_types(ws) == {
        "/a1/c/level": "std_msgs/msg/Float64",
        "/a1/c/where": "geometry_msgs/msg/Vector3",
        "/a1/c/joints": "robot_interfaces/msg/Float64Array7Sample",
        "/a1/c/arm": "robot_interfaces/msg/Arm",
        "/a1/c/motion": "geometry_msgs/msg/TwistStamped",
    }
    msgs = sorted(p.rsplit("/", 1)[1] for p in ws.files if p.endswith(".msg"))
    # Motion goes as a TwistStamped: no message of its own
    assert msgs == ["Ack.msg", "Arm.msg", "Float64Array7Sample.msg", "SampleInfo.msg",
                    "SubsystemStatus.msg"]
    sample = ws.files["robot_interfaces/msg/Float64Array7Sample.msg"]
    assert [x for x in sample.splitlines() if not x.startswith("#")] == ["float64[7] value"]
    node = ws.files["robot_a1/robot_a1/node_c.py"]
    assert "from std_msgs import msg as _std_msgs" in node
    assert "from geometry_msgs import msg as _geometry_msgs" in node
    assert "('msg', _std_msgs.Float64, 'data', ('float',))" in node
    manifest = parse_package_string(ws.files["robot_a1/package.xml"])
    depends = {d.name for d in manifest.exec_depends}
    assert {"std_msgs", "geometry_msgs"} <= depends and "sensor_msgs" not in depends
    # the stamped output's frame is a parameter
    assert "      frame_id:\n        motion: ''" in ws.files["robot_a1/config/params.yaml"]


def test_explicit_ros_types(tmp_path: Path) -> None:
    ws = generate_with(tmp_path, '[types]\n"a1.c.where" = "geometry_msgs/msg/PointStamped"\n'
                       '"a1.e.arm.joints" = "sensor_msgs/msg/JointState"   # consumer end\n'
                       '"a1.c.arm" = "sensor_msgs/JointState"\n'
                       '"a1.c.motion" = "geometry_msgs/msg/Twist"\n')
    assert not isinstance(ws, list)
    assert topic_types(ws) == {
        "/a1/c/level": "std_msgs/msg/Float64",
        "/a1/c/where": "geometry_msgs/msg/PointStamped",
        "/a1/c/joints": "sensor_msgs/msg/JointState",
        "/a1/c/arm": "sensor_msgs/msg/JointState",
        "/a1/c/motion": "geometry_msgs/msg/Twist",
    }
    node = ws.files["robot_a1/robot_a1/node_e_arm.py"]
    assert ("('joints', _sensor_msgs.JointState, 7, (('position', 'position'), "
            "('velocity', 'velocity')))") in node
    assert "('stamped', _geometry_msgs.PointStamped, 'point', ('xyz', _geometry_msgs.Point))" \
        in node
    depends = {d.name for d in parse_package_string(ws.files["robot_a1/package.xml"])
               .exec_depends}
    assert {"std_msgs", "geometry_msgs", "sensor_msgs"} <= depends
    assert not any(p.endswith(("Float64Array7Sample.msg", "/Arm.msg")) for p in ws.files)


def line_of(text: str, needle: str) -> int:
    return next(k for k, x in enumerate(text.splitlines(), start=1) if needle in x)


@pytest.mark.parametrize(("types", "code", "line", "message"), [
    ('[types]\n"a1.c.where" = "std_msgs/msg/Float64"\n', "E862", line_of(SPEC, "output where"),
     "buffer a1.c.where (float[3]) cannot be carried by ROS type 'std_msgs/msg/Float64' "
     "named in robot.ros2.toml: std_msgs/msg/Float64 carries a float"),
    ('[types]\n"a1.c.arm" = "geometry_msgs/msg/Pose"\n', "E862", line_of(SPEC, "output arm"),
     "geometry_msgs/msg/Pose carries a record {position: float[3], orientation: float[4]}"),
    ('[types]\n"a1.c.level" = "foo_msgs/msg/Bar"\n', "E862", line_of(SPEC, "output level"),
     "'foo_msgs/msg/Bar' is not one of the standard types rssmc maps"),
    ('[types]\n"a1.c.joints" = "std_msgs/msg/Int8"\n', "E862", line_of(SPEC, "output joints"),
     "std_msgs/msg/Int8 carries a range within -128..127"),
    ('# types\n[types]\n"a1.c.nothing" = "std_msgs/msg/Float64"\n', "E863", 3,
     "robot.ros2.toml names 'a1.c.nothing', which is no buffer of system robot"),
    ('[types]\n"a1.c.level" = "std_msgs/msg/Float64"\n"a1.e.arm.level" = "std_msgs/msg/Bool"\n',
     "E863", 3, "both ends of channel a1.c.level->a1.e.arm.level are named"),
    ('[types\n', "E863", 1, "robot.ros2.toml is not valid TOML"),
    ('[topics]\n', "E863", 1, "has table(s) topics; only [types] is read"),
])
def test_types_that_do_not_fit(tmp_path: Path, types: str, code: str, line: int,
                               message: str) -> None:
    out = generate_with(tmp_path, types)
    assert isinstance(out, list), "a workspace was generated"
    assert [d.code for d in out] == [code], [str(d) for d in out]
    assert message in out[0].message
    assert out[0].span.line == line
    where = "robot.rssm" if code == "E862" else "robot.ros2.toml"
    assert out[0].span.file.endswith(where)


def test_a_range_fits_a_smaller_integer(tmp_path: Path) -> None:
    spec = SPEC.replace("memory k: float = 0.0", "memory k: float = 0.0\n      memory n: int = 0"
                        ).replace("output level: float to", "output level: 0..200 to").replace(
        "input level: float from", "input level: 0..200 from").replace(
        "update level { level := k }", "update level { level := 3 }").replace(
        "seen := level +", "seen := 1.0 * level +")
    ws = generate_with(tmp_path, '[types]\n"a1.c.level" = "std_msgs/msg/UInt8"\n', spec)
    assert not isinstance(ws, list), [str(d) for d in ws]
    assert topic_types(ws)["/a1/c/level"] == "std_msgs/msg/UInt8"
    assert "('msg', _std_msgs.UInt8, 'data', ('range', 0, 200))" in ws.files[
        "robot_a1/robot_a1/node_c.py"]


def test_cli_reports_and_writes_nothing(tmp_path: Path) -> None:
    (tmp_path / "robot.rssm").write_text(SPEC)
    (tmp_path / "robot.ros2.toml").write_text('[types]\n"a1.c.where" = "std_msgs/msg/Bool"\n')
    out = tmp_path / "ws" / "src"
    done = subprocess.run([sys.executable, "-m", "rssm_dsl", "ros2", "robot.rssm", "-o",
                           str(out), "--format", "json"], cwd=tmp_path, capture_output=True,
                          text=True, timeout=120, check=False)
    assert done.returncode == 1, done.stderr
    assert [d["code"] for d in json.loads(done.stdout)] == ["E862"]
    assert not out.exists()


def test_every_known_type_is_a_real_interface() -> None:
    """The names rssmc maps exist in the pinned wheels' packages (the .msg files of the
    interface definitions are part of the wheels: checked where the ROS venv exists)."""
    venv = ROOT / ".cache" / "ros2-venv"
    share = venv / "share"
    if not share.is_dir():
        pytest.skip("no ROS venv built here (tests/ros2/conftest.py creates it)")
    for name in KNOWN:
        package, _, kind = name.split("/")
        assert (share / package / "msg" / f"{kind}.msg").is_file(), name


class Msg:
    """A stand-in of a generated message class: keyword fields, attribute access."""

    def __init__(self, **fields: Any) -> None:
        self.__dict__.update(fields)


class Stamped(Msg):
    def __init__(self, **fields: Any) -> None:
        super().__init__(header=None, **fields)


def test_values_to_standard_messages_and_back() -> None:
    vec = ("xyz", Msg)
    v = np.array([1.0, 2.0, 3.0])
    m = to_msg(vec)(v)
    assert (m.x, m.y, m.z) == (1.0, 2.0, 3.0)
    assert from_msg(vec)(m).tolist() == [1.0, 2.0, 3.0]
    twist = ("stamped", Stamped, "twist", ("record", Msg, (("linear", vec), ("angular", vec))))
    value = {"linear": v, "angular": np.array([0.0, 0.0, 0.5])}
    msg = to_msg(twist)(value)
    assert msg.twist.angular.z == 0.5
    back = from_msg(twist)(msg)
    assert back["linear"].tolist() == [1.0, 2.0, 3.0] and back["angular"].tolist()[2] == 0.5
    scalar = ("msg", Msg, "data", ("float",))
    assert to_msg(scalar)(2.5).data == 2.5 and from_msg(scalar)(Msg(data=2.5)) == 2.5
    joints = ("joints", Stamped, 3, (("", "position"),))
    assert to_msg(joints)(v).position == [1.0, 2.0, 3.0]
    with pytest.raises(ValueError, match=r"JointState\.position holds 2 values"):
        from_msg(joints)(Msg(position=[1.0, 2.0]))
    multi = ("multiarray", Msg, 3)
    assert from_msg(multi)(Msg(data=[1.0, 2.0, 3.0])).tolist() == [1.0, 2.0, 3.0]
    with pytest.raises(ValueError, match=r"Float64MultiArray\.data holds 4 values"):
        from_msg(multi)(Msg(data=[1.0, 2.0, 3.0, 4.0]))
