"""The worked example of docs/devices.md, run as a user runs it (`rssmc simulate` in a
subprocess): examples/devices/heaters.rssm with its Python module heater_sim.py (a device class
and an external operation). Checked: the devices' measurements reach the control subsystem, a
per-instance option changes the behaviour of one of two instances of a device type, the
external operation's result reaches the devices, bad options and rebinding by --device."""

from __future__ import annotations

import importlib.util
import subprocess
import sys
from pathlib import Path
from types import ModuleType
from typing import Any

import pytest

from rssm_dsl.interp.trace import read_trace

ROOT = Path(__file__).resolve().parents[2]
EXAMPLE = ROOT / "examples" / "devices" / "heaters.rssm"
TO_C = "a1.e.heat.temperatures->a1.c.temperatures"
Event = dict[str, Any]


def heater_sim() -> ModuleType:
    """The example's Python module, loaded under a name of its own (not `heater_sim`, which
    the interpreter imports from the example's folder)."""
    spec = importlib.util.spec_from_file_location("docs_example_heater_sim",
                                                  EXAMPLE.parent / "heater_sim.py")
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def rssmc(*args: str | Path) -> subprocess.CompletedProcess[str]:
    return subprocess.run([sys.executable, "-m", "rssm_dsl", *map(str, args)], cwd=ROOT,
                          capture_output=True, text=True, timeout=120)


def simulate(tmp_path: Path, until: float, *options: str) -> tuple[str, list[Event]]:
    trace = tmp_path / "heaters.jsonl"
    r = rssmc("simulate", EXAMPLE.relative_to(ROOT), "--until", str(until), "--trace", trace,
              *options)
    assert r.returncode == 0, r.stderr
    return r.stdout, read_trace(trace)


def switches(events: list[Event]) -> list[Event]:
    return [e for e in events if e["event"] == "switch"]


def values(events: list[Event], channel: str) -> list[Any]:
    """The values the consumer of ``channel`` took, in order."""
    return [e["value"] for e in events if e["event"] == "receive" and e["channel"] == channel]


def settled(watts: float) -> float:
    """Where a heater settles: the power heat_command gives it, (target - T) / 10 of its watts,
    balances its loss to the room, LOSS * (T - ambient) (target 60 and ambient 20 are the
    specification's parameters)."""
    sim = heater_sim()
    target, ambient = 60.0, 20.0
    return float((watts * target / 10 + sim.LOSS * ambient) / (watts / 10 + sim.LOSS))


# big has 2000 W from the specification (its own value of the type's parameter watts), small
# the type's 500 W; options of the run override the parameter of either instance
RUNS = {"big": (), "small": ("--device-option", "a1.E.small:watts=2000",
                             "--device-option", "a1.E.big:watts=500")}


@pytest.mark.parametrize("hot", ["big", "small"])
def test_the_instance_given_more_power_gets_hot_first(hot: str, tmp_path: Path) -> None:
    out, events = simulate(tmp_path, 5, *RUNS[hot])
    (switch,) = switches(events)
    other = "small" if hot == "big" else "big"
    assert (switch["subsystem"], switch["from"], switch["to"]) == ("a1.c", "warming",
                                                                  f"{hot}_first")
    assert switch["conditions"] == {f"{hot}_hot": True, f"{other}_hot": False}
    assert switch["time"] == pytest.approx(1.7)
    assert f"a1.c       {hot}_first" in out
    assert "warming=18" in out and f"{hot}_first=33" in out     # iterations in 5 s
    # the devices' measurements reach c (after the initial values [0, 0] of heat's inputs,
    # sent before any measurement arrived): from the room's 20 degrees up, never past the
    # target; the one that switched c is past 50 degrees, the other is not
    seen = values(events, TO_C)
    assert seen[0] == [0.0, 0.0]
    assert all(20.0 <= t < 60.0 for v in seen[1:] for t in v)
    index = 0 if hot == "small" else 1
    last = max(i for i, e in enumerate(events) if e["event"] == "receive"
               and e["channel"] == TO_C and e["time"] <= switch["time"])
    before_switch = events[last]["value"]
    assert before_switch[index] >= 50.0 > before_switch[1 - index]


def test_each_heater_settles_where_the_extern_says(tmp_path: Path) -> None:
    _, events = simulate(tmp_path, 30)
    small, big = values(events, TO_C)[-1]
    assert small == pytest.approx(settled(500.0), abs=0.01)      # 58.5 degrees
    assert big == pytest.approx(settled(2000.0), abs=0.01)       # 59.6 degrees
    assert round(small, 1) == 58.5 and round(big, 1) == 59.6
    # the extern's result is the command each device receives: full power at first, then
    # what balances the loss
    sim = heater_sim()
    for name, temperature in (("small", small), ("big", big)):
        power = values(events, f"a1.e.heat.{name}_p->a1.E.{name}.power")
        assert power[0] == 1.0
        assert all(0.0 <= p <= 1.0 for p in power)
        assert power[-1] == pytest.approx(sim.heat_command(temperature, 60.0), abs=1e-3)


def test_a_bad_option_is_reported_at_the_device_before_the_run() -> None:
    r = rssmc("simulate", EXAMPLE.relative_to(ROOT), "--until", "1",
              "--device-option", "a1.E.big:watts=lots")
    assert r.returncode == 1
    assert "error[E801]: device a1.E.big (heater_sim:Heater): option watts: 'lots' is not a " \
           "number" in r.stderr
    assert "heaters.rssm:69:19" in r.stderr
    assert "Traceback" not in r.stderr + r.stdout
    r = rssmc("simulate", EXAMPLE.relative_to(ROOT), "--until", "1",
              "--device-option", "a1.E.huge:watts=3")
    assert r.returncode == 2 and "no device a1.E.huge" in r.stderr


def test_another_class_bound_with_device(tmp_path: Path) -> None:
    out, events = simulate(tmp_path, 10, "--device",
                           "a1.E.big=rssm_stdlib.devices.constant:ConstantDevice")
    assert set(values(events, "a1.E.big.temperature->a1.e.heat.big_t")) == {20.0}
    (switch,) = switches(events)
    assert (switch["to"], switch["time"]) == ("small_first", pytest.approx(6.6))
    assert "a1.c       small_first" in out
