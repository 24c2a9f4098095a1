"""A device whose measurements repeat its last commands: each output buffer echoes the input
buffer of the same name, or the only input when the device has one input and one output of
the same type; option ``map`` pairs them explicitly (``out1=in1,out2=in2``)."""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

from rssm_dsl.interp.device import DeviceBase, DeviceConfigError, DeviceSpec


class EchoDevice(DeviceBase):
    """Outputs hold the last value received on their paired input (initially their own
    initial value)."""

    def __init__(self, spec: DeviceSpec) -> None:
        super().__init__(spec)
        self.pairs: dict[str, str] = self._pairs(spec)   # input -> output
        self.values: dict[str, Any] = {name: spec.initial[name] for name in spec.outputs}

    @staticmethod
    def _pairs(spec: DeviceSpec) -> dict[str, str]:
        text = spec.options.get("map")
        pairs: dict[str, str] = {}
        if text:
            for item in text.split(","):
                out, sep, inp = item.partition("=")
                out, inp = out.strip(), inp.strip()
                if not sep or out not in spec.outputs or inp not in spec.inputs:
                    raise DeviceConfigError(f"option map: '{item}' is not OUTPUT=INPUT of "
                                            f"{spec.id}")
                pairs[inp] = out
        elif len(spec.inputs) == 1 and len(spec.outputs) == 1:
            (inp, it), (out, ot) = next(iter(spec.inputs.items())), next(iter(spec.outputs.items()))
            if it == ot:
                pairs[inp] = out
        if not pairs:
            pairs = {n: n for n in spec.inputs if n in spec.outputs}
        for inp, out in pairs.items():
            if spec.inputs[inp] != spec.outputs[out]:
                raise DeviceConfigError(f"cannot echo input '{inp}' ({spec.inputs[inp]}) on "
                                        f"output '{out}' ({spec.outputs[out]})")
        if not pairs and spec.inputs and spec.outputs:
            raise DeviceConfigError(f"{spec.id}: no input and output of the same name to echo",
                                    )
        return pairs

    def receive(self, buffer: str, value: Any) -> None:
        out = self.pairs.get(buffer)
        if out is not None:
            self.values[out] = value

    def measure(self) -> Mapping[str, Any]:
        return self.values
