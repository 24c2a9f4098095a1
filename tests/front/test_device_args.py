"""A device instance gives its own values of its device type's parameters
(`real effector big: Heater(watts = 2000.0)`): the other parameters keep the type's values;
the values are checked like initial values; every backend reads the instance's values."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

from rssm_dsl.interp import RunConfig, build_runtime
from rssm_dsl.pipeline import Compilation, compile_file
from tests.conftest import ROOT

SPEC = """extern two() -> float = "math:tau"
const K: float = 3.0
device effector Heater @ 10 Hz {{
  input power: float nonblocking
  output temperature: float nonblocking = 20.0
  param ambient: float = 20.0
  param watts: float = 500.0
  param level: 0..3 = 1
  binding "rssm_stdlib.devices.constant:ConstantDevice"
}}

system s {{
  agent a {{
    control c @ 10 Hz {{
      output p: float to e.h nonblocking = 0.0
      behaviour b {{
        update p {{ p := 1.0 }}
        terminal never when false
      }}
      initial b
    }}
    effector h @ 10 Hz {{
      input p: float from c nonblocking
      output one_p: float to E.one nonblocking
      output two_p: float to E.two nonblocking
      input one_t: float from E.one nonblocking
      input two_t: float from E.two nonblocking
      behaviour b {{
        update one_p {{ one_p := p }}
        update two_p {{ two_p := p }}
        terminal never when false
      }}
      initial b
    }}
    real effector one: Heater
    real effector two: Heater{args}
  }}
}}
"""
ARGS_LINE = 36


def compiled(tmp_path: Path, args: str) -> Compilation:
    path = tmp_path / "heaters.rssm"
    path.write_text(SPEC.format(args=args), encoding="utf-8")
    return compile_file(path)


def errors(comp: Compilation) -> list[tuple[str, int, int]]:
    return [(d.code, d.span.line, d.span.column) for d in comp.diagnostics if d.is_error]


def device_params(comp: Compilation) -> dict[str, dict[str, object]]:
    """What the interpreter gives each device class in ``spec.params``."""
    rt = build_runtime(comp, RunConfig(base_dir=comp.path.parent))
    return {i: dict(d.impl.spec.params) for i, d in rt.devices.items()}  # type: ignore[attr-defined]


def test_an_instance_replaces_only_the_parameters_it_gives(tmp_path: Path) -> None:
    comp = compiled(tmp_path, "(watts = 2000.0 * K, level = 3) @ 20 Hz")
    assert comp.ok, comp.diagnostics
    assert device_params(comp) == {
        "a.E.one": {"ambient": 20.0, "watts": 500.0, "level": 1},
        "a.E.two": {"ambient": 20.0, "watts": 6000.0, "level": 3},
    }


def test_no_arguments_and_empty_arguments_are_the_type_s_values(tmp_path: Path) -> None:
    for args in ("", "()"):
        comp = compiled(tmp_path, args)
        assert comp.ok, comp.diagnostics
        assert device_params(comp)["a.E.two"] == {"ambient": 20.0, "watts": 500.0, "level": 1}


@pytest.mark.parametrize(("args", "want"), [
    # a name the type does not declare, at the name
    ("(wats = 1.0)", [("E310", ARGS_LINE, 31)]),
    # one parameter twice, at the second
    ("(watts = 1.0, watts = 2.0)", [("E101", ARGS_LINE, 44)]),
    # the value is checked against the parameter's type, at the value
    ("(watts = true)", [("E201", ARGS_LINE, 39)]),
    ("(level = 4)", [("E214", ARGS_LINE, 39)]),
    # computed before the run, without calling Python
    ("(watts = two())", [("E215", ARGS_LINE, 39)]),
])
def test_a_bad_argument_is_an_error_where_it_is_written(args: str,
                                                        want: list[tuple[str, int, int]],
                                                        tmp_path: Path) -> None:
    assert errors(compiled(tmp_path, args)) == want


def test_ros2_parameters_are_the_instance_s(tmp_path: Path) -> None:
    comp = compiled(tmp_path, "(watts = 2000.0)")
    assert comp.ok
    out = tmp_path / "ws"
    r = subprocess.run([sys.executable, "-m", "rssm_dsl", "ros2", str(comp.path), "-o", str(out)],
                       capture_output=True, text=True, timeout=300, cwd=ROOT)
    assert r.returncode == 0, r.stderr
    text = (out / "s_a" / "config" / "params.yaml").read_text(encoding="utf-8")
    one = text[text.index("/a/E_one:"):text.index("/a/E_two:")]
    two = text[text.index("/a/E_two:"):]
    assert "watts: 500.0" in one and "watts: 2000.0" in two
    assert "ambient: 20.0" in one and "ambient: 20.0" in two


def test_fmt_keeps_the_arguments(tmp_path: Path) -> None:
    comp = compiled(tmp_path, "( watts=2000.0 ,level = 2, )@ 20 Hz")
    assert comp.ok
    r = subprocess.run([sys.executable, "-m", "rssm_dsl", "fmt", str(comp.path)],
                       capture_output=True, text=True, timeout=60, cwd=ROOT)
    assert r.returncode == 0, r.stderr
    text = comp.path.read_text(encoding="utf-8")
    assert "real effector two: Heater(watts = 2000.0, level = 2,) @ 20 Hz" in text
    again = compile_file(comp.path)
    assert again.ok and device_params(again) == device_params(comp)
