"""The paper's LWR4+ is one robot of the generic device: examples/lwr4_circle.rssm run with its
device rebound to ``rssm_stdlib.robots.device:MujocoArmDevice`` (robot ``lwr4plus`` of the
standard library's table) gives the same trajectory as the LWR4+'s own device
(stdlib/lwr4plus/device.py), state for state, bit for bit."""

from __future__ import annotations

from typing import Any

import numpy as np

from rssm_dsl.interp import RunConfig, SimOptions, Simulator, build_runtime
from rssm_dsl.pipeline import compile_file
from tests.conftest import EXAMPLES

SPEC = EXAMPLES / "lwr4_circle.rssm"
GENERIC = "rssm_stdlib.robots.device:MujocoArmDevice"


def _run(config: RunConfig) -> tuple[list[dict[str, Any]], Any]:
    comp = compile_file(SPEC)
    rt = build_runtime(comp, config)
    device: Any = rt.devices["a1.E.lwr"].impl
    states: list[dict[str, Any]] = []
    device.observers.append(lambda d: states.append(d.state))
    result = Simulator(rt, SimOptions(seed=0, until=1.0)).run()
    assert result.ok, result.message
    return states, device


def test_the_generic_device_runs_the_lwr4_experiment_identically() -> None:
    base = SPEC.parent
    own, own_device = _run(RunConfig(base_dir=base))
    generic, generic_device = _run(RunConfig(
        base_dir=base, devices={"a1.E.lwr": GENERIC},
        device_options={"a1.E.lwr": {"robot": "lwr4plus"}}))
    assert type(generic_device).__name__ == "MujocoArmDevice"
    assert type(own_device).__name__ == "MujocoLwr4Device"
    assert np.allclose(generic_device.torque_high, own_device.arm.torque_high)
    assert len(own) == len(generic) == 1001
    for a, b in zip(own, generic, strict=True):
        for key in ("q", "dq", "position", "velocity"):
            assert np.allclose(a[key], b[key], rtol=0, atol=0), key
    # and the arm moved along the circle (not two arms at rest)
    assert np.linalg.norm(own[-1]["position"] - own[0]["position"]) > 0.01
