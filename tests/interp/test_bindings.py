"""External operations: resolution (stdlib, the spec's folder), diagnostics E801-E804,
failures taking the error condition path or stopping the run with a report."""

from __future__ import annotations

import shutil
from pathlib import Path

import numpy as np
import pytest

from rssm_dsl.bindings import BindingError, resolve
from rssm_dsl.interp import RunConfig, SimOptions, Simulator
from rssm_dsl.interp.errors import SetupError
from rssm_dsl.interp.trace import TraceWriter, read_trace
from tests.interp.conftest import SPECS, compile_text, compiled, run, runtime

OPS = (SPECS / "faulty_ops.py").read_text(encoding="utf-8")


def test_stdlib_is_importable_as_rssm_stdlib() -> None:
    fn = resolve("rssm_stdlib.lwr4plus.ops:circle_setpoint", [])
    assert callable(fn)
    sp = fn(0.05, 2.0, 0.0, 1.0)
    assert np.allclose(sp["position"], [0.58, 0.0, 0.4])      # phase 0: the start point
    sp = fn(0.05, 2.0, np.pi / 2, -1.0)                      # a quarter turn clockwise
    assert np.allclose(sp["position"], [0.53, -0.05, 0.4])
    assert np.allclose(np.linalg.norm(sp["velocity"]), 0.05 * np.pi)


def test_user_module_next_to_the_spec(tmp_path: Path) -> None:
    (tmp_path / "my_ops_mod.py").write_text("def twice(x):\n    return 2 * x\n")
    twice = resolve("my_ops_mod:twice", [tmp_path])
    assert callable(twice) and twice(4) == 8
    with pytest.raises(BindingError, match="no module 'absent_mod_xyz'"):
        resolve("absent_mod_xyz:f", [tmp_path])
    with pytest.raises(BindingError, match="has no attribute 'nope'"):
        resolve("my_ops_mod:nope", [tmp_path])


def _spec(extern: str, body: str, conditions: str = "terminal never when false",
          switches: str = "") -> str:
    return f"""
{extern}
system s {{
  agent a1 {{
    control c @ 100 Hz {{
      memory x: float = 0.0
      behaviour b {{
        update memory {{
{body}
        }}
        {conditions}
      }}
      initial b
{switches}
    }}
  }}
}}
"""


def test_missing_binding_is_e801_at_the_extern(tmp_path: Path) -> None:
    comp = compile_text(tmp_path, _spec('extern f(x: float) -> float = "nowhere_mod:f"',
                                        "          x := f(x)"))
    with pytest.raises(SetupError) as e:
        runtime(comp)
    (d,) = e.value.diagnostics
    assert d.code == "E801" and "nowhere_mod" in d.message
    assert d.span.line == 2 and d.related and "called here" in d.related[0].message


def test_wrong_arity_is_e804(tmp_path: Path) -> None:
    """`rssmc check` reads the arity from the source (E217, tests/front/test_binding_check.py);
    a function made at import time is only seen when the run imports it."""
    # modules are imported once per process: a name of its own
    (tmp_path / "made_ops.py").write_text("made = (lambda: lambda x: x)()\n")
    comp = compile_text(tmp_path, _spec(
        'extern f(x: float, y: float) -> float = "made_ops:made"', "          x := f(x, x)"))
    with pytest.raises(SetupError) as e:
        runtime(comp)
    assert [d.code for d in e.value.diagnostics] == ["E804"]


def test_wrong_return_type_is_e803_and_stops(tmp_path: Path) -> None:
    (tmp_path / "faulty_ops.py").write_text(OPS)
    comp = compile_text(tmp_path, _spec(
        'extern f(x: float) -> float = "faulty_ops:wrong_type"', "          x := f(x)"))
    _, result = run(comp, max_steps=100)
    assert result.reason == "error"
    (d,) = result.diagnostics
    assert d.code == "E803" and "str" in d.message and "where float is expected" in d.message


def test_failure_without_error_condition_stops_cleanly_and_flushes_the_trace(
        tmp_path: Path) -> None:
    (tmp_path / "faulty_ops.py").write_text(OPS)
    comp = compile_text(tmp_path, _spec(
        'extern risky(x: float) -> float = "faulty_ops:risky"',
        "          x := risky(x + 1.0) / 2.0"))
    rt = runtime(comp)
    rt.tracer = TraceWriter(tmp_path / "t.jsonl")
    result = Simulator(rt, SimOptions(until=1.0)).run()
    rt.tracer.close()
    assert result.reason == "error"
    (d,) = result.diagnostics
    assert d.code == "E802" and "risky() raised ValueError: x must not be 3" in d.message
    assert "has no error condition" in (d.hint or "")
    events = read_trace(tmp_path / "t.jsonl")
    assert events[-1]["event"] == "end" and events[-1]["reason"] == "error"
    errors = [e for e in events if e["event"] == "error"]
    assert errors and errors[0]["handled"] is False and errors[0]["code"] == "E802"


def test_failure_takes_the_error_condition_path(tmp_path: Path) -> None:
    d = tmp_path / "proj"
    shutil.copytree(SPECS, d)
    comp = compiled(d / "faulty.rssm")
    rt, result = run(comp, RunConfig(base_dir=d), max_steps=100_000)
    c = rt.subsystems["a1.c"]
    assert result.reason == "finished", result.message       # the run went on, then ended
    assert c.handled_errors == 1 and c.vars["recovered"] == 1
    assert c.behaviours["recover"].iterations == 1
    assert c.vars["x"] > 100.0 and c.ended


def test_a_bool_returned_for_an_int_is_e803(tmp_path: Path) -> None:
    """Python's True is an int to Python, not to RSSM: an extern declared `-> int` that
    returns a bool is a wrong return type (E803), not the number 1."""
    (tmp_path / "bool_ops.py").write_text("def flag(x):\n    return x > -1.0\n")
    comp = compile_text(tmp_path, _spec(
        'extern flag(x: float) -> int = "bool_ops:flag"', "          x := x + flag(x)"))
    _, result = run(comp, max_steps=100)
    assert result.reason == "error", result.message
    (d,) = result.diagnostics
    assert d.code == "E803" and "bool" in d.message, d.message


def test_sys_exit_in_an_extern_is_an_operation_failure(tmp_path: Path) -> None:
    """sys.exit() in user code is the operation failing (E802), not the end of rssmc with
    that exit code and nothing said."""
    (tmp_path / "exiting_ops.py").write_text("import sys\n\ndef f(x):\n    sys.exit(3)\n")
    comp = compile_text(tmp_path, _spec(
        'extern f(x: float) -> float = "exiting_ops:f"', "          x := f(x)"))
    _, result = run(comp, max_steps=100)
    assert result.reason == "error", result.message
    (d,) = result.diagnostics
    assert d.code == "E802" and "SystemExit" in d.message, d.message
