"""Enumerations and bounded integers (ranges) at run time: an enum memory variable switches
behaviours, an enum value is its member's name (in the variables and in the trace), a value
stored into a range outside it is a run-time failure (E802) that makes the behaviour's error
conditions hold, or stops the subsystem when there are none."""

from __future__ import annotations

from pathlib import Path

from rssm_core.trace import Receive, Send, TraceWriter
from rssm_core.trace import read_trace as read_events
from rssm_dsl.interp import SimOptions, Simulator
from rssm_dsl.interp.initial import InitialValues
from tests.interp.conftest import compile_text, run, runtime

PHASES = """
enum Phase { idle, approach, grasp, release }

system t {
  agent a1 {
    control c @ 100 Hz {
      memory phase: Phase = Phase.idle
      memory n: 0..10 = 0
      behaviour a {
        update memory {
          n := n + 1
          phase := if n >= 3 then Phase.grasp else Phase.approach
        }
        terminal moved when phase != Phase.approach and phase != Phase.idle
      }
      behaviour b {
        update memory { n := 0 }
        terminal never when false
      }
      behaviour other {
        update memory { n := 10 }
        terminal never when false
      }
      initial a
      switch a -> b when phase == Phase.grasp
      switch a -> other otherwise
    }
  }
}
"""


def test_an_enum_memory_variable_switches_behaviours(tmp_path: Path) -> None:
    comp = compile_text(tmp_path, PHASES)
    rt, result = run(comp, max_steps=300)
    assert result.ok, result.diagnostics
    c = rt.subsystems["a1.c"]
    assert c.behaviour == "b"
    assert c.vars["phase"] == "grasp"          # an enum value is its member's name
    assert c.vars["n"] == 0


COUNTER = """
system t {{
  agent a1 {{
    control c @ 100 Hz {{
      memory retries: 0..3 = 0
      memory after: int = 0
      behaviour count {{
        update memory {{
          retries := retries + 1
          after := after + 1
        }}
        terminal never when false
{error}
      }}
      behaviour recover {{
        update memory {{ after := 100 }}
        terminal never when false
      }}
      initial count
{switch}
    }}
  }}
}}
"""


def test_a_range_overflow_makes_the_error_condition_hold(tmp_path: Path) -> None:
    comp = compile_text(tmp_path, COUNTER.format(
        error="        error overflow when after > 1000",
        switch="      switch count -> recover when overflow"))
    rt, result = run(comp, max_steps=400)
    assert result.ok, result.diagnostics
    c = rt.subsystems["a1.c"]
    assert c.behaviour == "recover"
    assert c.handled_errors == 1
    assert c.vars["retries"] == 3              # the failed iteration committed nothing
    assert c.vars["after"] == 100


def test_a_range_overflow_without_an_error_condition_stops_the_subsystem(
        tmp_path: Path) -> None:
    comp = compile_text(tmp_path, COUNTER.format(error="", switch=""))
    rt, result = run(comp, max_steps=400)
    assert result.reason == "error"
    (d,) = result.diagnostics
    assert d.code == "E802"
    assert "value 4 is outside 0..3 of retries" in d.message
    assert comp.program.line(d.span.file, d.span.line).strip() == "retries := retries + 1"
    assert rt.subsystems["a1.c"].vars["retries"] == 3


def test_an_initial_value_outside_its_range_fails_before_the_run(tmp_path: Path) -> None:
    comp = compile_text(tmp_path, """
const start: int = 7
system t {
  agent a1 {
    control c {
      memory slot: 0..5 = start - 1
      behaviour b {
        update memory { slot := 0 }
        terminal never when false
      }
      initial b
    }
  }
}
""")
    assert comp.system is not None
    values = InitialValues(comp.system)
    (d,) = values.diagnostics
    assert d.code == "E802" and "value 6 is outside 0..5 of slot" in d.message


TRACED = """
enum Light { red, amber, green }
record Signal { light: Light, slot: 0..7 }

system t {
  agent a1 {
    control c @ 10 Hz {
      input echo: Signal from e.lamp
      output sig: Signal to e.lamp
      memory k: 0..7 = 0
      behaviour cycle {
        update sig {
          sig := {light: if k % 3 == 0 then Light.red else if k % 3 == 1 then Light.amber
                         else Light.green, slot: k}
        }
        update memory { k := (k + 1) % 8 }
        terminal seen when echo.light == Light.green and echo.slot > 100
      }
      initial cycle
      switch cycle -> end when seen
    }
    effector lamp @ 10 Hz {
      input sig: Signal from c
      output echo: Signal to c
      behaviour relay {
        update echo { echo := sig }
        terminal never when false
      }
      initial relay
    }
  }
}
"""


def test_a_trace_shows_enum_values_as_names(tmp_path: Path) -> None:
    comp = compile_text(tmp_path, TRACED)
    rt = runtime(comp)
    rt.tracer = TraceWriter(tmp_path / "t.jsonl")
    result = Simulator(rt, SimOptions(max_steps=600)).run()
    rt.tracer.close()
    assert result.ok, result.diagnostics
    events = read_events(tmp_path / "t.jsonl").events
    sent = [e.value for e in events if isinstance(e, Send) and e.buffer == "sig"]
    assert len(sent) >= 3
    assert [v["light"] for v in sent[:3]] == ["red", "amber", "green"]
    assert [v["slot"] for v in sent[:3]] == [0, 1, 2]
    received = [e.value for e in events if isinstance(e, Receive) and e.buffer == "echo"]
    assert received and all(v["light"] in ("red", "amber", "green") for v in received)
