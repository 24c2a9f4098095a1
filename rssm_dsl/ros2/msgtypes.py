"""ROS 2 message types for the system's data (the ``<system>_interfaces`` package).

| RSSM type        | message field type                 | generated data message of a channel |
|------------------|------------------------------------|------------------------------------|
| bool/int/float   | bool / int64 / float64             | (std_msgs: Bool, Int64, Float64)    |
| range lo..hi     | int64                              | (std_msgs/Int64)                    |
| enum E           | uint8, with a constant per member  | ESample                             |
| T[N], T scalar   | bool[N] / int64[N] / float64[N]    | Float64Array7Sample, ...            |
| record R         | message R (CamelCase of the name)  | R itself                            |
| R[N]             | R[N]                               | RArray4Sample                       |
| T[N][M]          | TArrayN[M] (see below)             | TArrayNArrayMSample                 |

An enum value travels as its member's position (from 0) in a ``uint8``; every message with
a field of enum type ``E`` (``Phase``) declares one constant per member, ``uint8
PHASE_IDLE=0`` (the enum's and the member's names in upper snake case), and the nodes
convert names to numbers and back at the boundary (runtime/messages.py). A range travels as
an ``int64`` (it is an int; the producer checked it when it was stored).

ROS 2 arrays do not nest: the inner array of T[N][M] is a wrapper message TArrayN with one
field ``items``.

A channel whose type has no standard counterpart (:mod:`rssm_dsl.ros2.stdtypes`) carries
its record's message, or a ``<Type>Sample`` with the one field ``value``; next to the data
topic, every producer publishes ``SampleInfo`` (``epoch``, ``seq``, ``digest``, ``stamp``), blocking
producers get ``Ack`` (``epoch``, ``seq``) back; every subsystem publishes
``SubsystemStatus`` on its diagnostics topic.
"""

from __future__ import annotations

import re

from rssm_core.records import dataclass
from rssm_dsl.pycode import tuple_source
from rssm_dsl.ros2.names import pascal
from rssm_dsl.semantics.types import INT, ArrayT, EnumT, RangeT, RecordT, Scalar, Type

SCALAR_FIELD = {"bool": "bool", "int": "int64", "float": "float64"}
SCALAR_NAME = {"bool": "Bool", "int": "Int64", "float": "Float64"}

ACK_FIELDS = (("uint32", "epoch", "the producer's epoch (a random number drawn at its start)"),
              ("uint64", "seq", "the sample taken"))
INFO_FIELDS = (
    ("uint32", "epoch", "the producer's epoch (a random number drawn at its start)"),
    ("uint64", "seq", "the producer's sample number, from 1"),
    ("uint64", "digest", "64 bits of BLAKE2b over the content of the data message it describes"),
    ("builtin_interfaces/Time", "stamp",
     "the tick of the producer's iteration that sent the sample, on its ROS clock (/clock "
     "with use_sim_time)"),
)
STATUS_FIELDS = (
    ("builtin_interfaces/Time", "stamp", ""),
    ("string", "subsystem", "the subsystem's id, e.g. a1.c"),
    ("string", "event", "enter | iteration | switch | end | error"),
    ("string", "behaviour", "the current behaviour (empty once the subsystem ended)"),
    ("string", "previous_behaviour", "the behaviour that just ended (switch, end)"),
    ("uint64", "iteration", "i, the discrete time stamp (iterations so far)"),
    ("uint64", "behaviour_iterations", "iterations since the current behaviour started"),
    ("uint64", "switches", "behaviour switches so far"),
    ("string[]", "behaviours", "every behaviour of the subsystem"),
    ("uint64[]", "behaviour_counts", "iterations of each, in total"),
    ("string[]", "inputs", "the input buffers"),
    ("bool[]", "new_data", "new(x) of each input in the last iteration"),
    ("string[]", "partial_functions", "targets of the partial transition functions"),
    ("uint16[]", "data_cases", "the data-availability case (varpi) each took"),
    ("string[]", "conditions", "terminal and error conditions of the behaviour"),
    ("bool[]", "condition_values", "their values at the end of the last iteration"),
    ("uint64", "overruns", "iterations that started two periods or more late"),
    ("uint64[]", "overwritten", "samples of each input that were never taken"),
    ("string", "message", "what went wrong (event error)"),
)


@dataclass(frozen=True)
class MsgField:
    type: str
    name: str
    comment: str = ""


@dataclass(frozen=True)
class MsgConstant:
    type: str
    name: str
    value: str


@dataclass(frozen=True)
class MsgView:
    name: str
    comment: str
    fields: tuple[MsgField, ...]
    constants: tuple[MsgConstant, ...] = ()


ENUM_FIELD = "uint8"
MAX_ENUM_MEMBERS = 256          # what a uint8 holds


def upper_snake(name: str) -> str:
    """``GripPhase`` -> ``GRIP_PHASE``, ``grasp_object`` -> ``GRASP_OBJECT``."""
    return re.sub(r"(?<=[a-z0-9])(?=[A-Z])", "_", name).upper()


def enum_constant(t: EnumT, member: str) -> str:
    """The message constant of an enum member: ``PHASE_IDLE``."""
    return f"{upper_snake(t.name)}_{upper_snake(member)}"


def enum_constants(t: EnumT) -> tuple[MsgConstant, ...]:
    return tuple(MsgConstant(ENUM_FIELD, enum_constant(t, m), str(k))
                 for k, m in enumerate(t.members))


