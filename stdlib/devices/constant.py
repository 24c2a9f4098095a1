"""A device whose measurements never change: its output buffers' initial values, or the
JSON object given as option ``values`` (``--device-option ID:values={"state": {...}}``)."""

from __future__ import annotations

import json
from collections.abc import Mapping
from typing import Any

from rssm_dsl.interp.device import DeviceBase, DeviceConfigError, DeviceSpec
from rssm_dsl.interp.values import ValueTypeError, converter


class ConstantDevice(DeviceBase):
    """Ignores commands; measures the same values every period."""

    def __init__(self, spec: DeviceSpec) -> None:
        super().__init__(spec)
        values = {name: spec.initial[name] for name in spec.outputs}
        text = spec.options.get("values")
        if text is not None:
            try:
                given = json.loads(text)
            except json.JSONDecodeError as e:
                raise DeviceConfigError(f"option values is not JSON: {e.msg}") from e
            if not isinstance(given, dict):
                raise DeviceConfigError("option values must be a JSON object {output: value}")
            for name, value in given.items():
                if name not in spec.outputs:
                    raise DeviceConfigError(f"{spec.id} has no output buffer '{name}'")
                try:
                    values[name] = converter(spec.outputs[name])(value)
                except ValueTypeError as e:
                    raise DeviceConfigError(f"option values, output '{name}': {e}") from e
        self.values: dict[str, Any] = values

    def measure(self) -> Mapping[str, Any]:
        return self.values
