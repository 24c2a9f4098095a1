"""The types of the RSSM language: bool, int, float, fixed-size arrays and records."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any


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


Type = Scalar | ArrayT | RecordT

BOOL = Scalar("bool")
INT = Scalar("int")
FLOAT = Scalar("float")
SCALARS = {"bool": BOOL, "int": INT, "float": FLOAT}


def is_numeric(t: Type) -> bool:
    return t in (INT, FLOAT)


def is_numeric_array(t: Type) -> bool:
    return isinstance(t, ArrayT) and is_numeric(t.element)


def assignable(src: Type, dst: Type) -> bool:
    """Can a value of type src be stored where dst is expected? (int widens to float)"""
    if src == dst:
        return True
    if src == INT and dst == FLOAT:
        return True
    if isinstance(src, ArrayT) and isinstance(dst, ArrayT):
        return src.size == dst.size and assignable(src.element, dst.element)
    return False


def descriptor(t: Type) -> tuple[Any, ...]:
    """The value descriptor of a type, as the semantics core reads it (rssm_core.values):
    ``("bool",)``, ``("int",)``, ``("float",)``, ``("array", ELEMENT, N)``,
    ``("record", NAME, ((FIELD, DESCRIPTOR), ...))``."""
    if isinstance(t, Scalar):
        return (t.name,)
    if isinstance(t, ArrayT):
        return ("array", descriptor(t.element), t.size)
    return ("record", t.name, tuple((n, descriptor(ft)) for n, ft in t.fields))
