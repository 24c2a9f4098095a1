"""Enumerations and ranges in the generated ROS 2 interfaces, without building: an enum field
is a uint8 with one constant per member, a range an int64; every generated .msg file is
valid for rosidl's parser (checked here against its rules: field and constant names, types,
constant values); the nodes convert enum names to numbers and back; enum members that
cannot become message constants are reported (E860)."""

from __future__ import annotations

import json
import re
import subprocess
from pathlib import Path
from types import SimpleNamespace
from typing import Any

import numpy as np
import pytest

from rssm_dsl.ros2 import toolchain
from rssm_dsl.ros2.generator import Workspace
from rssm_dsl.ros2.names import MSG_CONSTANT, msg_field_ok
from rssm_dsl.ros2.runtime.messages import from_msg, to_msg
from tests.ros2.conftest import SPECS, Processes, build_spec, launch_cmd, node_env
from tests.ros2.test_generate import gen, gen_text

PRIMITIVES = {"bool", "byte", "char", "float32", "float64", "int8", "uint8", "int16", "uint16",
              "int32", "uint32", "int64", "uint64", "string"}
UINT8 = range(0, 256)
_FIELD = re.compile(r"(?P<type>[A-Za-z0-9_/]+)(?P<array>\[\d*\])?\s+(?P<name>\S+?)"
                    r"(?:=(?P<value>\S+))?\s*$")


def _messages(ws: Workspace) -> dict[str, str]:
    return {Path(p).stem: text for p, text in ws.files.items() if p.endswith(".msg")}


def check_msg(name: str, text: str, known: set[str]) -> None:
    """The rules of rosidl_adapter's .msg parser that the generator can get wrong."""
    names: set[str] = set()
    for line in text.splitlines():
        code = line.split("#", 1)[0].strip()
        if not code:
            continue
        m = _FIELD.fullmatch(code)
        assert m is not None, f"{name}: not a field or constant: {line!r}"
        base, field = m["type"], m["name"]
        assert base in PRIMITIVES or base in known or "/" in base, f"{name}: type {base}"
        assert field not in names, f"{name}: {field} twice"
        names.add(field)
        if m["value"] is None:
            assert msg_field_ok(field), f"{name}: field name {field}"
        else:
            assert m["array"] is None and base in PRIMITIVES, f"{name}: constant {line!r}"
            assert MSG_CONSTANT.match(field), f"{name}: constant name {field}"
            if base == "uint8":
                assert int(m["value"]) in UINT8, f"{name}: {line!r}"


@pytest.fixture(scope="module")
def finite() -> Workspace:
    return gen(SPECS / "finite.rssm")


def test_enum_and_range_fields_of_a_record_message(finite: Workspace) -> None:
    msgs = _messages(finite)
    grip = [line for line in msgs["Grip"].splitlines() if not line.startswith("#")]
    assert grip == ["uint8 PHASE_IDLE=0", "uint8 PHASE_APPROACH=1", "uint8 PHASE_GRASP=2",
                    "uint8 PHASE_RELEASE=3", "uint8 phase", "int64 retries", "int64[2] slots"]
    # a channel of the enum type itself: its sample message carries the constants too
    sample = msgs["PhaseSample"].splitlines()
    assert "uint8 value" in sample and "uint8 PHASE_GRASP=2" in sample
    for name, text in msgs.items():
        check_msg(name, text, set(msgs))


def test_parameters_of_enum_and_range_types(finite: Workspace) -> None:
    [params] = [t for p, t in finite.files.items() if p.endswith("config/params.yaml")]
    assert "    start: 'approach'\n" in params and "    limit: 2\n" in params


def _record_class(name: str) -> Any:
    def make(**fields: Any) -> Any:
        return SimpleNamespace(_type=name, **fields)
    return make


def test_nodes_convert_enum_names_to_numbers_and_back() -> None:
    phase = ("enum", "Phase", ("idle", "approach", "grasp", "release"))
    desc = ("record", _record_class("Grip"), (("phase", phase), ("retries", ("range", 0, 3)),
                                              ("slots", ("array", ("range", 0, 11), 2, None)),
                                              ("history", ("array", phase, 3, None))))
    value = {"phase": "grasp", "retries": 3, "slots": (0, 11),
             "history": ("idle", "release", "approach")}
    msg = to_msg(desc)(value)
    assert msg.phase == 2 and msg.retries == 3
    assert msg.slots.dtype == np.int64 and msg.slots.tolist() == [0, 11]
    assert msg.history.dtype == np.uint8 and msg.history.tolist() == [0, 3, 1]
    assert from_msg(desc)(msg) == value
    with pytest.raises(ValueError, match="not a member of enum Phase"):
        from_msg(phase)(7)


