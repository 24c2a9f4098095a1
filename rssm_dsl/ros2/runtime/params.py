"""ROS parameters of the generated nodes.

Every `param` of the specification is a ROS parameter of its node, with the specification's
value as default (the generated ``config/params.yaml`` repeats it). A scalar or an array of
scalars is one parameter; a record is one parameter per field (``NAME.FIELD``, nested as
needed); arrays of records and arrays of arrays are not exposed (the specification's value
is used). Values are checked against the declared type (an int is accepted for a float; a
range takes an int inside it; an enum is a string parameter, the member's name).

The runtime's own parameters live under ``rssm.``, which no name of a specification can
take: ``rssm.rate_hz`` (the iteration frequency; the specification's by default, 0 = as
fast as communication allows), ``rssm.diagnostics_period`` (seconds between two status
messages; behaviour switches are always published), ``rssm.resend_period`` (seconds before a
blocking send publishes its sample again), ``rssm.linger`` (seconds a node stays after its
subsystem ended, so that late subscribers still get its last status) and ``rssm.trace_file``
(JSON lines of every iteration; empty: none, unless ``$RSSM_TRACE_DIR`` is set).
"""

from __future__ import annotations

import array
from typing import Any

from rcl_interfaces.msg import ParameterDescriptor
from rclpy.node import Node

from rssm_core.records import dataclass
from rssm_core.values import ValueTypeError, converter, type_text


class SetupError(Exception):
    """The node cannot start; the message says why."""


@dataclass(frozen=True)
class ParamSpec:
    name: str
    desc: tuple[Any, ...]      # value descriptor
    default: Any               # the specification's value, as JSON-like data


@dataclass(frozen=True)
class RuntimeParams:
    rate_hz: float
    diagnostics_period: float
    resend_period: float
    linger: float
    trace_file: str


def declare(node: Node, name: str, default: Any) -> Any:
    descriptor = ParameterDescriptor(dynamic_typing=True)
    value = node.declare_parameter(name, default, descriptor).value
    return list(value) if isinstance(value, array.array) else value


def runtime_params(node: Node, frequency: float | None) -> RuntimeParams:
    rate = declare(node, "rssm.rate_hz", float(frequency or 0.0))
    diag = declare(node, "rssm.diagnostics_period", 0.1)
    resend = declare(node, "rssm.resend_period", 1.0)
    linger = declare(node, "rssm.linger", 1.0)
    trace = declare(node, "rssm.trace_file", "")
    for name, v in (("rssm.rate_hz", rate), ("rssm.diagnostics_period", diag),
                    ("rssm.resend_period", resend), ("rssm.linger", linger)):
        if isinstance(v, bool) or not isinstance(v, int | float) or v < 0:
            raise SetupError(f"parameter {name} must be a number >= 0, not {v!r}")
    if not isinstance(trace, str):
        raise SetupError(f"parameter rssm.trace_file must be a string, not {trace!r}")
    return RuntimeParams(float(rate), float(diag), float(resend) or 1.0, float(linger), trace)


Leaf = tuple[str, tuple[str, ...], Any]
_LEAF_KINDS = ("bool", "int", "float", "enum", "range")


def leaves(name: str, desc: tuple[Any, ...], default: Any) -> list[Leaf]:
    """The ROS parameters of one specification parameter: (ROS name, field path, default)."""
    kind = desc[0]
    if kind in _LEAF_KINDS:
        return [(name, (), default)]
    if kind == "array":
        return [(name, (), default)] if desc[1][0] in _LEAF_KINDS else []
    out: list[Leaf] = []
    for field, fd in desc[2]:
        for ros, path, value in leaves(f"{name}.{field}", fd, default[field]):
            out.append((ros, (field, *path), value))
    return out


def _replace(value: Any, path: tuple[str, ...], leaf: Any) -> Any:
    if not path:
        return leaf
    new = dict(value)
    new[path[0]] = _replace(value[path[0]], path[1:], leaf)
    return new


def read_params(node: Node, params: tuple[ParamSpec, ...]) -> dict[str, Any]:
    """Declare the specification's parameters and return their checked values by name."""
    values: dict[str, Any] = {}
    for p in params:
        value = p.default
        for ros, path, default in leaves(p.name, p.desc, p.default):
            value = _replace(value, path, declare(node, ros, default))
        try:
            values[p.name] = converter(p.desc)(value)
        except ValueTypeError as e:
            raise SetupError(f"parameter {p.name} ({type_text(p.desc)}): {e}") from None
    return values
