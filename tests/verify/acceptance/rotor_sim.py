"""A very small vertical-axis model of a quadrotor's rotors, for rssmc simulate."""
from collections.abc import Mapping
from typing import Any

from rssm_dsl.interp.device import DeviceBase

RATES = {"off": 0.0, "hover": 0.0, "cruise": 0.0, "descend": -0.6, "climb": 1.0}


class Rotors(DeviceBase):
    def __init__(self, spec) -> None:
        super().__init__(spec)
        self.altitude = float(spec.params["start_altitude"])
        self.mode = "off"

    def receive(self, buffer: str, value: Any) -> None:
        if buffer == "mode":
            self.mode = value

    def step(self, dt: float) -> None:
        super().step(dt)
        self.altitude = max(0.0, self.altitude + RATES.get(self.mode, 0.0) * dt)

    def measure(self) -> Mapping[str, Any]:
        return {"altitude": self.altitude}
