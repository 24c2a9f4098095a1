"""The values of the RSSM language and every operation on them, defined once.

The interpreter (``rssmc simulate``) and the generated ROS 2 nodes both run the Python that
:mod:`rssm_dsl.pycode` writes for an expression; that code calls the functions of this
module (imported as ``_rt``) for everything that is not plain Python arithmetic on floats, so
that division, remainder, integer overflow, indexing, array arithmetic and the checks at the
boundary with Python code mean one thing everywhere.

Representation:

| RSSM type          | Python value                                          |
|--------------------|-------------------------------------------------------|
| ``bool``           | ``bool``                                              |
| ``int``            | ``int``, a signed 64-bit integer                      |
| ``float``          | ``float`` (IEEE 754 double)                           |
| ``enum E {...}``   | ``str``, the member's name (``"grasp"``)              |
| ``lo..hi``         | ``int``, with ``lo <= value <= hi``                   |
| ``float[N]``       | read-only ``numpy.ndarray``, dtype float64, shape (N,) |
| any other ``T[N]`` | ``tuple`` of N values                                 |
| ``record R {...}`` | ``dict`` field name -> value, exactly the declared fields |

An enum value is its member's name, so traces and JSON show names. A range value is checked
whenever it is stored (an assignment, an initial value, a field of a record literal, an
argument of an external operation): the code :mod:`rssm_dsl.pycode` writes calls
:func:`in_range` (or :func:`check_ranges` for arrays of ranges) where a value of a wider type
is stored into a range, and a value outside fails with E802 ("value 4 is outside 0..3 of
retries"); a range value read is an ordinary int. At the boundary with Python code
(:func:`converter`) an enum takes only a member's name, a range only an int inside it (E803
otherwise).

Values are never changed in place: replacing a field or an element builds a new value, so
buffers, channel slots and memory may share values safely.

Arithmetic (docs/language.md, "Operators"):

* ``int`` is a signed 64-bit integer: ``+ - * %``, unary ``-`` and ``abs`` of ints whose exact
  result lies outside [-2**63, 2**63 - 1] fail with "integer overflow" (E802), and so does an
  int coming from Python code (an external operation, a device) outside that range (E803);
* ``/`` is always float division; ``%`` follows Python: the result has the sign of the
  divisor (``-7 % 3 == 2``, ``7 % -3 == -2``, ``-7.5 % 2.0 == 0.5``); a division or remainder
  by zero fails (E802), for ints and floats alike;
* floats follow IEEE 754 otherwise: overflow gives ``inf``, NaN compares unequal to
  everything (itself included) and propagates through ``min``, ``max`` and ``clamp``; a math
  function outside its domain (``sqrt(-1.0)``, ``log(0.0)``, ``floor(inf)``) fails (E802).

A type is described by a *descriptor*, a nested tuple: ``("bool",)``, ``("int",)``,
``("float",)``, ``("enum", NAME, (MEMBER, ...))``, ``("range", LO, HI)``,
``("array", ELEMENT, N)``, ``("record", NAME, ((FIELD, DESCRIPTOR), ...))``.

Failures raise :class:`OperationError` with the code (E802 an operation failed, E803 Python
code returned a value that does not fit its declared type) and ``where``: the place in the
specification, as the code that called the function passed it (a ``file:line:column`` string
in generated nodes, a source span in the interpreter).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping, Sequence
from types import ModuleType
from typing import TYPE_CHECKING, Any


class _Numpy(ModuleType):
    """numpy, imported at its first use: checking a specification that has no ``float[N]``
    value never needs it, and importing it is a third of `rssmc check`'s start-up."""

    def __getattr__(self, name: str) -> Any:
        import numpy

        globals()["np"] = numpy
        globals()["_F64"] = numpy.dtype(numpy.float64)
        return getattr(numpy, name)


if TYPE_CHECKING:
    import numpy as np
    _F64: np.dtype[np.float64]
else:
    np = _Numpy("numpy")
    _F64 = None                    # numpy's float64 dtype, set with np at numpy's first use

Desc = tuple[Any, ...]
Convert = Callable[[Any], Any]

BOOL: Desc = ("bool",)
INT: Desc = ("int",)
FLOAT: Desc = ("float",)
INT_MIN = -(2**63)
INT_MAX = 2**63 - 1


class OperationError(Exception):
    """An operation of the specification failed at run time."""

    def __init__(self, code: str, message: str, where: Any) -> None:
        super().__init__(f"{where}: {message} [{code}]")
        self.code = code
        self.message = message
        self.where = where


