"""The Python side of examples/devices/heaters.rssm (docs/devices.md): the device class
`Heater` and the external operation `heat_command`."""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

from rssm_dsl.interp.device import DeviceBase, DeviceConfigError, DeviceSpec

CAPACITY = 100.0   # J/K: the heat it takes to warm a heater by 1 °C
LOSS = 2.0         # W/K: the heat it loses to the room per °C above the room


class Heater(DeviceBase):
    """A heating element: `power` (0..1) of its `watts` heats it, it cools towards the room's
    temperature `ambient`; it measures its `temperature`. `watts` and `ambient` are the
    device type's parameters, with the instance's own values where the specification gives
    them (`real effector big: Heater(watts = 2000.0)`); an option of the run,
    `--device-option ID:watts=...`, overrides `watts`."""

    def __init__(self, spec: DeviceSpec) -> None:
        super().__init__(spec)                       # keeps spec, starts self.time at 0
        self.ambient = float(spec.params["ambient"])
        self.temperature = float(spec.initial["temperature"])
        self.power = 0.0
        self.watts = float(spec.params["watts"])
        text = self.option("watts")                  # --device-option ID:watts=...
        if text is not None:
            try:
                self.watts = float(text)
            except ValueError:
                raise DeviceConfigError(f"option watts: '{text}' is not a number") from None

    def receive(self, buffer: str, value: Any) -> None:
        if buffer == "power":                        # only when a new command arrived
            self.power = value

    def step(self, dt: float) -> None:
        super().step(dt)
        heat = self.watts * self.power - LOSS * (self.temperature - self.ambient)
        self.temperature += dt * heat / CAPACITY

    def measure(self) -> Mapping[str, Any]:
        return {"temperature": self.temperature}


def heat_command(temperature: float, target: float) -> float:
    """Full power up to 10 °C below the target, then less and less, none above it."""
    return min(1.0, max(0.0, (target - temperature) / 10.0))
