"""rssm_core.records.dataclass makes the same classes as dataclasses.dataclass.

Each shape of class is defined twice, once by each decorator, and everything a caller can see
is compared: the fields, `__init__`'s signature, repr, equality and hashing, frozenness,
`replace`, `asdict`, pickling and copying, `match` by position, slots and class attributes.
"""

from __future__ import annotations

import copy
import dataclasses
import inspect
import pickle
from collections.abc import Callable
from typing import Any, ClassVar

import pytest

from rssm_core import records

Decorator = Callable[..., Any]


def shapes(dc: Decorator) -> dict[str, tuple[type[Any], list[tuple[Any, ...]]]]:
    """Each shape: the class, and argument tuples for instances (two equal, one not)."""

    @dc(frozen=True, slots=True)
    class Node:
        span: int
        name: str

    @dc(frozen=True, slots=True)
    class One:
        value: float

    @dc(frozen=True, slots=True)
    class Empty:
        pass

    @dc(frozen=True)
    class Defaults:
        a: int
        b: str = "x"
        c: tuple[int, ...] = dataclasses.field(default=())
        d: list[int] = dataclasses.field(default_factory=list)

    @dc(frozen=True, slots=True)
    class Hidden:
        a: int
        b: int = dataclasses.field(default=0, compare=False, repr=False)
        c: int = dataclasses.field(default=0, hash=False)
        d: int = dataclasses.field(default=7, init=False)
        e: list[int] = dataclasses.field(default_factory=list, init=False)

    @dc(frozen=True)
    class Derived:
        a: int
        b: int = dataclasses.field(init=False, repr=False, compare=False)
        c: int = dataclasses.field(default=5, init=False)

        def __post_init__(self) -> None:
            object.__setattr__(self, "b", self.a * 2)

    @dc(frozen=True, kw_only=True)
    class Keywords:
        a: int
        b: int = 2

    @dc
    class Mutable:
        a: int
        b: list[int] = dataclasses.field(default_factory=list)

    @dc(eq=False)
    class Identity:
        a: int

    @dc(frozen=True, eq=False)
    class FrozenIdentity:
        a: int

    @dc(frozen=True, order=True)          # handed to the standard decorator
    class Ordered:
        a: int
        b: str

    @dc(frozen=True)
    class WithClassVar:                   # handed to the standard decorator
        limit: ClassVar[int] = 3
        a: int

    return {
        "node": (Node, [(1, "a"), (1, "a"), (2, "a")]),
        "one": (One, [(1.0,), (1.0,), (2.0,)]),
        "empty": (Empty, [(), (), ()]),
        "defaults": (Defaults, [(1,), (1, "x", ()), (1, "y")]),
        "hidden": (Hidden, [(1, 2, 3), (1, 5, 3), (1, 2, 4)]),
        "derived": (Derived, [(1,), (1,), (2,)]),
        "keywords": (Keywords, [(), (), ()]),
        "mutable": (Mutable, [(1,), (1, []), (2,)]),
        "identity": (Identity, [(1,), (1,), (2,)]),
        "frozen_identity": (FrozenIdentity, [(1,), (1,), (2,)]),
        "ordered": (Ordered, [(1, "a"), (1, "a"), (0, "b")]),
        "classvar": (WithClassVar, [(1,), (1,), (2,)]),
    }


OURS = shapes(records._dataclass)
STDLIB = shapes(dataclasses.dataclass)


def make(cls: type[Any], args: tuple[Any, ...]) -> Any:
    if cls.__name__ == "Keywords":
        return cls(a=1) if not args else cls(a=args[0])
    return cls(*args)


def outcome(f: Callable[[], Any]) -> Any:
    """What a call gives: its value, or the type and message of what it raised."""
    try:
        return ("value", f())
    except Exception as e:  # the exception is what is compared
        return ("raised", type(e).__name__, str(e))


