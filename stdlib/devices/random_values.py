"""A device whose measurements are drawn at random every period: each output of finite type
(``bool``, an enum, a range ``lo..hi``, and such parts of records and arrays) gets a value
drawn from its type; other parts (``float``, ``int``) keep their initial values. Option
``values`` (``--device-option ID:values={"code": [0, 7]}``) gives per output the values to
draw from: a list of alternatives, or one value (measured every period, as
``ConstantDevice`` does). Option ``seed`` (an integer, default 0) seeds the draws, mixed
with the device's id so that two devices do not draw alike. ``rssmc verify`` binds every
device to it for its random runs (docs/verify.md, "Simulation as a falsifier").
"""

from __future__ import annotations

import random
import zlib
from collections.abc import Callable, Mapping
from typing import Any

from rssm_dsl.interp.device import DeviceBase, DeviceConfigError, DeviceSpec
from rssm_dsl.interp.values import ValueTypeError, converter
from rssm_dsl.semantics.types import ArrayT, RecordT, Type, finite_domain

from .constant import values_option

Draw = Callable[[random.Random], Any]


def _drawer(t: Type, initial: Any) -> Draw | None:
    """How to draw a value of ``t`` (None: nothing in it is drawn, it keeps ``initial``)."""
    domain = finite_domain(t)
    if domain is not None:
        return lambda rnd: domain[rnd.randrange(len(domain))]
    if isinstance(t, RecordT):
        parts = [(name, _drawer(ft, initial[name])) for name, ft in t.fields]
        if all(d is None for _, d in parts):
            return None
        return lambda rnd: {name: initial[name] if d is None else d(rnd) for name, d in parts}
    if isinstance(t, ArrayT):
        items = [_drawer(t.element, initial[k]) for k in range(t.size)]
        if all(d is None for d in items):
            return None
        return lambda rnd: tuple(initial[k] if d is None else d(rnd)
                                 for k, d in enumerate(items))
    return None


def _choices(name: str, t: Type, given: Any) -> Draw:
    """The draw of an output the option ``values`` names: one value, or a list of them."""
    convert = converter(t)
    try:
        value = convert(given)
        return lambda rnd: value
    except ValueTypeError:
        if not isinstance(given, list) or not given:
            raise DeviceConfigError(f"option values, output '{name}': neither a value of "
                                    f"type {t} nor a list of them") from None
    try:
        options = [convert(v) for v in given]
    except ValueTypeError as e:
        raise DeviceConfigError(f"option values, output '{name}': {e}") from e
    return lambda rnd: options[rnd.randrange(len(options))]


class RandomDevice(DeviceBase):
    """Ignores commands; measures values drawn at random every period."""

    def __init__(self, spec: DeviceSpec) -> None:
        super().__init__(spec)
        try:
            seed = int(spec.options.get("seed", "0"))
        except ValueError as e:
            raise DeviceConfigError(f"option seed is not an integer: {e}") from e
        self.rnd = random.Random(seed * 1_000_003 + zlib.crc32(spec.id.encode()))
        self.current: dict[str, Any] = {name: spec.initial[name] for name in spec.outputs}
        draws: dict[str, Draw] = {}
        for name, t in spec.outputs.items():
            draw = _drawer(t, spec.initial[name])
            if draw is not None:
                draws[name] = draw
        for name, value in values_option(spec).items():
            draws[name] = _choices(name, spec.outputs[name], value)
        self.draws = draws

    def measure(self) -> Mapping[str, Any]:
        rnd = self.rnd
        for name, draw in self.draws.items():
            self.current[name] = draw(rnd)
        return dict(self.current)
