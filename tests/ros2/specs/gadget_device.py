"""A thermometer for tests/ros2/specs/wire.rssm: its temperature rises by one degree a step
from 20 and falls back to 20 after 40 (plain Python: no import of rssmc, as a vendor's
simulator would be)."""

from __future__ import annotations

from typing import Any


class Thermometer:
    def __init__(self, spec: Any) -> None:
        self.spec = spec
        self.temperature = 20.0
        self.steps = 0

    def receive(self, buffer: str, value: Any) -> None:
        raise ValueError(f"a thermometer has no input {buffer}")

    def step(self, dt: float) -> None:
        self.steps += 1
        self.temperature = 20.0 if self.temperature >= 40.0 else self.temperature + 1.0

    def measure(self) -> dict[str, float]:
        return {"temperature": self.temperature}

    def close(self) -> None:
        return None
