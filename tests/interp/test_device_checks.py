"""What a device measures is checked against the declared types of its outputs (E803): at
every period for any device; for a class that declares ``typed_measurements = True``, the
first time each output is measured (rssm_dsl.interp.device). The standard library's MuJoCo
devices declare it: their measurements over a run are checked here."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
import pytest

from rssm_dsl.interp import RunConfig, SimOptions, Simulator
from rssm_dsl.interp.values import converter
from tests.interp.conftest import EXAMPLES, compile_text, compiled, runtime
from tests.robots.conftest import runtime as arms_runtime
from tests.robots.conftest import write_robots, write_spec

DEVICE = '''
import numpy as np
from rssm_dsl.interp.device import DeviceBase


def _pos(x):
    a = np.full(3, float(x))
    a.setflags(write=False)
    return a


class Probe(DeviceBase):
    """Measures pos = (n, n, n) and count = n at its n-th step; at step `bad_at` it measures
    `bad` instead: a list of two floats for pos, a name that is no output, or pos only from
    step `late` on (count only before)."""

    def __init__(self, spec):
        super().__init__(spec)
        self.n = 0
        self.bad_at = int(self.option("bad_at", "0"))
        self.bad = self.option("bad", "short")
        self.late = int(self.option("late", "0"))

    def step(self, dt):
        self.n += 1

    def measure(self):
        n = self.n
        if n == self.bad_at:
            if self.bad == "short":
                return {"pos": [1.0, 2.0], "count": n}
            return {"pos": _pos(n), "count": n, "extra": 1.0}
        if n < self.late:
            return {"count": n}
        return {"pos": _pos(n), "count": n}


class TypedProbe(Probe):
    typed_measurements = True
'''

SPEC = '''
device receptor Sensor @ 100 Hz {
  output pos: float[3] nonblocking
  output count: int nonblocking
  binding "probe_dev:Probe"
}

system s {
  agent a1 {
    receptor probe @ 100 Hz {
      input pos: float[3] from R.probe nonblocking
      input count: int from R.probe nonblocking
      memory x: float = 0.0
      memory k: int = 0
      behaviour b {
        update memory {
          x := x + pos[0]
          k := k + count
        }
        terminal never when false
      }
      initial b
    }
    real receptor probe: Sensor
    control c @ 10 Hz {
      memory t: int = 0
      behaviour idle {
        update memory {
          t := t + 1
        }
        terminal never when false
      }
      initial idle
    }
  }
}
'''


def _line(text: str) -> int:
    """The line of the spec written to the file (it starts with a blank line)."""
    return SPEC[:SPEC.index(text)].count("\n") + 1


def _run(tmp_path: Path, cls: str, **options: str) -> tuple[Any, Any]:
    (tmp_path / "probe_dev.py").write_text(DEVICE, encoding="utf-8")
    comp = compile_text(tmp_path, SPEC)
    config = RunConfig(base_dir=tmp_path, devices={"a1.R.probe": f"probe_dev:{cls}"},
                       device_options={"a1.R.probe": dict(options)})
    rt = runtime(comp, config)
    result = Simulator(rt, SimOptions(until=0.2)).run()
    return rt, result


@pytest.mark.parametrize("cls", ["Probe", "TypedProbe"])
def test_a_good_device_runs_and_its_values_arrive(tmp_path: Path, cls: str) -> None:
    rt, result = _run(tmp_path, cls)
    assert result.reason == "until", result.message
    device = rt.devices["a1.R.probe"]
    n = device.steps
    assert n >= 20
    # the last measurement is the device's buffers' value
    assert device.vars["count"] == n and np.array_equal(device.vars["pos"], [n, n, n])
    assert not device.vars["pos"].flags.writeable


@pytest.mark.parametrize("cls", ["Probe", "TypedProbe"])
@pytest.mark.parametrize("bad_at", [1, 5])
def test_a_wrong_value_is_E803_at_the_period_it_is_measured(tmp_path: Path, cls: str,
                                                            bad_at: int) -> None:
    """Any device: a wrong value at its first measurement stops the run (E803). A device
    without the declaration is checked at every period; a typed one only at the first."""
    rt, result = _run(tmp_path, cls, bad_at=str(bad_at))
    device = rt.devices["a1.R.probe"]
    if cls == "TypedProbe" and bad_at > 1:
        # checked once: the later wrong value is stored as the device returned it, and the
        # receptor that reads it fails on it (E802)
        assert result.reason == "error"
        (d,) = result.diagnostics
        assert d.code == "E802" and "'list'" in d.message and "a1.r.probe" in d.message
        assert device.steps >= bad_at
        return
    assert result.reason == "error"
    (d,) = result.diagnostics
    assert d.code == "E803" and "a1.R.probe" in d.message and "'pos'" in d.message
    assert "float[3]" in d.message and d.span.line == _line("real receptor probe")
    assert device.steps == bad_at


@pytest.mark.parametrize("cls", ["Probe", "TypedProbe"])
def test_a_name_that_is_no_output_is_E803(tmp_path: Path, cls: str) -> None:
    _, result = _run(tmp_path, cls, bad_at="1", bad="extra")
    assert result.reason == "error"
    (d,) = result.diagnostics
    assert d.code == "E803" and "'extra'" in d.message and "pos, count" in d.message


def test_a_typed_device_has_each_output_checked_when_it_first_measures_it(
        tmp_path: Path) -> None:
    """`pos` first appears at step 4, wrong: checked then, although `count` was checked
    (and trusted) since step 1."""
    rt, result = _run(tmp_path, "TypedProbe", late="4", bad_at="4")
    assert result.reason == "error"
    (d,) = result.diagnostics
    assert d.code == "E803" and "'pos'" in d.message
    assert rt.devices["a1.R.probe"].steps == 4


def _checked_measurements(impl: Any, types: dict[str, Any]) -> list[int]:
    """Wrap ``impl.measure`` so that every value it returns goes through the full check of
    its declared type (and is what the check returns); returns the list of checked counts."""
    convert = {name: converter(t) for name, t in types.items()}
    measure = impl.measure
    seen = [0]

    def checked() -> Any:
        measured = measure()
        for name, value in measured.items():
            out = convert[name](value)          # raises ValueTypeError on a wrong value
            assert out is value or _same(out, value), name
            for x in (value.values() if isinstance(value, dict) else (value,)):
                assert not isinstance(x, np.ndarray) or not x.flags.writeable, name
        seen[0] += 1
        return measured
    impl.measure = checked
    return seen


def _same(a: Any, b: Any) -> bool:
    """The check returned an equal record made of the very same field values."""
    return isinstance(a, dict) and a.keys() == b.keys() and all(a[k] is b[k] for k in a)


def test_the_mujoco_lwr4_device_measures_its_declared_types_over_a_run() -> None:
    comp = compiled(EXAMPLES / "lwr4_circle.rssm")
    config = RunConfig(base_dir=EXAMPLES, devices={
        "a1.E.lwr": "rssm_stdlib.lwr4plus.device:MujocoLwr4Device"})
    rt = runtime(comp, config)
    device = rt.devices["a1.E.lwr"]
    assert getattr(device.impl, "typed_measurements", False) is True
    seen = _checked_measurements(device.impl, {b.name: b.type for b in device.model.outputs})
    result = Simulator(rt, SimOptions(until=0.3)).run()
    assert result.ok, result.message
    assert seen[0] == device.steps >= 300
    # what the controller received is the device's last state, unchanged since
    state = rt.subsystems["a1.e.lwr"].vars["state"]
    assert set(state) == {"q", "dq", "position", "velocity"}
    assert all(not a.flags.writeable for a in state.values())


def test_the_mujoco_arm_device_measures_its_declared_types_over_a_run(tmp_path: Path) -> None:
    rt = arms_runtime(write_spec(write_robots(tmp_path)))
    devices = [d for d in rt.devices.values() if type(d.impl).__name__ == "MujocoArmDevice"]
    assert len(devices) == 2
    counts = []
    for device in devices:
        assert getattr(device.impl, "typed_measurements", False) is True
        counts.append(_checked_measurements(device.impl,
                                            {b.name: b.type for b in device.model.outputs}))
    result = Simulator(rt, SimOptions(until=0.2)).run()
    assert result.ok, result.message
    for device, seen in zip(devices, counts, strict=True):
        assert seen[0] == device.steps >= 200
