"""Values of the RSSM language inside the generated ROS 2 nodes, and the operations the
generated code calls. The representation is the interpreter's (rssm_dsl.interp.values), so a
node computes what `rssmc simulate` computes:

| RSSM type          | Python value                                          |
|--------------------|-------------------------------------------------------|
| bool / int / float | bool / int / float                                    |
| float[N]           | read-only numpy.ndarray, dtype float64, shape (N,)    |
| any other T[N]     | tuple of N values                                     |
| record R {...}     | dict field name -> value                              |

Values are never changed in place. A type is described by a *descriptor*, a nested tuple the
generator writes into the node: ``("bool",)``, ``("int",)``, ``("float",)``,
``("array", ELEMENT, N)``, ``("record", NAME, ((FIELD, DESCRIPTOR), ...))``.

Run-time failures raise :class:`OperationError` with the code the interpreter reports
(E802 an operation failed, E803 an external operation returned the wrong type) and the
``file:line:column`` of the expression.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping
from typing import Any

import numpy as np

Desc = tuple[Any, ...]
Convert = Callable[[Any], Any]

BOOL: Desc = ("bool",)
INT: Desc = ("int",)
FLOAT: Desc = ("float",)


class OperationError(Exception):
    """An operation of the specification failed at run time."""

    def __init__(self, code: str, message: str, where: str) -> None:
        super().__init__(f"{where}: {message} [{code}]")
        self.code = code
        self.message = message
        self.where = where


class ValueTypeError(Exception):
    def __init__(self, expected: Desc, got: Any, path: str = "") -> None:
        where = f" at {path}" if path else ""
        super().__init__(f"{describe(got)}{where} where {type_text(expected)} is expected")
        self.expected = expected
        self.got = got
        self.path = path


def type_text(d: Desc) -> str:
    if d[0] == "array":
        return f"{type_text(d[1])}[{d[2]}]"
    if d[0] == "record":
        return str(d[1])
    return str(d[0])


def describe(v: Any) -> str:
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
        return "a mapping with keys {" + ", ".join(str(k) for k in list(v)[:6]) + "}"
    return "None" if v is None else f"{type(v).__name__} {repr(v)[:40]}"


# ---------------------------------------------------------------- construction


def freeze(a: Any) -> Any:
    a.flags.writeable = False
    return a


def float_array(items: Any) -> Any:
    """A fresh read-only float64 array of ``items``."""
    a = np.array(items, dtype=np.float64)
    a.flags.writeable = False
    return a


def is_float_array(d: Desc) -> bool:
    return bool(d[0] == "array" and d[1] == FLOAT)


def default(d: Desc) -> Any:
    """The value of a buffer or memory variable declared without an initial value."""
    kind = d[0]
    if kind == "bool":
        return False
    if kind == "int":
        return 0
    if kind == "float":
        return 0.0
    if kind == "array":
        if d[1] == FLOAT:
            return freeze(np.zeros(d[2], dtype=np.float64))
        return tuple(default(d[1]) for _ in range(d[2]))
    return {name: default(fd) for name, fd in d[2]}


# ---------------------------------------------------------------- conversion at the boundary


def converter(d: Desc) -> Convert:
    """Check a value coming from Python code (an external operation, a device, a parameter)
    and convert it to the representation above; raises :class:`ValueTypeError`."""
    kind = d[0]
    if kind == "float":
        def to_float(v: Any) -> float:
            if type(v) is float:
                return v
            if isinstance(v, bool | np.bool_) or not isinstance(
                    v, int | float | np.integer | np.floating):
                raise ValueTypeError(d, v)
            return float(v)
        return to_float
    if kind == "int":
        def to_int(v: Any) -> int:
            if isinstance(v, bool | np.bool_) or not isinstance(v, int | np.integer):
                raise ValueTypeError(d, v)
            return int(v)
        return to_int
    if kind == "bool":
        def to_bool(v: Any) -> bool:
            if not isinstance(v, bool | np.bool_):
                raise ValueTypeError(d, v)
            return bool(v)
        return to_bool
    if kind == "array":
        return _float_array(d) if d[1] == FLOAT else _array(d)
    return _record(d)


def _float_array(d: Desc) -> Convert:
    size = d[2]

    def to_array(v: Any) -> Any:
        if isinstance(v, np.ndarray):
            if v.shape != (size,) or v.dtype.kind not in "fiu":
                raise ValueTypeError(d, v)
            if v.dtype == np.float64 and not v.flags.writeable:
                return v
            return freeze(v.astype(np.float64, copy=True))
        if not isinstance(v, list | tuple) or len(v) != size:
            raise ValueTypeError(d, v)
        for k, x in enumerate(v):
            if isinstance(x, bool | np.bool_) or not isinstance(
                    x, int | float | np.integer | np.floating):
                raise ValueTypeError(FLOAT, x, f"[{k}]")
        return freeze(np.array(v, dtype=np.float64))
    return to_array


def _array(d: Desc) -> Convert:
    item, size = converter(d[1]), d[2]

    def to_tuple(v: Any) -> tuple[Any, ...]:
        if not isinstance(v, list | tuple | np.ndarray) or len(v) != size:
            raise ValueTypeError(d, v)
        out = []
        for k, x in enumerate(v):
            try:
                out.append(item(x))
            except ValueTypeError as e:
                raise ValueTypeError(e.expected, e.got, f"[{k}]{e.path}") from None
        return tuple(out)
    return to_tuple


def _record(d: Desc) -> Convert:
    fields = [(n, converter(fd)) for n, fd in d[2]]
    names = {n for n, _ in d[2]}

    def to_dict(v: Any) -> dict[str, Any]:
        out: dict[str, Any] = {}
        if isinstance(v, Mapping):
            extra = [str(k) for k in v if k not in names]
            if extra:
                raise ValueTypeError(d, v, f"field(s) {', '.join(extra)} not in {d[1]}")
            get: Callable[[str], Any] = v.__getitem__
            has: Callable[[str], bool] = v.__contains__
        else:
            def get(n: str) -> Any:
                return getattr(v, n)

            def has(n: str) -> bool:
                return hasattr(v, n)
        for n, conv in fields:
            if not has(n):
                raise ValueTypeError(d, v, f".{n} (missing)")
            try:
                out[n] = conv(get(n))
            except ValueTypeError as e:
                raise ValueTypeError(e.expected, e.got, f".{n}{e.path}") from None
        return out
    return to_dict


def to_json(v: Any) -> Any:
    """A JSON-compatible form of a value (non-finite floats as "nan", "inf", "-inf")."""
    if isinstance(v, bool | int | str) or v is None:
        return v
    if isinstance(v, float):
        return v if math.isfinite(v) else ("nan" if math.isnan(v) else
                                           ("inf" if v > 0 else "-inf"))
    if isinstance(v, np.ndarray):
        return [to_json(float(x)) for x in v.tolist()]
    if isinstance(v, dict):
        return {str(k): to_json(x) for k, x in v.items()}
    if isinstance(v, tuple | list):
        return [to_json(x) for x in v]
    if isinstance(v, np.generic):
        return to_json(v.item())
    return str(v)


# ---------------------------------------------------------------- operations


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


def _fail(where: str, message: str) -> OperationError:
    return OperationError("E802", message, where)


def index(a: Any, i: int, size: int, floats: bool, where: str) -> Any:
    if 0 <= i < size:
        return a.item(i) if floats else a[i]
    raise _fail(where, f"index {i} is out of range (indices run from 0 to {size - 1})")


def set_item(container: Any, i: int, size: int, item: Any, where: str) -> Any:
    """``container`` with element ``i`` replaced (a new value)."""
    if not 0 <= i < size:
        raise _fail(where, f"index {i} is out of range (indices run from 0 to {size - 1})")
    if isinstance(container, np.ndarray):
        c = container.copy()
        c[i] = item
        return freeze(c)
    items = list(container)
    items[i] = item
    return tuple(items)


def set_field(container: Any, name: str, value: Any) -> Any:
    new = dict(container)
    new[name] = value
    return new


def div(x: Any, y: Any, where: str) -> Any:
    if y == 0:
        raise _fail(where, "division by zero")
    return x / y


def mod(x: Any, y: Any, where: str) -> Any:
    if y == 0:
        raise _fail(where, "remainder by zero")
    return x % y


def as_np(x: Any) -> Any:
    """An int (or bool) array operand, a tuple, as a float64 array for arithmetic."""
    return np.array(x, dtype=np.float64)


def aadd(x: Any, y: Any) -> Any:
    return freeze(np.add(x, y))


def asub(x: Any, y: Any) -> Any:
    return freeze(np.subtract(x, y))


def amul(x: Any, y: Any) -> Any:
    return freeze(np.multiply(x, y))


def adiv(x: Any, y: Any, y_array: bool, where: str) -> Any:
    if (not np.all(y)) if y_array else y == 0:
        raise _fail(where, "division by zero")
    return freeze(np.divide(x, y))


def aneg(x: Any) -> Any:
    return freeze(np.negative(x))


def math1(fn: Callable[[float], float], name: str, x: float, where: str) -> float:
    try:
        return fn(x)
    except (ValueError, OverflowError) as e:
        raise _fail(where, f"{name}({x!r}): {e}") from None


def floor(x: float) -> float:
    return float(math.floor(x))


def ceil(x: float) -> float:
    return float(math.ceil(x))


def norm(x: Any) -> float:
    return float(np.linalg.norm(x))


def dot(x: Any, y: Any, where: str) -> float:
    if len(x) != len(y):
        raise _fail(where, f"dot() of arrays of sizes {len(x)} and {len(y)}")
    return float(np.dot(x, y))


def cross(x: Any, y: Any) -> Any:
    return freeze(np.cross(x, y))


def call(fn: Callable[..., Any], conv: Convert, name: str, where: str, *args: Any) -> Any:
    """Call an external operation and check what it returns against its declared type."""
    try:
        r = fn(*args)
    except Exception as e:
        raise OperationError("E802", f"{name}() raised {type(e).__name__}: {e}", where) from e
    try:
        return conv(r)
    except ValueTypeError as e:
        raise OperationError("E803", f"{name}() returned {e}", where) from None