def observe(cls: type[Any], argsets: list[tuple[Any, ...]]) -> dict[str, Any]:
    x, y, z = (make(cls, a) for a in argsets)
    seen: dict[str, Any] = {
        "state": [[getattr(v, f.name) for f in dataclasses.fields(cls)] for v in (x, y, z)],
        "fields": [(f.name, f.type, f.default, f.default_factory, f.init, f.repr, f.compare,
                    f.hash, f.kw_only) for f in dataclasses.fields(cls)],
        "signature": [(p.name, p.kind, p.default) for p in
                      inspect.signature(cls.__init__).parameters.values()],
        "repr": [repr(x), repr(z)],
        "eq": [x == y, x == z, x != z, x == 1, x.__eq__(object())],
        "hashable": outcome(lambda: hash(x) == hash(y)),
        "set": outcome(lambda: len({x, y, z})),
        "is_dataclass": dataclasses.is_dataclass(x),
        "replace": outcome(lambda: repr(dataclasses.replace(x))),
        "asdict": dataclasses.asdict(x),
        "astuple": dataclasses.astuple(x),
        "deepcopy": repr(copy.deepcopy(x)) == repr(x),
        "copy": repr(copy.copy(x)) == repr(x),
        "match_args": getattr(cls, "__match_args__", None),
        "slots": getattr(cls, "__slots__", None),
        "has_dict": hasattr(x, "__dict__"),
        "class_defaults": {name: getattr(cls, name, "<none>")
                           for name in ("a", "b", "c", "d", "e", "limit")
                           if not isinstance(getattr(cls, name, None), property)
                           and not type(getattr(cls, name, None)).__name__.endswith("descriptor")},
        "params": {k: getattr(cls.__dataclass_params__, k) for k in
                   ("init", "repr", "eq", "order", "unsafe_hash", "frozen")},
        "qualname": cls.__qualname__.rsplit(".", 1)[-1],
        "hash_attr_none": cls.__hash__ is None,
    }
    if dataclasses.fields(cls):
        first = dataclasses.fields(cls)[0].name
        seen["setattr"] = outcome(lambda: setattr(x, first, 9))
        seen["delattr"] = outcome(lambda: delattr(x, first))
        # the standard decorator of 3.11 raises TypeError for a slotted class (its
        # __setattr__ names the class before __slots__ replaced it), ours FrozenInstanceError
        seen["new_attr"] = outcome(lambda: setattr(z, "unknown", 1))[0]
    if cls.__name__ == "Ordered":
        seen["order"] = [x < z, z < x, x <= y]
    return seen


@pytest.mark.parametrize("shape", sorted(OURS))
def test_same_class_as_the_standard_decorator(shape: str) -> None:
    ours, stdlib = OURS[shape], STDLIB[shape]
    assert observe(*ours) == observe(*stdlib)


@pytest.mark.parametrize("shape", ["node", "one", "empty", "defaults", "hidden", "derived",
                                   "keywords", "mutable", "identity", "frozen_identity"])
def test_common_shapes_take_the_cheap_path(shape: str) -> None:
    """Not handed to the standard decorator (else the test above compares it with itself)."""
    cls = OURS[shape][0]
    assert cls.__init__.__globals__.get("__object_setattr") is object.__setattr__
    if shape not in ("identity", "frozen_identity"):
        assert cls.__eq__.__qualname__.startswith("_eq.")


def test_fallbacks_are_the_standard_decorator() -> None:
    for shape in ("ordered", "classvar"):
        cls = OURS[shape][0]
        assert "__object_setattr" not in cls.__init__.__globals__


@records._dataclass(frozen=True, slots=True)
class PickledNode:
    span: int
    name: str
    tags: tuple[str, ...] = ()


@records._dataclass(frozen=True)
class PickledRecord:
    a: int
    b: list[int] = dataclasses.field(default_factory=list)


def test_pickling() -> None:
    for value in (PickledNode(1, "a", ("t",)), PickledRecord(2, [3])):
        back = pickle.loads(pickle.dumps(value))
        assert back == value and back is not value and type(back) is type(value)


def test_match_by_position() -> None:
    node_class = OURS["node"][0]
    match node_class(3, "x"):
        case node_class(span, name):
            assert (span, name) == (3, "x")
        case _:
            pytest.fail("no match")


def test_post_init_runs_after_the_fields_are_set() -> None:
    seen: list[int] = []

    @records._dataclass(frozen=True, slots=True)
    class Checked:
        a: int

        def __post_init__(self) -> None:
            seen.append(self.a)

    Checked(4)
    assert seen == [4]
    assert "__object_setattr" in Checked.__init__.__globals__


def test_errors_of_the_standard_decorator() -> None:
    for dc in (records._dataclass, dataclasses.dataclass):
        with pytest.raises(TypeError, match="non-default argument 'b' follows default"):
            @dc(frozen=True)
            class Bad:
                a: int = 0
                b: int
        with pytest.raises(ValueError, match="mutable default"):
            @dc(frozen=True)
            class Mutable:
                a: list[int] = []  # noqa: RUF012 - the error under test
