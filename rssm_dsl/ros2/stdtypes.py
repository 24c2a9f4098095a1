"""Standard ROS 2 interfaces on the data topics (docs/ros2.md, "Data topics").

A channel's data topic carries its value as a plain message that any ROS node can subscribe
to: a standard one where the buffer's type has a standard counterpart, else the generated
record message or ``<Type>Sample`` of the ``<system>_interfaces`` package.

| RSSM type of the buffer                        | data topic by default                |
|------------------------------------------------|--------------------------------------|
| ``float`` / ``int``, ranges / ``bool``         | ``std_msgs/msg/Float64`` / ``Int64`` / ``Bool`` |
| ``float[3]``                                   | ``geometry_msgs/msg/Vector3``        |
| record ``{linear: float[3], angular: float[3]}`` | ``geometry_msgs/msg/TwistStamped`` |
| record ``{force: float[3], torque: float[3]}`` | ``geometry_msgs/msg/WrenchStamped``  |
| record ``{position: float[3], orientation: float[4]}`` (x, y, z, w) | ``geometry_msgs/msg/PoseStamped`` |
| anything else                                  | generated message                    |

The ROS type of a buffer can be named explicitly in ``<spec>.ros2.toml`` next to the
specification (:func:`load_mapping`) among :data:`KNOWN`, e.g. ``geometry_msgs/msg/Point``
for a ``float[3]`` position or ``sensor_msgs/msg/JointState`` for a joint vector; a type
that cannot carry the buffer's values exactly is E862, a file that names no buffer of the
system E863.
"""

from __future__ import annotations

import re
import tomllib
from collections.abc import Callable
from pathlib import Path

from rssm_core.records import dataclass
from rssm_dsl.diagnostics import Diagnostic
from rssm_dsl.pycode import tuple_source
from rssm_dsl.semantics.loader import display_path
from rssm_dsl.semantics.model import Buffer, System
from rssm_dsl.semantics.types import BOOL, FLOAT, INT, ArrayT, RangeT, RecordT, Type
from rssm_dsl.source import Span, split_lines

PACKAGES = ("std_msgs", "geometry_msgs", "sensor_msgs")
MAPPING_SUFFIX = ".ros2.toml"
_NAME = re.compile(r"([a-z][a-z0-9_]*)/(?:msg/)?([A-Z][A-Za-z0-9]*)\Z")

# std_msgs integers: (name, lo, hi) — a range fits when its bounds do
INTEGERS = (("Int8", -2**7, 2**7 - 1), ("Int16", -2**15, 2**15 - 1),
            ("Int32", -2**31, 2**31 - 1), ("Int64", -2**63, 2**63 - 1),
            ("UInt8", 0, 2**8 - 1), ("UInt16", 0, 2**16 - 1), ("UInt32", 0, 2**32 - 1),
            ("UInt64", 0, 2**64 - 1))
# geometry_msgs records: name -> (field of the stamped variant, {field: (kind, message)})
SHAPES: dict[str, tuple[str, dict[str, tuple[str, str]]]] = {
    "Twist": ("twist", {"linear": ("xyz", "Vector3"), "angular": ("xyz", "Vector3")}),
    "Accel": ("accel", {"linear": ("xyz", "Vector3"), "angular": ("xyz", "Vector3")}),
    "Wrench": ("wrench", {"force": ("xyz", "Vector3"), "torque": ("xyz", "Vector3")}),
    "Pose": ("pose", {"position": ("xyz", "Point"), "orientation": ("xyzw", "Quaternion")}),
}
# geometry_msgs vectors: name -> (kind, field of the stamped variant)
VECTORS = {"Vector3": ("xyz", "vector"), "Point": ("xyz", "point"),
           "Quaternion": ("xyzw", "quaternion")}
JOINT_FIELDS = ("position", "velocity", "effort")

KNOWN: tuple[str, ...] = (
    "std_msgs/msg/Bool", "std_msgs/msg/Float64", "std_msgs/msg/Float64MultiArray",
    *(f"std_msgs/msg/{n}" for n, _, _ in INTEGERS),
    *(f"geometry_msgs/msg/{n}{s}" for n in (*VECTORS, *SHAPES) for s in ("", "Stamped")),
    "sensor_msgs/msg/JointState",
)


@dataclass(frozen=True)
class RosType:
    """A standard message type and the message descriptor (runtime/messages.py) of a buffer
    carried by it, as Python source: the node imports ``from PKG import msg as _PKG``."""

    package: str
    name: str
    desc: str

    @property
    def full(self) -> str:
        return f"{self.package}/msg/{self.name}"

    @property
    def alias(self) -> str:
        return f"_{self.package}"

    @property
    def cls(self) -> str:
        return f"{self.alias}.{self.name}"

    @property
    def stamped(self) -> bool:
        return self.desc.startswith(("('stamped'", "('joints'"))


