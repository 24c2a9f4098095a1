"""Helpers for the interpreter tests: compile a spec (a file or a text) and run it."""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Any

import pytest

from rssm_dsl.diagnostics.render import render_text
from rssm_dsl.interp import RunConfig, RunResult, Runtime, SimOptions, Simulator, build_runtime
from rssm_dsl.pipeline import Compilation, compile_file

HERE = Path(__file__).resolve().parent
SPECS = HERE / "specs"
ROOT = HERE.parent.parent
EXAMPLES = ROOT / "examples"
CONSTANT = "rssm_stdlib.devices.constant:ConstantDevice"
Q0 = [0.0, -0.6, 0.0, 1.4, 0.0, 0.6 + 1.4 - math.pi, 0.0]
LWR_STATE = {"q": Q0, "dq": [0.0] * 7, "position": [0.58, 0.0, 0.4], "velocity": [0.0] * 3}


def compiled(path: Path) -> Compilation:
    comp = compile_file(path)
    assert comp.ok, render_text(comp.diagnostics, comp.program.line)
    return comp


def compile_text(tmp_path: Path, text: str, name: str = "spec.rssm") -> Compilation:
    path = tmp_path / name
    path.write_text(text, encoding="utf-8")
    return compiled(path)


def lwr4_config() -> RunConfig:
    return RunConfig(base_dir=EXAMPLES, devices={"a1.E.lwr": CONSTANT},
                     device_options={"a1.E.lwr": {"values": json.dumps({"state": LWR_STATE})}})


def runtime(comp: Compilation, config: RunConfig | None = None) -> Runtime:
    return build_runtime(comp, config or RunConfig(base_dir=comp.path.parent))


def run(comp: Compilation, config: RunConfig | None = None, **options: Any
        ) -> tuple[Runtime, RunResult]:
    rt = runtime(comp, config)
    result = Simulator(rt, SimOptions(**options)).run()
    return rt, result


def single_control(body: str, memory: str = "", extra: str = "", frequency: str = "") -> str:
    """A system of one control subsystem with one behaviour whose memory update is ``body``."""
    return f"""
{extra}
system t {{
  agent a1 {{
    control c {frequency} {{
{memory}
      behaviour b {{
        update memory {{
{body}
        }}
        terminal never when false
      }}
      initial b
    }}
  }}
}}
"""


@pytest.fixture
def lwr4() -> Compilation:
    return compiled(EXAMPLES / "lwr4_circle.rssm")