def _wire(t: Type) -> Type:
    """The type a value travels as: a range as an int (arrays element-wise)."""
    if isinstance(t, RangeT):
        return INT
    if isinstance(t, ArrayT):
        return ArrayT(_wire(t.element), t.size)
    return t


def enums_in(t: Type) -> list[EnumT]:
    """The enum types of a message field holding a ``t`` (itself or its elements; the fields
    of a record are the record message's)."""
    while isinstance(t, ArrayT):
        t = t.element
    return [t] if isinstance(t, EnumT) else []


class MessageTypes:
    """Names and message descriptors of the system's types (see the module docstring)."""

    def __init__(self) -> None:
        self.records: dict[str, RecordT] = {}       # message name -> record
        self.wrappers: dict[str, ArrayT] = {}       # wrapper message name -> inner array
        self.samples: dict[str, Type] = {}          # sample message name -> value type

    # ------------------------------------------------------------------ names
    def type_name(self, t: Type) -> str:
        """CamelCase name of a type: Float64, LwrState, Float64Array7, ..."""
        t = _wire(t)
        if isinstance(t, Scalar):
            return SCALAR_NAME[t.name]
        if isinstance(t, EnumT):
            return pascal(t.name)
        if isinstance(t, RecordT):
            name = pascal(t.name)
            if name not in self.records:
                self.records[name] = t
                for _, ft in t.fields:
                    self.field_type(ft)
            return name
        assert isinstance(t, ArrayT)
        return f"{self.type_name(t.element)}Array{t.size}"

    def field_type(self, t: Type) -> str:
        """The type of a message field holding a value of type ``t``."""
        t = _wire(t)
        if isinstance(t, Scalar):
            return SCALAR_FIELD[t.name]
        if isinstance(t, EnumT):
            return ENUM_FIELD
        if isinstance(t, RecordT):
            return self.type_name(t)
        assert isinstance(t, ArrayT)
        return f"{self._element(t.element)}[{t.size}]"

    def _element(self, t: Type) -> str:
        if isinstance(t, ArrayT):
            name = self.type_name(t)
            if name not in self.wrappers:
                self.wrappers[name] = t
                self.field_type(t)
            return name
        return self.field_type(t)

    def sample(self, t: Type) -> str:
        t = _wire(t)
        name = self.type_name(t) + "Sample"
        if name not in self.samples:
            self.samples[name] = t
            self.field_type(t)
        return name

    def data_message(self, t: Type, msg: str = "_msg") -> tuple[str, str]:
        """The generated message of a data topic of type ``t`` (a record's own message, else
        ``<Type>Sample``) and its message descriptor, both as Python source."""
        if isinstance(t, RecordT):
            return f"{msg}.{self.type_name(t)}", self.descriptor(t, msg)
        name = self.sample(t)
        return f"{msg}.{name}", f"('msg', {msg}.{name}, 'value', {self.descriptor(t, msg)})"

    # ------------------------------------------------------------------ descriptors
    def descriptor(self, t: Type, msg: str = "_msg") -> str:
        """The message descriptor (rssm_dsl/ros2/runtime/messages.py) of ``t`` as Python
        source; ``msg`` is the name under which the node imported the messages."""
        if isinstance(t, Scalar):
            return f"({t.name!r},)"
        if isinstance(t, EnumT):
            return repr(("enum", t.name, t.members))
        if isinstance(t, RangeT):
            return repr(("range", t.lo, t.hi))
        if isinstance(t, ArrayT):
            wrapper = f"{msg}.{self.type_name(t.element)}" if isinstance(
                t.element, ArrayT) else "None"
            return f"('array', {self.descriptor(t.element, msg)}, {t.size}, {wrapper})"
        fields = tuple_source([f"({n!r}, {self.descriptor(ft, msg)})" for n, ft in t.fields])
        return f"('record', {msg}.{self.type_name(t)}, {fields})"

    # ------------------------------------------------------------------ .msg files
    def views(self) -> list[MsgView]:
        out: list[MsgView] = []
        for name, rec in self.records.items():
            out.append(MsgView(name, f"record {rec.name} of the specification",
                               tuple(MsgField(self.field_type(ft), n) for n, ft in rec.fields),
                               self._constants([ft for _, ft in rec.fields])))
        for name, arr in self.wrappers.items():
            out.append(MsgView(name, f"an array {arr} as an element of an array (ROS 2 arrays "
                               "do not nest)", (MsgField(self.field_type(arr), "items"),),
                               self._constants([arr])))
        for name, t in self.samples.items():
            out.append(MsgView(name, f"the value of a channel of type {t} (its epoch and "
                               "sequence number travel in SampleInfo on <topic>/info)",
                               (MsgField(self.field_type(t), "value"),), self._constants([t])))
        out.append(MsgView("SampleInfo", "a producer published a sample on the data topic "
                           "<topic> (on <topic>/info)", tuple(MsgField(*f) for f in INFO_FIELDS)))
        out.append(MsgView("Ack", "a consumer took a sample of a blocking producer",
                           tuple(MsgField(*f) for f in ACK_FIELDS)))
        out.append(MsgView("SubsystemStatus", "the diagnostics of a subsystem node",
                           tuple(MsgField(*f) for f in STATUS_FIELDS)))
        return sorted(out, key=lambda m: m.name)

    @staticmethod
    def _constants(types: list[Type]) -> tuple[MsgConstant, ...]:
        """The member constants of the enums of a message's fields, each enum once."""
        seen: dict[str, EnumT] = {}
        for t in types:
            for e in enums_in(t):
                seen.setdefault(e.name, e)
        return tuple(c for e in seen.values() for c in enum_constants(e))