def normal_name(text: str) -> str | None:
    """``pkg/msg/Type`` (or ``pkg/Type``) in its full form, None when it is not one."""
    m = _NAME.match(text.strip())
    return f"{m.group(1)}/msg/{m.group(2)}" if m else None


def _float_vector(t: Type, size: int | None = None) -> bool:
    return isinstance(t, ArrayT) and t.element == FLOAT and (size is None or t.size == size)


def _shape_of(t: Type) -> str | None:
    """The geometry_msgs record whose fields a record has (by name and type), if any."""
    if not isinstance(t, RecordT):
        return None
    fields = dict(t.fields)
    for name, (_, shape) in SHAPES.items():
        if set(fields) == set(shape) and all(
                _float_vector(fields[f], 3 if kind == "xyz" else 4)
                for f, (kind, _) in shape.items()):
            return name
    return None


def default_name(t: Type) -> str | None:
    """The standard type a buffer of type ``t`` is carried by when none is named."""
    if t == FLOAT:
        return "std_msgs/msg/Float64"
    if t == INT or isinstance(t, RangeT):
        return "std_msgs/msg/Int64"
    if t == BOOL:
        return "std_msgs/msg/Bool"
    if _float_vector(t, 3):
        return "geometry_msgs/msg/Vector3"
    shape = _shape_of(t)
    return f"geometry_msgs/msg/{shape}Stamped" if shape is not None else None


def _g(name: str) -> str:
    return f"_geometry_msgs.{name}"


def _record_desc(shape: str, t: RecordT) -> str:
    fields = SHAPES[shape][1]
    items = tuple_source([f"({f!r}, ({fields[f][0]!r}, {_g(fields[f][1])}))"
                          for f, _ in t.fields])
    return f"('record', {_g(shape)}, {items})"


def resolve(name: str, t: Type, value_desc: Callable[[Type], str]) -> RosType | str:
    """The standard type ``name`` carrying buffers of type ``t``, or why it cannot (a
    sentence). ``value_desc`` gives the value descriptor source of a type."""
    full = normal_name(name)
    if full is None or full not in KNOWN:
        return (f"'{name}' is not one of the standard types rssmc maps: "
                + ", ".join(KNOWN))
    package, _, short = full.split("/")
    if package == "std_msgs":
        return _std_msgs(short, t, value_desc)
    if package == "sensor_msgs":
        return _joint_state(short, t)
    return _geometry(short, t)


def _std_msgs(short: str, t: Type, value_desc: Callable[[Type], str]) -> RosType | str:
    if short == "Float64MultiArray":
        if isinstance(t, ArrayT) and t.element == FLOAT:
            return RosType("std_msgs", short, f"('multiarray', _std_msgs.{short}, {t.size})")
        ok, need = False, "a float[N] (joint vectors and other float arrays)"
    elif short == "Bool":
        ok, need = t == BOOL, "a bool"
    elif short == "Float64":
        ok, need = t == FLOAT, "a float"
    elif short == "Int64":
        ok, need = t == INT or isinstance(t, RangeT), "an int or a range"
    else:
        lo, hi = next((lo, hi) for n, lo, hi in INTEGERS if n == short)
        ok = isinstance(t, RangeT) and lo <= t.lo and t.hi <= hi
        need = f"a range within {lo}..{hi}"
    if not ok:
        return f"std_msgs/msg/{short} carries {need}"
    return RosType("std_msgs", short, f"('msg', _std_msgs.{short}, 'data', {value_desc(t)})")


def _joint_state(short: str, t: Type) -> RosType | str:
    if isinstance(t, ArrayT) and t.element == FLOAT:
        return RosType("sensor_msgs", short, f"('joints', _sensor_msgs.{short}, {t.size}, "
                                             "(('', 'position'),))")
    if isinstance(t, RecordT) and t.fields and {f for f, _ in t.fields} <= set(JOINT_FIELDS):
        sizes = {ft.size if isinstance(ft, ArrayT) and ft.element == FLOAT else -1
                 for _, ft in t.fields}
        if len(sizes) == 1 and -1 not in sizes:
            pairs = tuple_source([f"({f!r}, {f!r})" for f, _ in t.fields])
            return RosType("sensor_msgs", short,
                           f"('joints', _sensor_msgs.{short}, {sizes.pop()}, {pairs})")
    return (f"sensor_msgs/msg/{short} carries a float[N] (the positions) or a record whose "
            "fields are some of position, velocity, effort, all float[N] of one N")