class ValueTypeError(Exception):
    """A Python value that does not fit an RSSM type; ``path`` locates the offending part."""

    def __init__(self, expected: Desc, got: Any, path: str = "") -> None:
        where = f" at {path}" if path else ""
        super().__init__(f"{describe(got)}{where} where {type_text(expected)} is expected")
        self.expected = expected
        self.got = got
        self.path = path


def type_text(d: Desc) -> str:
    """The type of a descriptor as the specification writes it (``float[3]``, ``Pose``)."""
    if d[0] == "array":
        return f"{type_text(d[1])}[{d[2]}]"
    if d[0] in ("record", "enum"):
        return str(d[1])
    if d[0] == "range":
        return f"{d[1]}..{d[2]}"
    return str(d[0])


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
        return "a mapping with keys {" + ", ".join(str(k) for k in list(v)[:6]) + "}"
    return "None" if v is None else f"{type(v).__name__} {repr(v)[:40]}"


# ---------------------------------------------------------------- construction


def freeze(a: Any) -> Any:
    """``a``, made read-only (in place)."""
    # setflags(write=False) is what `a.flags.writeable = False` does at half the cost; the
    # argument by position (`write` is the first) spares the parsing of a keyword
    a.setflags(False)
    return a


def float_array(items: Any, size: int | None = None) -> Any:
    """A fresh read-only float64 array of ``items`` (of shape ``(size,)`` when given)."""
    a = np.array(items, dtype=np.float64)
    if size is not None and a.shape != (size,):
        raise ValueError(f"shape {a.shape}, expected ({size},)")
    return freeze(a)


def joined(parts: Sequence[Any]) -> Any:
    """A fresh read-only float64 array of the float64 arrays ``parts`` end to end (each
    C-contiguous: their bytes are read as they are), such as a device's measurement whose
    slices are the fields of a record. The parts' bytes joined into one immutable ``bytes``
    and viewed as float64: read-only from the start, for less than half of what
    ``np.concatenate`` and :func:`freeze` cost on a few short arrays."""
    return np.frombuffer(b"".join(parts))


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
    if kind == "enum":
        return d[2][0]                   # the first member
    if kind == "range":
        return min(max(0, d[1]), d[2])   # 0, or the bound nearest to it
    if kind == "array":
        if d[1] == FLOAT:
            return freeze(np.zeros(d[2], dtype=np.float64))
        return tuple(default(d[1]) for _ in range(d[2]))
    return {name: default(fd) for name, fd in d[2]}


# ---------------------------------------------------------------- conversion at the boundary


def converter(d: Desc) -> Convert:
    """Check a value coming from Python code (an external operation, a device, a parameter)
    and convert it to the representation above (ints are accepted for floats; lists, tuples
    and arrays for arrays; mappings or objects with the right attributes for records);
    raises :class:`ValueTypeError` naming the offending part."""
    kind = d[0]
    if kind == "float":
        return _to_float
    if kind == "int":
        return _to_int
    if kind == "bool":
        return _to_bool
    if kind == "enum":
        return _enum(d)
    if kind == "range":
        return _range(d)
    if kind == "array":
        return _float_array(d) if d[1] == FLOAT else _array(d)
    return _record(d)


def _enum(d: Desc) -> Convert:
    members = frozenset(d[2])

    def to_member(v: Any) -> str:
        if type(v) is not str or v not in members:
            raise ValueTypeError(d, v, f"(members: {', '.join(d[2])})")
        return v
    return to_member


def _range(d: Desc) -> Convert:
    lo, hi = d[1], d[2]

    def to_bounded(v: Any) -> int:
        if isinstance(v, bool | np.bool_) or not isinstance(v, int | np.integer):
            raise ValueTypeError(d, v)
        i = int(v)
        if not lo <= i <= hi:
            raise ValueTypeError(d, v, f"(outside {lo}..{hi})")
        return i
    return to_bounded


def _to_float(v: Any) -> float:
    if type(v) is float:
        return v
    if isinstance(v, bool | np.bool_) or not isinstance(v, int | float | np.integer | np.floating):
        raise ValueTypeError(FLOAT, v)
    return float(v)


def _to_int(v: Any) -> int:
    if isinstance(v, bool | np.bool_) or not isinstance(v, int | np.integer):
        raise ValueTypeError(INT, v)
    i = int(v)
    if not INT_MIN <= i <= INT_MAX:
        raise ValueTypeError(INT, v, "(outside the 64-bit range of int)")
    return i


def _to_bool(v: Any) -> bool:
    if not isinstance(v, bool | np.bool_):
        raise ValueTypeError(BOOL, v)
    return bool(v)


