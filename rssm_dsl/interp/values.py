"""The values of the RSSM language for Python code that works with the front end's types
(devices, external operations, the interpreter): the semantics core's value domain
(rssm_core.values, where the representation and every operation are defined) addressed by
:class:`rssm_dsl.semantics.types.Type` instead of a descriptor.

| RSSM type            | Python value                                             |
|----------------------|----------------------------------------------------------|
| ``bool``             | ``bool``                                                 |
| ``int``              | ``int`` (64-bit)                                         |
| ``float``            | ``float``                                                |
| ``enum E {...}``     | ``str``, the member's name                               |
| ``lo..hi``           | ``int`` inside the range                                 |
| ``float[N]``         | read-only ``numpy.ndarray``, dtype float64, shape (N,)   |
| any other ``T[N]``   | ``tuple`` of N values of T                               |
| ``record R {...}``   | ``dict`` field name -> value, exactly the declared fields |

External code receives these values and must not modify them (float arrays are read-only;
copy before changing). :func:`converter` gives, for one type, the function that checks a value
coming from Python and converts it to this representation, raising :class:`ValueTypeError`
with the path of the offending part.
"""

from __future__ import annotations

from typing import Any

from rssm_core.values import (
    Convert,
    ValueTypeError,
    describe,
    equal,
    float_array,
    freeze,
    short,
    to_json,
)
from rssm_core.values import converter as _converter
from rssm_core.values import default as _default
from rssm_dsl.semantics.types import FLOAT, ArrayT, Type, descriptor

__all__ = ["Convert", "ValueTypeError", "converter", "default_value", "describe", "equal",
           "float_array", "freeze", "is_float_array", "short", "to_json"]


def converter(t: Type) -> Convert:
    """The check-and-convert function of a type (see the module docstring)."""
    return _converter(descriptor(t))


def default_value(t: Type) -> Any:
    """The value of a buffer or memory variable declared without an initial value."""
    return _default(descriptor(t))


def is_float_array(t: Type) -> bool:
    return isinstance(t, ArrayT) and t.element == FLOAT
