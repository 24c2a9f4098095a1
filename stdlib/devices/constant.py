"""A device whose measurements never change: its output buffers' initial values, or the
JSON object given as option ``values`` (``--device-option ID:values={"state": {...}}``)."""

from __future__ import annotations

import json
from collections.abc import Mapping
from typing import Any

from rssm_dsl.interp.device import DeviceBase, DeviceConfigError, DeviceSpec
from rssm_dsl.interp.values import ValueTypeError, converter


def values_option(spec: DeviceSpec) -> dict[str, Any]:
    """The device's option ``values``: a JSON object of output names (each an output of the
    device) to what the device makes of them; empty when the option is not given."""
    text = spec.options.get("values")
    if text is None:
        return {}
    try:
        given = json.loads(text)
    except json.JSONDecodeError as e:
        raise DeviceConfigError(f"option values is not JSON: {e.msg}") from e
    if not isinstance(given, dict):
        raise DeviceConfigError("option values must be a JSON object {output: value}")
    for name in given:
        if name not in spec.outputs:
            raise DeviceConfigError(f"{spec.id} has no output buffer '{name}'")
    return given


class ConstantDevice(DeviceBase):
    """Ignores commands; measures the same values every period."""

    def __init__(self, spec: DeviceSpec) -> None:
        super().__init__(spec)
        values = {name: spec.initial[name] for name in spec.outputs}
        for name, value in values_option(spec).items():
            try:
                values[name] = converter(spec.outputs[name])(value)
            except ValueTypeError as e:
                raise DeviceConfigError(f"option values, output '{name}': {e}") from e
        self.values: dict[str, Any] = values

    def measure(self) -> Mapping[str, Any]:
        return self.values