def _float_array(d: Desc) -> Convert:
    size = d[2]
    shape = (size,)
    ndarray, f64 = np.ndarray, np.dtype(np.float64)

    def to_array(v: Any) -> Any:
        # the common case first: a value of this type already (a read-only float64 array of
        # the right shape), returned as it is, as the general checks below would
        if type(v) is ndarray and v.dtype is f64 and v.shape == shape and not v.flags.writeable:
            return v
        if isinstance(v, np.ndarray):
            if v.shape != shape or v.dtype.kind not in "fiu":
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

    def checked(v: Any) -> dict[str, Any]:
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
    return _to_dict(d, fields, checked)


def _to_dict(d: Desc, fields: list[tuple[str, Convert]], checked: Convert) -> Convert:
    """The converter of record ``d``. Its common case, a dict with the declared fields, each
    converted in order (``fields``: name and converter), a ``float[N]`` field that is a value of
    that type already taken as it is without calling its converter, is compiled for the record:
    one expression with the fields unrolled, as a loop over them costs about twice as many
    steps of the interpreter. Anything else (or a field that does not convert) goes to
    ``checked``, which says what is wrong. Field names appear only in string literals written
    by ``repr``."""
    namespace: dict[str, Any] = {"ndarray": np.ndarray, "f64": np.dtype(np.float64),
                                 "ValueTypeError": ValueTypeError, "checked": checked}
    items: list[str] = []
    for k, ((name, conv), (_, fd)) in enumerate(zip(fields, d[2], strict=True)):
        namespace[f"convert{k}"] = conv
        key = repr(name)
        if is_float_array(fd):
            items.append(f"{key}: x if (type(x := v[{key}]) is ndarray and x.dtype is f64 "
                         f"and x.shape == ({int(fd[2])},) and not x.flags.writeable) "
                         f"else convert{k}(x)")
        else:
            items.append(f"{key}: convert{k}(v[{key}])")
    source = "\n".join([
        "def to_dict(v):",
        f"    if type(v) is dict and len(v) == {len(fields)}:",
        "        try:",
        "            return {" + ", ".join(items) + "}",
        "        except (KeyError, ValueTypeError):",
        "            pass",
        "    return checked(v)", ""])
    exec(compile(source, f"<record {d[1]}>", "exec"), namespace)
    to_dict: Convert = namespace["to_dict"]
    return to_dict


class MeasurementError(Exception):
    """What a device measured does not fit its outputs (E803); ``message`` says what, to be
    put after "device ID " by the caller."""

    def __init__(self, message: str, wrong_type: bool) -> None:
        super().__init__(message)
        self.message = message
        self.wrong_type = wrong_type      # a value of the wrong type (else: not an output)


def measured_values(convert: Mapping[str, Convert], measured: Mapping[str, Any]
                    ) -> dict[str, Any]:
    """The values to store of what a device measured (``measured``, output name -> value, a
    subset of the outputs), each checked and converted by its output's converter
    (``convert``); raises :class:`MeasurementError` at the first name that is not an output
    or value that does not fit. The interpreter and the ROS 2 device node both check a
    device's measurements here."""
    out: dict[str, Any] = {}
    for name, value in measured.items():
        conv = convert.get(name)
        if conv is None:
            raise MeasurementError(f"measured '{name}', which is not one of its output buffers "
                                   f"({', '.join(convert) or 'none'})", False)
        try:
            out[name] = conv(value)
        except ValueTypeError as e:
            raise MeasurementError(f"measured {e} for output '{name}'", True) from None
    return out


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
    """A one-line text of a value for summaries."""
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


# ---------------------------------------------------------------- operations


def _fail(where: Any, message: str) -> OperationError:
    return OperationError("E802", message, where)


def int64(x: int, where: Any) -> int:
    """``x`` when it is a 64-bit int; an overflow otherwise."""
    if INT_MIN <= x <= INT_MAX:
        return x
    raise _fail(where, f"integer overflow: {x} is outside the 64-bit range of int")


def iadd(x: int, y: int, where: Any) -> int:
    r = x + y
    return r if INT_MIN <= r <= INT_MAX else int64(r, where)


def isub(x: int, y: int, where: Any) -> int:
    r = x - y
    return r if INT_MIN <= r <= INT_MAX else int64(r, where)


def imul(x: int, y: int, where: Any) -> int:
    r = x * y
    return r if INT_MIN <= r <= INT_MAX else int64(r, where)


def ineg(x: int, where: Any) -> int:
    return -x if x != INT_MIN else int64(-x, where)


def iabs(x: int, where: Any) -> int:
    return abs(x) if x != INT_MIN else int64(-x, where)


def div(x: Any, y: Any, where: Any) -> float:
    """``x / y``: always float division."""
    if y == 0:
        raise _fail(where, "division by zero")
    try:
        return float(x / y)
    except OverflowError as e:
        raise _fail(where, f"division: {e}") from None


