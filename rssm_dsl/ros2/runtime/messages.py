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
* ``("record", CLASS, ((FIELD, DESCRIPTOR), ...))``: a message of the record's type (the
  record's generated message, or a standard one whose fields have the record's field names:
  ``geometry_msgs/msg/Twist`` for a record ``{linear: float[3], angular: float[3]}``).

The message of a data topic (the whole message, not one field) has one of these descriptors,
or ``record`` above:

* ``("msg", CLASS, FIELD, DESCRIPTOR)``: a message with one field holding the value
  (``std_msgs/msg/Float64`` and its field ``data``; a generated ``<Type>Sample``, ``value``);
* ``("xyz", CLASS)``: a ``float[3]`` as a message with fields ``x``, ``y``, ``z``
  (``geometry_msgs/msg/Vector3``, ``Point``); ``("xyzw", CLASS)``: a ``float[4]`` as
  ``x``, ``y``, ``z``, ``w`` (``Quaternion``); both also as fields of a ``record``;
* ``("stamped", CLASS, FIELD, DESCRIPTOR)``: a message with a ``header`` (stamped by the
  producer when it publishes) and a field holding the value's message
  (``geometry_msgs/msg/TwistStamped``, field ``twist``);
* ``("joints", CLASS, N, ((VALUE_FIELD, FIELD), ...))``: ``sensor_msgs/msg/JointState``
  (stamped, joint names from the producer's parameters): a ``float[N]`` as its ``position``
  (VALUE_FIELD ``""``), or the ``float[N]`` fields of a record as the fields of the same
  names; a received message must carry exactly N values in each;
* ``("multiarray", CLASS, N)``: a ``float[N]`` as ``std_msgs/msg/Float64MultiArray``'s
  ``data`` (N values, the layout left empty).
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
    if kind in MESSAGE_KINDS:
        return _to_message(d)
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
    if kind in MESSAGE_KINDS:
        return _from_message(d)
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


MESSAGE_KINDS = frozenset(("msg", "xyz", "xyzw", "stamped", "joints", "multiarray"))
STAMPED_KINDS = frozenset(("stamped", "joints"))      # messages with a std_msgs/Header


def _to_message(d: Desc) -> ToMsg:
    kind, cls = d[0], d[1]
    if kind == "msg" or kind == "stamped":
        field, inner = d[2], to_msg(d[3])
        return lambda v: cls(**{field: inner(v)})
    if kind == "xyz":
        return lambda v: cls(x=float(v[0]), y=float(v[1]), z=float(v[2]))
    if kind == "xyzw":
        return lambda v: cls(x=float(v[0]), y=float(v[1]), z=float(v[2]), w=float(v[3]))
    if kind == "joints":
        pairs = tuple(d[3])
        return lambda v: cls(**{field: [float(x) for x in (v[name] if name else v)]
                                for name, field in pairs})
    assert kind == "multiarray"
    return lambda v: cls(data=[float(x) for x in v])


def _sized(items: Any, size: int, what: str) -> Any:
    if len(items) != size:
        raise ValueError(f"{what} holds {len(items)} values, the buffer takes {size}")
    return float_array(items)


def _from_message(d: Desc) -> FromMsg:
    kind = d[0]
    if kind == "msg" or kind == "stamped":
        field, inner = d[2], from_msg(d[3])
        return lambda m: inner(getattr(m, field))
    if kind == "xyz":
        return lambda m: float_array((m.x, m.y, m.z))
    if kind == "xyzw":
        return lambda m: float_array((m.x, m.y, m.z, m.w))
    size = d[2]
    if kind == "joints":
        pairs = tuple(d[3])
        if len(pairs) == 1 and not pairs[0][0]:
            field = pairs[0][1]
            return lambda m: _sized(getattr(m, field), size, f"JointState.{field}")
        return lambda m: {name: _sized(getattr(m, field), size, f"JointState.{field}")
                          for name, field in pairs}
    assert kind == "multiarray"
    return lambda m: _sized(m.data, size, "Float64MultiArray.data")


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
