"""How the interpreter represents the values of the RSSM language, and the checks at the
boundary with Python code (external operations and devices).

| RSSM type            | Python value                                             |
|----------------------|----------------------------------------------------------|
| ``bool``             | ``bool``                                                 |
| ``int``              | ``int``                                                  |
| ``float``            | ``float``                                                |
| ``float[N]``         | read-only ``numpy.ndarray``, dtype float64, shape (N,)   |
| any other ``T[N]``   | ``tuple`` of N values of T                               |
| ``record R {...}``   | ``dict`` field name -> value, exactly the declared fields |

Values are never changed in place: an assignment to a field or an element builds a new
value, so buffers, channel slots and memory may share values safely. External code receives
these values and must not modify them (float arrays are read-only; copy before changing).

:func:`converter` gives, for one type, the function that checks a value coming from Python and
converts it to this representation (ints are accepted for floats; lists, tuples and arrays for
arrays; mappings or objects with the right attributes for records), raising
:class:`ValueTypeError` with the path of the offending part.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping
from typing import Any

import numpy as np
from numpy.typing import NDArray

from rssm_dsl.semantics.types import BOOL, FLOAT, INT, ArrayT, RecordT, Scalar, Type

Convert = Callable[[Any], Any]
F64 = np.dtype(np.float64)
FloatArray = NDArray[np.float64]


class ValueTypeError(Exception):
    """A Python value that does not fit an RSSM type; ``path`` locates the offending part."""

    def __init__(self, expected: Type, got: Any, path: str = "") -> None:
        self.expected = expected
        self.got = got
        self.path = path
        where = f" at {path}" if path else ""
        super().__init__(f"{describe(got)}{where} where {expected} is expected")


def freeze(a: FloatArray) -> FloatArray:
    a.flags.writeable = False
    return a


def float_array(items: Any, size: int | None = None) -> FloatArray:
    """A fresh read-only float64 array of ``items``."""
    a = np.array(items, dtype=np.float64)
    if size is not None and a.shape != (size,):
        raise ValueError(f"shape {a.shape}, expected ({size},)")
    a.flags.writeable = False
    return a


def is_float_array(t: Type) -> bool:
    return isinstance(t, ArrayT) and t.element == FLOAT


def describe(v: Any) -> str:
    """A short description of a Python value, for error messages."""
    if isinstance(v, bool | np.bool_):
        return f"bool {bool(v)}"
    if isinstance(v, int | np.integer):
        return f"int {int(v)}"
    if isinstance(v, float | np.floating):
        return f"float {float(v)!r}"
    if isinstance(v, np.ndarray):
        return f"an array of shape {v.shape} ({v.dtype})"
    if isinstance(v, list | tuple):
        return f"a {type(v).__name__} of {len(v)} item(s)"
    if isinstance(v, Mapping):
        keys = ", ".join(str(k) for k in list(v)[:6])
        return f"a mapping with keys {{{keys}}}"
    if v is None:
        return "None"
    text = repr(v)
    return f"{type(v).__name__} {text[:40]}"


# ---------------------------------------------------------------- defaults


def default_value(t: Type) -> Any:
    """The value of a buffer or memory variable declared without an initial value."""
    if t == BOOL:
        return False
    if t == INT:
        return 0
    if t == FLOAT:
        return 0.0
    if isinstance(t, ArrayT):
        if t.element == FLOAT:
            return freeze(np.zeros(t.size, dtype=np.float64))
        return tuple(default_value(t.element) for _ in range(t.size))
    assert isinstance(t, RecordT)
    return {n: default_value(ft) for n, ft in t.fields}


# ---------------------------------------------------------------- conversion at the boundary


def _scalar(t: Scalar) -> Convert:
    if t == FLOAT:
        def to_float(v: Any) -> float:
            if type(v) is float:
                return v
            if isinstance(v, bool | np.bool_) or not isinstance(v, int | float | np.integer
                                                                   | np.floating):
                raise ValueTypeError(t, v)
            return float(v)
        return to_float
    if t == INT:
        def to_int(v: Any) -> int:
            if isinstance(v, bool | np.bool_) or not isinstance(v, int | np.integer):
                raise ValueTypeError(t, v)
            return int(v)
        return to_int

    def to_bool(v: Any) -> bool:
        if not isinstance(v, bool | np.bool_):
            raise ValueTypeError(t, v)
        return bool(v)
    return to_bool


def _float_array(t: ArrayT) -> Convert:
    size = t.size

    shape = (size,)

    def to_array(v: Any) -> FloatArray:
        if type(v) is np.ndarray:
            if v.shape != shape or v.dtype.kind not in "fiu":
                raise ValueTypeError(t, v)
            if v.dtype is F64 and not v.flags.writeable:
                return v
            return freeze(v.astype(np.float64, copy=True))
        if isinstance(v, np.ndarray):
            return to_array(np.asarray(v))
        if not isinstance(v, list | tuple) or len(v) != size:
            raise ValueTypeError(t, v)
        for k, x in enumerate(v):
            if isinstance(x, bool | np.bool_) or not isinstance(
                    x, int | float | np.integer | np.floating):
                raise ValueTypeError(FLOAT, x, f"[{k}]")
        return freeze(np.array(v, dtype=np.float64))
    return to_array


def _array(t: ArrayT) -> Convert:
    if t.element == FLOAT:
        return _float_array(t)
    item = converter(t.element)
    size = t.size

    def to_tuple(v: Any) -> tuple[Any, ...]:
        if not isinstance(v, list | tuple | np.ndarray) or len(v) != size:
            raise ValueTypeError(t, v)
        out = []
        for k, x in enumerate(v):
            try:
                out.append(item(x))
            except ValueTypeError as e:
                raise ValueTypeError(e.expected, e.got, f"[{k}]{e.path}") from None
        return tuple(out)
    return to_tuple


def _record(t: RecordT) -> Convert:
    fields = [(n, converter(ft)) for n, ft in t.fields]
    names = {n for n, _ in t.fields}

    size = len(fields)

    def to_dict(v: Any) -> dict[str, Any]:
        if type(v) is dict and len(v) == size:
            try:
                return {n: conv(v[n]) for n, conv in fields}
            except (KeyError, ValueTypeError):
                pass                     # the slow path below says what is wrong
        return checked(v)

    def checked(v: Any) -> dict[str, Any]:
        out: dict[str, Any] = {}
        if isinstance(v, Mapping):
            extra = [str(k) for k in v if k not in names]
            if extra:
                raise ValueTypeError(t, v, f"field(s) {', '.join(extra)} not in {t.name}")
            get: Callable[[str], Any] = v.__getitem__
            has: Callable[[str], bool] = v.__contains__
        else:
            def get(n: str) -> Any:
                return getattr(v, n)

            def has(n: str) -> bool:
                return hasattr(v, n)
        for n, conv in fields:
            if not has(n):
                raise ValueTypeError(t, v, f".{n} (missing)")
            try:
                out[n] = conv(get(n))
            except ValueTypeError as e:
                raise ValueTypeError(e.expected, e.got, f".{n}{e.path}") from None
        return out
    return to_dict


def converter(t: Type) -> Convert:
    """The check-and-convert function of a type (see the module docstring)."""
    if isinstance(t, Scalar):
        return _scalar(t)
    if isinstance(t, ArrayT):
        return _array(t)
    return _record(t)


# ---------------------------------------------------------------- equality, JSON, text


def equal(a: Any, b: Any) -> bool:
    """Structural equality of two values of one type (arrays and records element-wise)."""
    if isinstance(a, np.ndarray) or isinstance(b, np.ndarray):
        return bool(np.array_equal(np.asarray(a, dtype=np.float64),
                                   np.asarray(b, dtype=np.float64)))
    if isinstance(a, dict) and isinstance(b, dict):
        return a.keys() == b.keys() and all(equal(a[k], b[k]) for k in a)
    if isinstance(a, tuple) and isinstance(b, tuple):
        return len(a) == len(b) and all(equal(x, y) for x, y in zip(a, b, strict=True))
    return bool(a == b)


def _json_float(x: float) -> float | str:
    if math.isfinite(x):
        return x
    return "nan" if math.isnan(x) else ("inf" if x > 0 else "-inf")


def to_json(v: Any) -> Any:
    """A JSON-compatible form of a value (non-finite floats as "nan", "inf", "-inf")."""
    if isinstance(v, bool | int | str) or v is None:
        return v
    if isinstance(v, float):
        return _json_float(v)
    if isinstance(v, np.ndarray):
        return [_json_float(float(x)) for x in v.tolist()]
    if isinstance(v, dict):
        return {str(k): to_json(x) for k, x in v.items()}
    if isinstance(v, tuple | list):
        return [to_json(x) for x in v]
    if isinstance(v, np.generic):
        return to_json(v.item())
    return str(v)


def short(v: Any, width: int = 48) -> str:
    """A one-line text of a value for the live summary."""
    if isinstance(v, float):
        text = f"{v:.4g}"
    elif isinstance(v, np.ndarray):
        text = "[" + ", ".join(f"{x:.3g}" for x in v.tolist()) + "]"
    elif isinstance(v, dict):
        text = "{" + ", ".join(f"{k}: {short(x, width)}" for k, x in v.items()) + "}"
    elif isinstance(v, tuple):
        text = "[" + ", ".join(short(x, width) for x in v) + "]"
    else:
        text = str(v).lower() if isinstance(v, bool) else str(v)
    return text if len(text) <= width else text[: width - 1] + "…"
