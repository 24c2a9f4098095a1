"""The types of the RSSM language: bool, int, float, enumerations, bounded integers (declared
ranges), fixed-size arrays and records."""

from __future__ import annotations

from typing import Any

from rssm_core.records import dataclass


@dataclass(frozen=True, slots=True)
class Scalar:
    name: str  # "bool" | "int" | "float"

    def __str__(self) -> str:
        return self.name


@dataclass(frozen=True, slots=True)
class ArrayT:
    element: Type
    size: int

    def __str__(self) -> str:
        return f"{self.element}[{self.size}]"


@dataclass(frozen=True, slots=True)
class RecordT:
    name: str
    fields: tuple[tuple[str, Type], ...]

    def field(self, name: str) -> Type | None:
        for n, t in self.fields:
            if n == name:
                return t
        return None

    def __str__(self) -> str:
        return self.name


@dataclass(frozen=True, slots=True)
class EnumT:
    """``enum Phase { idle, approach }``: a value is one of the members (at run time, the
    member's name as a ``str``)."""

    name: str
    members: tuple[str, ...]

    def __str__(self) -> str:
        return self.name


@dataclass(frozen=True, slots=True)
class RangeT:
    """A bounded integer ``lo..hi`` (both included): a subtype of int, checked when stored."""

    lo: int
    hi: int

    def __str__(self) -> str:
        return f"{self.lo}..{self.hi}"

    def __contains__(self, value: object) -> bool:
        return isinstance(value, int) and not isinstance(value, bool) and \
            self.lo <= value <= self.hi


Type = Scalar | ArrayT | RecordT | EnumT | RangeT

BOOL = Scalar("bool")
INT = Scalar("int")
FLOAT = Scalar("float")
SCALARS = {"bool": BOOL, "int": INT, "float": FLOAT}


# a domain of at most this many values is enumerated by finite_domain
MAX_FINITE = 64


def is_int(t: Type) -> bool:
    """int, or a range (which reads as an int anywhere)."""
    return t == INT or isinstance(t, RangeT)


def is_numeric(t: Type) -> bool:
    return t == FLOAT or is_int(t)


def is_numeric_array(t: Type) -> bool:
    return isinstance(t, ArrayT) and is_numeric(t.element)


def assignable(src: Type, dst: Type) -> bool:
    """Can a value of type src be stored where dst is expected? (int widens to float)"""
    if src == dst:
        return True
    if is_int(src) and (is_int(dst) or dst == FLOAT):
        return True   # a range reads as an int; an int is stored into a range (checked then)
    if isinstance(src, ArrayT) and isinstance(dst, ArrayT):
        return src.size == dst.size and assignable(src.element, dst.element)
    return False


def join(a: Type, b: Type) -> Type | None:
    """The type of a value that is either an ``a`` or a ``b`` (the branches of ``if``, the
    items of an array literal): int for two different int types, the wider of two types one
    of which converts to the other, None when neither does."""
    if a == b:
        return a
    if is_int(a) and is_int(b):
        return INT
    if isinstance(a, ArrayT) and isinstance(b, ArrayT) and a.size == b.size:
        element = join(a.element, b.element)
        return ArrayT(element, a.size) if element is not None else None
    if assignable(a, b):
        return b
    if assignable(b, a):
        return a
    return None


def scalar_count(t: Type) -> int:
    """How many scalars (numbers, bools, enum members) a value of type ``t`` holds."""
    if isinstance(t, ArrayT):
        return t.size * scalar_count(t.element)
    if isinstance(t, RecordT):
        return sum(scalar_count(f) for _, f in t.fields)
    return 1


def descriptor(t: Type) -> tuple[Any, ...]:
    """The value descriptor of a type, as the semantics core reads it (rssm_core.values):
    ``("bool",)``, ``("int",)``, ``("float",)``, ``("enum", NAME, MEMBERS)``,
    ``("range", LO, HI)``, ``("array", ELEMENT, N)``,
    ``("record", NAME, ((FIELD, DESCRIPTOR), ...))``."""
    if isinstance(t, Scalar):
        return (t.name,)
    if isinstance(t, EnumT):
        return ("enum", t.name, t.members)
    if isinstance(t, RangeT):
        return ("range", t.lo, t.hi)
    if isinstance(t, ArrayT):
        return ("array", descriptor(t.element), t.size)
    return ("record", t.name, tuple((n, descriptor(ft)) for n, ft in t.fields))


def finite_domain(t: Type) -> tuple[Any, ...] | None:
    """Every run-time value of ``t`` in order, when it has few (bool, an enum, a range of
    at most 64 values); None otherwise (int, float, arrays, records)."""
    if t == BOOL:
        return (False, True)
    if isinstance(t, EnumT):
        return t.members
    if isinstance(t, RangeT) and t.hi - t.lo < MAX_FINITE:
        return tuple(range(t.lo, t.hi + 1))
    return None
