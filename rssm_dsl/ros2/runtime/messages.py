"""Values to ROS messages and back.

A *message descriptor* is the value descriptor of :mod:`.values` with the message classes of
the workspace's interfaces package filled in by the generator:

* ``("bool",)``, ``("int",)``, ``("float",)``: ``bool``, ``int64``, ``float64`` fields;
* ``("range", LO, HI)``: an ``int64`` field;
* ``("enum", NAME, MEMBERS)``: a ``uint8`` field holding the member's position in MEMBERS
  (the message declares the positions as constants); the value is the member's name;
* ``("array", ELEMENT, N, WRAPPER)``: a fixed-size array field ``T[N]``; WRAPPER is ``None``
  unless the element is itself an array, which ROS messages cannot nest: then each element
  is a WRAPPER message holding the inner array in its field ``items``;
* ``("record", CLASS, ((FIELD, DESCRIPTOR), ...))``: a message of the record's type.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import numpy as np

from rssm_core.values import Desc, float_array

ToMsg = Callable[[Any], Any]
FromMsg = Callable[[Any], Any]


def to_msg(d: Desc) -> ToMsg:
    """The function turning a value into what a message field of descriptor ``d`` holds."""
    kind = d[0]
    if kind == "bool":
        return bool
    if kind in ("int", "range"):
        return int
    if kind == "float":
        return float
    if kind == "enum":
        return _member_number(d)
    if kind == "array":
        elem, wrapper = d[1], d[3]
        if elem[0] == "float":
            return lambda v: np.asarray(v, dtype=np.float64)
        if elem[0] in ("int", "range"):
            return lambda v: np.asarray(v, dtype=np.int64)
        if elem[0] == "enum":
            number = _member_number(elem)
            return lambda v: np.asarray([number(x) for x in v], dtype=np.uint8)
        if elem[0] == "bool":
            return list
        inner = to_msg(elem)
        if wrapper is not None:
            return lambda v: [wrapper(items=inner(x)) for x in v]
        return lambda v: [inner(x) for x in v]
    cls, fields = d[1], tuple((name, to_msg(fd)) for name, fd in d[2])

    def record(v: Any) -> Any:
        return cls(**{name: conv(v[name]) for name, conv in fields})
    return record


def from_msg(d: Desc) -> FromMsg:
    """The function turning a message field of descriptor ``d`` into a value."""
    kind = d[0]
    if kind == "bool":
        return bool
    if kind in ("int", "range"):
        return int
    if kind == "float":
        return float
    if kind == "enum":
        return _member_name(d)
    if kind == "array":
        elem, wrapper = d[1], d[3]
        if elem[0] == "float":
            return float_array
        inner = from_msg(elem)
        if wrapper is not None:
            return lambda m: tuple(inner(x.items) for x in m)
        return lambda m: tuple(inner(x) for x in m)
    fields = tuple((name, from_msg(fd)) for name, fd in d[2])
    return lambda m: {name: conv(getattr(m, name)) for name, conv in fields}


def _member_number(d: Desc) -> Callable[[str], int]:
    """An enum member's name -> its number on the wire (its position among the members)."""
    numbers = {m: k for k, m in enumerate(d[2])}
    return numbers.__getitem__


def _member_name(d: Desc) -> Callable[[Any], str]:
    """An enum field's number -> the member's name; a number that names no member fails."""
    members: tuple[str, ...] = tuple(d[2])

    def name(n: Any) -> str:
        k = int(n)
        if not 0 <= k < len(members):
            raise ValueError(f"{k} is not a member of enum {d[1]} (0..{len(members) - 1})")
        return members[k]
    return name