ENUMS = """
enum Mode {{ {members} }}
record Cmd {{ mode: Mode, level: 0..9 }}
system sys {{
  agent a1 {{
    control c {{
      output cmd: Cmd to e.arm
      behaviour b {{
        update cmd {{ cmd := {{mode: Mode.{first}, level: 9}} }}
        terminal never when false
      }}
      initial b
    }}
    effector arm {{
      input cmd: Cmd from c
      memory last: Cmd
      behaviour b {{
        update memory {{ last := cmd }}
        terminal stop when last.level > 8 and last.mode == Mode.{first}
      }}
      initial b
      switch b -> end when stop
    }}
  }}
}}
"""


@pytest.mark.parametrize(("members", "message"), [
    ("run, _stop", "member '_stop' of enum Mode cannot become ROS 2 message constant "
                   "'MODE__STOP'"),
    ("run, Run", "members 'run' and 'Run' of enum Mode both become message constant "
                 "'MODE_RUN'"),
])
def test_enum_members_that_cannot_become_constants(tmp_path: Path, members: str,
                                                   message: str) -> None:
    out = gen_text(tmp_path, ENUMS.format(members=members, first="run"))
    assert isinstance(out, list)
    assert [d.code for d in out] == ["E860"]
    assert message in out[0].message


def test_camel_case_enum_names_become_upper_snake_constants(tmp_path: Path) -> None:
    ws = gen_text(tmp_path, ENUMS.format(members="fastRun, slow_walk", first="fastRun")
                  .replace("Mode", "GripMode"))
    assert not isinstance(ws, list)
    msgs = _messages(ws)
    assert "uint8 GRIP_MODE_FAST_RUN=0" in msgs["Cmd"].splitlines()
    assert "uint8 GRIP_MODE_SLOW_WALK=1" in msgs["Cmd"].splitlines()
    for name, text in msgs.items():
        check_msg(name, text, set(msgs))


@pytest.mark.ros2
@pytest.mark.slow
def test_built_nodes_carry_enums_and_check_ranges(ros_venv: toolchain.RosVenv, build_dir: Path,
                                                  domain: int, tmp_path: Path,
                                                  processes: Processes) -> None:
    """Built with rosidl (the constants compile), run: enum values cross the wire as numbers
    and arrive as names, a value stored outside its range takes the error condition."""
    built = build_spec(SPECS / "finite.rssm", ros_venv, build_dir)
    launch = processes.start(
        launch_cmd([built.launch_file("finite_a1", "a1")], duration=12,
                   log_dir=tmp_path / "logs"),
        node_env(built, domain, tmp_path), tmp_path / "launch.log")
    try:
        launch.wait(timeout=60)
    except subprocess.TimeoutExpired:
        pytest.fail("the nodes did not stop: " + (tmp_path / "launch.log").read_text())

    def events(sid: str) -> list[dict[str, Any]]:
        path = tmp_path / "trace" / f"{sid}.jsonl"
        return [json.loads(x) for x in path.read_text().splitlines() if x.strip()]

    c = events("a1.c")
    errors = [e for e in c if e["event"] == "error"]
    assert errors and all(e["code"] == "E802" and e["handled"] for e in errors), errors
    # the first value stored out of its range: `retries` past 3, or the command's record
    # built with retries 3 (`slots: [retries, retries * 4]`, 12 past 0..11); which comes
    # first depends on whether a fresh status arrived in that iteration (DDS timing: the
    # interpreter has both, retries first)
    assert {e["message"] for e in errors} <= {"value 4 is outside 0..3 of retries",
                                             "value 12 is outside 0..11 of Grip.slots[1]"}, errors
    assert [(e["from"], e["to"]) for e in c if e["event"] == "switch"] == [("work", None)]
    received = [got["value"] for e in events("a1.e.hand") if e["event"] == "iteration"
                for buffer, got in e["received"].items() if buffer == "phase_out"]
    assert received and set(received) <= {"idle", "approach", "grasp", "release"}
    status = [got["value"] for e in c if e["event"] == "iteration"
              for buffer, got in e["received"].items() if buffer == "status"]
    # the record comes back from the effector with its enum field as a name (which one
    # depends on when DDS discovery let the first messages through)
    assert status and all(v["phase"] in {"idle", "approach", "grasp", "release"}
                          and 0 <= v["retries"] <= 3 for v in status)
