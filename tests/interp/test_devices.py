"""The scripted devices of the standard library and the device interface."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from rssm_dsl.bindings import resolve
from rssm_dsl.interp.device import Device, DeviceConfigError, DeviceSpec
from rssm_dsl.semantics.types import BOOL, FLOAT, INT, ArrayT, RecordT

BLOB = RecordT("Blob", (("visible", BOOL), ("x", FLOAT), ("ids", ArrayT(INT, 2))))


def spec(tmp_path: Path, options: dict[str, str] | None = None,
         outputs: dict[str, Any] | None = None, inputs: dict[str, Any] | None = None
         ) -> DeviceSpec:
    outs = outputs if outputs is not None else {"frame": BLOB}
    ins = inputs if inputs is not None else {}
    initial = {"frame": {"visible": False, "x": 0.0, "ids": (0, 0)}, "angle": 0.0,
               "command": 0.0}
    return DeviceSpec("a1.R.cam", "cam", "Camera", "receptor", 30.0, ins, outs,
                      {k: initial[k] for k in (*ins, *outs)}, options=options or {},
                      base_dir=tmp_path)


def make(binding: str, s: DeviceSpec) -> Device:
    cls = resolve(binding, [])
    assert callable(cls)
    dev = cls(s)
    assert isinstance(dev, Device)
    return dev


def test_constant_device(tmp_path: Path) -> None:
    dev = make("rssm_stdlib.devices.constant:ConstantDevice", spec(tmp_path))
    dev.step(0.1)
    assert dev.measure()["frame"]["visible"] is False
    values = json.dumps({"frame": {"visible": True, "x": 0.5, "ids": [1, 2]}})
    dev = make("rssm_stdlib.devices.constant:ConstantDevice",
               spec(tmp_path, {"values": values}))
    assert dev.measure()["frame"] == {"visible": True, "x": 0.5, "ids": (1, 2)}
    with pytest.raises(DeviceConfigError, match="no output buffer 'nope'"):
        make("rssm_stdlib.devices.constant:ConstantDevice",
             spec(tmp_path, {"values": '{"nope": 1}'}))


def test_echo_device(tmp_path: Path) -> None:
    s = spec(tmp_path, outputs={"angle": FLOAT}, inputs={"command": FLOAT})
    dev = make("rssm_stdlib.devices.echo:EchoDevice", s)
    assert dev.measure() == {"angle": 0.0}
    dev.receive("command", 1.25)
    dev.step(0.01)
    assert dev.measure() == {"angle": 1.25}


def test_csv_replay_by_rows_and_by_time(tmp_path: Path) -> None:
    (tmp_path / "cam.csv").write_text(
        "frame.visible,frame.x,frame.ids[0],frame.ids[1]\n"
        "false,0.0,1,2\ntrue,0.5,3,4\n")
    dev = make("rssm_stdlib.devices.replay:CsvReplay", spec(tmp_path))
    seen = []
    for _ in range(3):
        dev.step(1 / 30)
        seen.append(dev.measure()["frame"]["x"])
    assert seen == [0.0, 0.5, 0.5]                        # one row per step, then held
    (tmp_path / "timed.csv").write_text("time,frame.visible,frame.x,frame.ids[0],frame.ids[1]\n"
                                        "0.0,false,0.0,0,0\n0.25,true,1.0,0,0\n")
    dev = make("rssm_stdlib.devices.replay:CsvReplay", spec(tmp_path, {"file": "timed.csv"}))
    xs = []
    for _ in range(4):
        dev.step(0.1)
        xs.append(dev.measure()["frame"]["x"])
    assert xs == [0.0, 0.0, 1.0, 1.0]                     # by the time column
    assert isinstance(dev.measure()["frame"]["ids"], tuple)


def test_csv_replay_reports_bad_files(tmp_path: Path) -> None:
    with pytest.raises(DeviceConfigError, match="cannot read"):
        make("rssm_stdlib.devices.replay:CsvReplay", spec(tmp_path))
    (tmp_path / "cam.csv").write_text("frame.visible,frame.x\ntrue,0.5\n")
    with pytest.raises(DeviceConfigError, match=r"needs column\(s\) frame.ids\[0\]"):
        make("rssm_stdlib.devices.replay:CsvReplay", spec(tmp_path))
    (tmp_path / "cam.csv").write_text(
        "frame.visible,frame.x,frame.ids[0],frame.ids[1]\nmaybe,0.5,1,2\n")
    with pytest.raises(DeviceConfigError, match="'maybe' is not a bool"):
        make("rssm_stdlib.devices.replay:CsvReplay", spec(tmp_path))


def test_lwr4_impedance_op_matches_the_dynamics_library() -> None:
    impedance = resolve("rssm_stdlib.lwr4plus.ops:impedance", [])
    dyn = resolve("rssm_stdlib.lwr4plus.dynamics:impedance_torque", [])
    assert callable(impedance) and callable(dyn)
    q = np.array([0.0, -0.6, 0.0, 1.4, 0.0, 0.6 + 1.4 - np.pi, 0.0])
    state = {"q": q, "dq": np.zeros(7), "position": np.zeros(3), "velocity": np.zeros(3)}
    sp = {"position": np.array([0.6, 0.0, 0.4]), "velocity": np.zeros(3)}
    tau = impedance(state, sp, 2000.0, 100.0)
    assert tau.shape == (7,) and not tau.flags.writeable
    assert np.allclose(tau, dyn(q, np.zeros(7), sp["position"], sp["velocity"], 2000.0, 100.0))


@pytest.mark.parametrize("failed", [False, True])
def test_a_device_can_end_the_run_with_its_own_reason(failed: bool, tmp_path: Path) -> None:
    from rssm_dsl.interp import RunConfig, SimOptions, Simulator, build_runtime
    from rssm_dsl.pipeline import compile_file

    module = f"stop_device_{int(failed)}"  # module names are per process: keep them unique
    (tmp_path / f"{module}.py").write_text(
        "from rssm_dsl.interp.device import DeviceBase\n"
        "from rssm_dsl.interp.errors import StopSimulation\n"
        "class Stopper(DeviceBase):\n"
        "    def step(self, dt):\n"
        "        super().step(dt)\n"
        "        if self.time >= 0.05:\n"
        f"            raise StopSimulation('enough', 'stopped by the device', failed={failed})\n")
    (tmp_path / "s.rssm").write_text("""
