"""The interface between the interpreter and a device (a real effector E or receptor R).

A device is a Python class named by the device type's ``binding "module:Class"`` (or by
``rssmc simulate --device ID=module:Class``). The interpreter builds one instance per device
of the system, ``Class(spec)``, and drives it from the device net that closes the HPN: every
period it delivers what arrived on the device's input buffers (``receive``), lets it advance
(``step``), then sends what it ``measure``-s on its output buffers.

Values follow :mod:`rssm_dsl.interp.values` (float arrays as read-only float64 numpy arrays,
records as dicts). ``measure`` may return a subset of the outputs (the others keep their
values); what it returns is checked against the declared types (E803).

A device class whose ``measure`` builds every value of an output the same way, so that the
first value's type stands for all (a physics device reading fixed MuJoCo arrays), can say so
with the class attribute ``typed_measurements = True``: the interpreter then checks each
output the first time it is measured (E803, as for any device) and stores its later values
as they are, without the check at every period (a few per cent of a 1 kHz run). The device
must then also never change a value it has returned (its arrays read-only, a fresh dict for
each record). The standard library's MuJoCo devices do; tests/interp/test_device_checks.py
checks their measurements over a run.

A simulator such as the MuJoCo LWR4+ fits as: ``receive("torque", tau)`` stores the command,
``step(dt)`` integrates ``dt`` seconds of physics, ``measure()`` returns ``{"state": {...}}``.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import field
from pathlib import Path
from typing import Any, ClassVar, Protocol, runtime_checkable

from rssm_core.records import dataclass
from rssm_dsl.semantics.types import Type


@dataclass(frozen=True)
class DeviceSpec:
    """What a device instance is told about itself when it is built."""

    id: str                               # "a1.E.lwr"
    name: str                             # "lwr"
    device_type: str                      # "LWR4Plus"
    kind: str                             # "effector" | "receptor"
    frequency: float | None               # Hz; None: as fast as the net runs it
    inputs: Mapping[str, Type]            # buffers the device receives (commands)
    outputs: Mapping[str, Type]           # buffers the device sends (measurements)
    initial: Mapping[str, Any]            # initial values of all its buffers
    params: Mapping[str, Any] = field(default_factory=dict)   # `param`s of the device type
    options: Mapping[str, str] = field(default_factory=dict)  # --device-option ID:KEY=VALUE
    base_dir: Path = Path(".")            # folder of the specification (relative files)


@runtime_checkable
class Device(Protocol):
    """What the interpreter calls, in this order every period: receive* step measure."""

    def receive(self, buffer: str, value: Any) -> None:
        """A new value arrived on the input buffer ``buffer`` (only when one arrived)."""

    def step(self, dt: float) -> None:
        """Advance by ``dt`` seconds (simulated or wall-clock, per the run's mode)."""

    def measure(self) -> Mapping[str, Any]:
        """The current values of (some of) the output buffers, by buffer name."""

    def close(self) -> None:
        """Release resources; called once when the run ends."""


class DeviceBase:
    """A convenient base class: stores the spec, ignores commands, measures nothing new."""

    typed_measurements: ClassVar[bool] = False     # see the module docstring

    def __init__(self, spec: DeviceSpec) -> None:
        self.spec = spec
        self.time = 0.0

    def receive(self, buffer: str, value: Any) -> None:
        return None

    def step(self, dt: float) -> None:
        self.time += dt

    def measure(self) -> Mapping[str, Any]:
        return {}

    def close(self) -> None:
        return None

    def option(self, key: str, default: str | None = None) -> str | None:
        return self.spec.options.get(key, default)


class DeviceConfigError(Exception):
    """A device cannot be built from its spec and options (reported as E801 at the device)."""