def mod(x: Any, y: Any, where: Any) -> Any:
    """``x % y`` with the sign of the divisor (ints stay ints)."""
    if y == 0:
        raise _fail(where, "remainder by zero")
    return x % y


def fmin(x: float, y: float) -> float:
    """The smaller float; NaN when either is NaN."""
    if x != x or y != y:
        return math.nan
    return x if x <= y else y


def fmax(x: float, y: float) -> float:
    """The larger float; NaN when either is NaN."""
    if x != x or y != y:
        return math.nan
    return x if x >= y else y


def fclamp(x: float, lo: float, hi: float) -> float:
    """``min(max(x, lo), hi)`` for floats, NaN when any is NaN."""
    return fmin(fmax(x, lo), hi)


def in_range(x: int, lo: int, hi: int, what: str | None, where: Any) -> int:
    """``x`` stored into the range ``lo..hi`` (of ``what``, for the message)."""
    if lo <= x <= hi:
        return x
    of = f" of {what}" if what else ""
    raise _fail(where, f"value {x} is outside {lo}..{hi}{of}")


def check_ranges(v: Any, d: Desc, what: str | None, where: Any, path: str = "") -> Any:
    """``v`` stored where a value of descriptor ``d`` is expected, every range in it checked
    (an array of ints stored into an array of ranges)."""
    kind = d[0]
    if kind == "range":
        return in_range(v, d[1], d[2], f"{what or ''}{path}" or None, where)
    if kind == "array" and d[1] != FLOAT:
        for k, x in enumerate(v):
            check_ranges(x, d[1], what, where, f"{path}[{k}]")
    elif kind == "record":
        for name, fd in d[2]:
            check_ranges(v[name], fd, what, where, f"{path}.{name}")
    return v


def index(a: Any, i: int, size: int, floats: bool, where: Any) -> Any:
    if 0 <= i < size:
        return a.item(i) if floats else a[i]
    raise _fail(where, f"index {i} is out of range (indices run from 0 to {size - 1})")


def set_item(container: Any, i: int, size: int, item: Any, where: Any) -> Any:
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
    """``container`` with field ``name`` replaced (a new record)."""
    new = dict(container)
    new[name] = value
    return new


def as_np(x: Any) -> Any:
    """An int array operand (a tuple) as a float64 array for arithmetic."""
    return np.array(x, dtype=np.float64)


def as_float64(x: Any) -> Any:
    """``x`` as a float64 array, as ``np.asarray(x, dtype=np.float64)`` gives it: ``x`` itself
    when it is one already (a ``float[N]`` value), without the cost of that call."""
    if type(x) is np.ndarray and x.dtype is _F64:    # np first: it sets _F64
        return x
    return np.asarray(x, dtype=np.float64)


# The arithmetic of float arrays, run at every iteration of a controller: the fresh result is
# made read-only in place (what freeze does, without the cost of calling it).


def aadd(x: Any, y: Any) -> Any:
    r = np.add(x, y)
    r.setflags(False)
    return r


def asub(x: Any, y: Any) -> Any:
    r = np.subtract(x, y)
    r.setflags(False)
    return r


def amul(x: Any, y: Any) -> Any:
    r = np.multiply(x, y)
    r.setflags(False)
    return r


def adiv(x: Any, y: Any, y_array: bool, where: Any) -> Any:
    if (not np.all(y)) if y_array else y == 0:
        raise _fail(where, "division by zero")
    return freeze(np.divide(x, y))


def aneg(x: Any) -> Any:
    r = np.negative(x)
    r.setflags(False)
    return r


def math1(fn: Callable[[float], float], name: str, x: float, where: Any) -> float:
    """A math function of one float; a domain or range error fails."""
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


def dot(x: Any, y: Any, where: Any) -> float:
    if len(x) != len(y):
        raise _fail(where, f"dot() of arrays of sizes {len(x)} and {len(y)}")
    return float(np.dot(x, y))


def cross(x: Any, y: Any) -> Any:
    return freeze(np.cross(x, y))


def call(fn: Callable[..., Any] | None, conv: Convert, name: str, where: Any,
         *args: Any) -> Any:
    """Call an external operation and check what it returns against its declared type
    (``fn`` is None when no Python function could be bound to it: E801)."""
    if fn is None:
        raise OperationError("E801", f"extern {name} has no binding", where)
    try:
        r = fn(*args)
    except (Exception, SystemExit) as e:    # sys.exit() in user code fails the operation
        raise OperationError("E802", f"{name}() raised {type(e).__name__}: {e}", where) from e
    try:
        return conv(r)
    except ValueTypeError as e:
        raise OperationError("E803", f"{name}() returned {e}", where) from None