device effector Valve @ 100 Hz {
  input open: bool nonblocking
  binding "MODULE:Stopper"
}
system s {
  agent a1 {
    control c @ 50 Hz {
      output open: bool to e.v nonblocking
      behaviour run {
        update open { open := true }
        terminal never when false
      }
      initial run
    }
    effector v @ 100 Hz {
      input open: bool from c nonblocking
      output cmd: bool to E.v nonblocking
      behaviour pass {
        update cmd { cmd := open }
        terminal never when false
      }
      initial pass
    }
    real effector v: Valve
  }
}
""".replace("MODULE", module))
    comp = compile_file(tmp_path / "s.rssm")
    assert comp.ok, comp.diagnostics
    rt = build_runtime(comp, RunConfig(base_dir=tmp_path))
    result = Simulator(rt, SimOptions(until=10.0)).run()
    assert result.reason == "enough" and result.message == "stopped by the device"
    assert result.ok is not failed      # a clean end unless the device says it failed
    # the CLI: exit 0 for a clean end, 1 for a failure, the reason in the JSON either way
    r = subprocess.run([sys.executable, "-m", "rssm_dsl", "simulate", str(tmp_path / "s.rssm"),
                        "--until", "10", "--format", "json"], capture_output=True, text=True,
                       timeout=120, cwd=tmp_path)
    assert r.returncode == (1 if failed else 0), r.stderr
    assert json.loads(r.stdout)["reason"] == "enough"
    assert 0.04 <= result.time <= 0.06


def test_time_standing_still_is_reported_not_a_hang(tmp_path: Path) -> None:
    from rssm_dsl.interp import RunConfig, SimOptions, Simulator, build_runtime, scheduler
    from rssm_dsl.pipeline import compile_file

    (tmp_path / "z.rssm").write_text("""
system z {
  agent a1 {
    control c {
      memory n: int = 0
      behaviour spin {
        update memory { n := n + 1 }
        terminal never when n < 0
      }
      initial spin
      switch spin -> spin otherwise
    }
  }
}
""")
    comp = compile_file(tmp_path / "z.rssm")
    assert comp.ok, comp.diagnostics
    rt = build_runtime(comp, RunConfig(base_dir=tmp_path))
    old = scheduler.ZENO_FIRINGS
    scheduler.ZENO_FIRINGS = 20_000        # keep the test short; the default is 2 million
    try:
        result = Simulator(rt, SimOptions(until=1.0)).run()
    finally:
        scheduler.ZENO_FIRINGS = old
    assert result.reason == "error"
    assert [d.code for d in result.diagnostics] == ["E808"]
    assert "subsystems without a frequency: a1.c" in result.message


ECHO_LOOP = """
device effector Echo @ 100 Hz {
  input command: float nonblocking
  output angle: float nonblocking
  binding "rssm_stdlib.devices.echo:EchoDevice"
}

system loop {
  agent a {
    control c @ 50 Hz {
      memory n: float = 0.0
      memory seen: float = 0.0
      output cmd: float to e.m nonblocking
      input back: float from e.m nonblocking
      behaviour go {
        update cmd { cmd := n }
        update memory {
          n := n + 1.0
          seen := back
        }
        terminal never when false
      }
      initial go
    }
    effector m @ 100 Hz {
      input cmd: float from c nonblocking
      output command: float to E.m nonblocking
      input angle: float from E.m nonblocking
      output back: float to c nonblocking
      behaviour relay {
        update command { command := cmd }
        update back { back := angle }
        terminal never when false
      }
      initial relay
    }
    real effector m: Echo
  }
}
"""


def test_a_device_receives_a_command_every_period(tmp_path: Path) -> None:
    """The controller counts 0, 1, 2, ... into an echo device (through its effector) and
    reads the echo back: after 1 s at 50 Hz it reads a recent count, not the first command
    again (the device net takes in a command in every period, not once)."""
    from rssm_dsl.interp import RunConfig, SimOptions, Simulator, build_runtime
    from rssm_dsl.pipeline import compile_file

    path = tmp_path / "loop.rssm"
    path.write_text(ECHO_LOOP, encoding="utf-8")
    comp = compile_file(path)
    assert comp.ok, [d.message for d in comp.diagnostics]
    rt = build_runtime(comp, RunConfig(base_dir=tmp_path))
    result = Simulator(rt, SimOptions(until=1.0)).run()
    assert result.reason == "until", result.message
    c = rt.subsystems["a.c"].vars
    assert c["n"] == 51.0
    assert 40.0 <= c["seen"] < c["n"], c