def _geometry(short: str, t: Type) -> RosType | str:
    what = f"geometry_msgs/msg/{short} carries "
    base = short.removesuffix("Stamped")
    if base in VECTORS:
        kind, field = VECTORS[base]
        size = 3 if kind == "xyz" else 4
        if not _float_vector(t, size):
            return what + f"a float[{size}]" + (" (x, y, z, w)" if size == 4 else " (x, y, z)")
        inner = f"({kind!r}, {_g(base)})"
    else:
        field, shape = SHAPES[base]
        found = _shape_of(t)
        if not isinstance(t, RecordT) or found not in (base, "Twist" if base == "Accel"
                                                       else base):
            fields = ", ".join(f"{f}: float[{3 if k == 'xyz' else 4}]"
                               for f, (k, _) in shape.items())
            return what + f"a record {{{fields}}}"
        inner = _record_desc(base, t)
    if short != base:
        return RosType("geometry_msgs", short, f"('stamped', {_g(short)}, {field!r}, {inner})")
    return RosType("geometry_msgs", short, inner)


# ---------------------------------------------------------------- the mapping file


def mapping_path(spec: Path) -> Path:
    """``<folder>/<stem>.ros2.toml`` of a specification ``<folder>/<stem>.rssm``."""
    return spec.with_name(spec.stem + MAPPING_SUFFIX)


def _span(path: Path, text: str, needle: str | None) -> Span:
    line = 1
    if needle:
        for k, content in enumerate(split_lines(text), start=1):
            if needle in content:
                line = k
                break
    return Span(display_path(path), line, 1, line, 1)


def load_mapping(spec: Path, system: System
                 ) -> tuple[dict[str, tuple[str, Buffer]], list[Diagnostic]]:
    """The explicit ROS types of ``spec``'s mapping file, by channel id: (type name, the
    buffer it was named for), and the E863 diagnostics of the file. No file: no mapping.

        # lwr4_circle.ros2.toml
        [types]
        "a1.c.cmd" = "geometry_msgs/msg/PointStamped"     # either end of the channel
    """
    path = mapping_path(spec)
    if not path.is_file():
        return {}, []
    text = path.read_text(encoding="utf-8", errors="replace")
    problems: list[Diagnostic] = []

    def bad(message: str, needle: str | None, hint: str) -> None:
        problems.append(Diagnostic("E863", message, _span(path, text, needle), hint))

    try:
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError as e:
        bad(f"{path.name} is not valid TOML: {e}", None, "see docs/ros2.md, \"Data topics\"")
        return {}, problems
    extra = sorted(set(data) - {"types"})
    if extra:
        bad(f"{path.name} has table(s) {', '.join(extra)}; only [types] is read", extra[0],
            "write [types] and BUFFER = \"pkg/msg/Type\" lines")
    types = data.get("types", {})
    if not isinstance(types, dict):
        bad(f"'types' of {path.name} must be a table", "types", "write a [types] table")
        return {}, problems
    buffers: dict[str, Buffer] = {}
    for sub in system.subsystems():
        buffers.update((b.qualified, b) for b in (*sub.inputs, *sub.outputs))
    for dev in system.devices():
        buffers.update((b.qualified, b) for b in (*dev.inputs, *dev.outputs))
    out: dict[str, tuple[str, Buffer]] = {}
    for key, value in types.items():
        buf = buffers.get(key)
        if not isinstance(value, str):
            bad(f"the ROS type of '{key}' in {path.name} must be a string", key,
                "write \"pkg/msg/Type\"")
            continue
        if buf is None:
            bad(f"{path.name} names '{key}', which is no buffer of system {system.name}", key,
                "name a buffer as AGENT.SUBSYSTEM.BUFFER, e.g. a1.c.cmd or a1.e.arm.cmd")
            continue
        ch = system.channel_of(buf)
        if ch is None:
            bad(f"buffer {key} in {path.name} is connected to no channel: it has no topic",
                key, "remove the line")
            continue
        if ch.id in out and normal_name(out[ch.id][0]) != normal_name(value):
            bad(f"both ends of channel {ch.id} are named in {path.name}, with different "
                f"types ('{out[ch.id][0]}', '{value}')", key, "name one type per channel")
            continue
        out[ch.id] = (value, buf)
    return out, problems


def explicit_diagnostic(name: str, buf: Buffer, reason: str, mapping: Path) -> Diagnostic:
    return Diagnostic("E862", f"buffer {buf.qualified} ({buf.type}) cannot be carried by ROS "
                      f"type '{name}' named in {mapping.name}: {reason}", buf.span,
                      "name a type that fits (docs/ros2.md, \"Data topics\"), or remove the "
                      "line to get the default")
