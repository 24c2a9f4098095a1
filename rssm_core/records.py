"""`dataclass`: the standard library's decorator, with a cheaper class creation.

Python 3.11's `dataclasses.dataclass` compiles six functions for each frozen class (`__init__`,
`__repr__`, `__eq__`, `__hash__`, `__setattr__`, `__delattr__`), about 0.7 ms a class; the
syntax tree and the semantic model define about a hundred, which was a third of `rssmc check`'s
start-up. This decorator compiles no code for a class: its `__init__` is the code compiled once
for every class of the same shape (which fields have defaults or factories), with the class's
field names put in, and the other methods are closures over the field names; a class costs
about a twentieth. What it makes is a dataclass
in every observable way: `dataclasses.fields`, `replace`, `asdict`, `is_dataclass`, `match`
by position, pickling and copying, `FrozenInstanceError`, the same equality and hashing
(the tuple of the compared fields, only between instances of the same class).

It takes the standard decorator's arguments. What it does not implement itself (`order`,
`unsafe_hash`, `init=False` for the class, `weakref_slot`, a field's own `kw_only`, `ClassVar`,
`InitVar` and `KW_ONLY` annotations, a dataclass base class, a class that defines one of the
generated methods itself) it hands to `dataclasses.dataclass`, so every class gets the
standard semantics. Type checkers see `dataclasses.dataclass` itself.

Differences that no caller can rely on: the class's `__doc__` is not replaced by its
signature when it has none, and `__repr__` has no guard against a record that contains itself
(a frozen record cannot).
"""

from __future__ import annotations

import dataclasses
import inspect
from collections.abc import Callable
from functools import cache
from operator import attrgetter
from types import CodeType, FunctionType
from typing import TYPE_CHECKING, Any

__all__ = ["dataclass"]

_GENERATED = ("__init__", "__repr__", "__eq__", "__hash__", "__setattr__", "__delattr__",
              "__getstate__", "__setstate__", "__match_args__", "__slots__")
_UNSUPPORTED_ANNOTATIONS = ("ClassVar", "InitVar", "KW_ONLY")
_FIELD_TYPE: Any = vars(dataclasses)["_FIELD"]
_PARAMS: Any = vars(dataclasses)["_DataclassParams"]


_HAS_FACTORY: Any = vars(dataclasses)["_HAS_DEFAULT_FACTORY"]   # what signatures show

def _dataclass(cls: type[Any] | None = None, /, *, init: bool = True, repr: bool = True,
               eq: bool = True, order: bool = False, unsafe_hash: bool = False,
               frozen: bool = False, match_args: bool = True, kw_only: bool = False,
               slots: bool = False, weakref_slot: bool = False) -> Any:
    """As `dataclasses.dataclass` (same arguments, same result)."""
    options = dict(init=init, repr=repr, eq=eq, order=order, unsafe_hash=unsafe_hash,
                   frozen=frozen, match_args=match_args, kw_only=kw_only, slots=slots,
                   weakref_slot=weakref_slot)

    def wrap(c: type[Any]) -> type[Any]:
        made = _make(c, repr=repr, eq=eq, frozen=frozen, kw_only=kw_only, slots=slots) \
            if init and match_args and not (order or unsafe_hash or weakref_slot) else None
        return made if made is not None else dataclasses.dataclass(c, **options)  # type: ignore[call-overload, no-any-return]

    return wrap if cls is None else wrap(cls)


def _fields_of(cls: type[Any], kw_only: bool) -> list[dataclasses.Field[Any]] | None:
    """The class's fields as the standard decorator makes them, or None where it must."""
    if any(hasattr(base, "__dataclass_fields__") for base in cls.__mro__[1:]):
        return None
    if any(name in cls.__dict__ for name in _GENERATED):
        return None
    if getattr(cls, "__abstractmethods__", None):
        return None
    fields: list[dataclasses.Field[Any]] = []
    for name, annotation in inspect.get_annotations(cls).items():
        text = annotation if isinstance(annotation, str) else getattr(annotation, "__name__", "")
        if any(word in text for word in _UNSUPPORTED_ANNOTATIONS):
            return None
        default = cls.__dict__.get(name, dataclasses.MISSING)
        if isinstance(default, dataclasses.Field):
            f = default
            if f.kw_only is not dataclasses.MISSING:
                return None
        else:
            if default is not dataclasses.MISSING and default.__class__.__hash__ is None:
                return None           # the standard decorator's error about mutable defaults
            f = dataclasses.field(default=default)
        f.name = name
        f.type = annotation
        f.kw_only = kw_only  # type: ignore[assignment]
        f._field_type = _FIELD_TYPE  # type: ignore[attr-defined]
        fields.append(f)
    seen_default = False
    for f in (f for f in fields if f.init):
        has_default = f.default is not dataclasses.MISSING \
            or f.default_factory is not dataclasses.MISSING
        if not kw_only and seen_default and not has_default:
            return None               # the standard decorator's error about the order
        seen_default = seen_default or has_default
    return fields


def _init(cls: type[Any], fields: list[dataclasses.Field[Any]], frozen: bool, kw_only: bool,
          slots: bool, post_init: bool) -> Callable[..., None]:
    """`__init__` as the standard decorator compiles it: the code of `_template` for the
    class's shape, with the field names put in (the template's only names and strings
    that stand for fields), its defaults and factories in its globals."""
    env: dict[str, Any] = {"__object_setattr": object.__setattr__, "__has_factory": _HAS_FACTORY}
    kinds: list[str] = []
    defaults: list[Any] = []
    for i, f in enumerate(fields):
        factory = f.default_factory is not dataclasses.MISSING
        if factory:
            env[f"__factory{i}"] = f.default_factory
        if f.init:
            kinds.append("factory" if factory else
                         "plain" if f.default is dataclasses.MISSING else "default")
            if kinds[-1] != "plain":
                defaults.append(_HAS_FACTORY if factory else f.default)
        elif factory:
            kinds.append("set-factory")
        elif slots and f.default is not dataclasses.MISSING:
            env[f"__default{i}"] = f.default
            kinds.append("set-default")
        else:
            kinds.append("skip")   # the class attribute holds the default
    template = _template(frozen, kw_only, tuple(kinds), post_init)
    rename = {f"__f{i}__": f.name for i, f in enumerate(fields)}
    code = template.replace(
        co_varnames=tuple(rename.get(n, n) for n in template.co_varnames),
        co_names=tuple(rename.get(n, n) for n in template.co_names),
        co_consts=tuple(rename.get(c, c) if isinstance(c, str) else c
                        for c in template.co_consts),
        co_qualname=f"{cls.__qualname__}.__init__")
    init = FunctionType(code, env, "__init__", None if kw_only else tuple(defaults))
    if kw_only:
        init.__kwdefaults__ = {f.name: d for f, d in zip(
            [f for f, k in zip(fields, kinds, strict=True) if k in ("default", "factory")],
            defaults, strict=True)}
    return init


@cache
def _template(frozen: bool, kw_only: bool, kinds: tuple[str, ...], post_init: bool) -> CodeType:
    """The code of an `__init__` for fields `__f0__`, `__f1__`, ... of these kinds: "plain",
    "default", "factory" (parameters), "set-factory", "set-default" (set from the globals
    `__factory<i>`, `__default<i>`) or "skip"."""
    params: list[str] = []
    body: list[str] = []
    for i, kind in enumerate(kinds):
        name = f"__f{i}__"
        value = {"factory": f"__factory{i}() if {name} is __has_factory else {name}",
                 "set-factory": f"__factory{i}()", "set-default": f"__default{i}"}.get(kind, name)
        if kind in ("plain", "default", "factory"):
            params.append(name if kind == "plain" else f"{name}=None")
        if kind != "skip":
            body.append(f"__object_setattr(self, {name!r}, {value})" if frozen
                        else f"self.{name} = {value}")
    if post_init:
        body.append("self.__post_init__()")
    star = ["*"] if kw_only and params else []
    source = (f"def __init__(self, {', '.join([*star, *params])}) -> None:\n"
              + "".join(f"    {line}\n" for line in body or ["pass"]))
    module = compile(source, "<string>", "exec")
    code: CodeType = next(c for c in module.co_consts if isinstance(c, CodeType))
    return code


def _key(names: tuple[str, ...]) -> Callable[[Any], tuple[Any, ...]]:
    """The tuple of the named attributes (attrgetter alone gives a bare value for one name)."""
    if not names:
        return lambda self: ()
    if len(names) == 1:
        one = attrgetter(names[0])
        return lambda self: (one(self),)
    many: Callable[[Any], tuple[Any, ...]] = attrgetter(*names)
    return many


def _make(cls: type[Any], *, repr: bool, eq: bool, frozen: bool, kw_only: bool,
          slots: bool) -> type[Any] | None:
    fields = _fields_of(cls, kw_only)
    if fields is None:
        return None
    names = tuple(f.name for f in fields)
    made: dict[str, Any] = {
        "__dataclass_fields__": {f.name: f for f in fields},
        "__dataclass_params__": _params(repr=repr, eq=eq, frozen=frozen, kw_only=kw_only,
                                        slots=slots),
        "__init__": _init(cls, fields, frozen, kw_only, slots, "__post_init__" in cls.__dict__),
        "__match_args__": () if kw_only else tuple(f.name for f in fields if f.init),
    }
    if repr:
        made["__repr__"] = _repr([f.name for f in fields if f.repr])
    if eq:                        # the class defines neither __eq__ nor __hash__ (_fields_of)
        made["__eq__"] = _eq(_key(tuple(f.name for f in fields if f.compare)))
        made["__hash__"] = _hash(_key(tuple(
            f.name for f in fields if (f.compare if f.hash is None else f.hash)))) \
            if frozen else None
    if not slots:                 # as the standard decorator: the class itself, plain defaults
        for f in fields:          # staying class attributes
            if f.default is not dataclasses.MISSING:
                setattr(cls, f.name, f.default)
            elif f.name in cls.__dict__:
                delattr(cls, f.name)
        for name, value in made.items():
            setattr(cls, name, value)
        result = cls
    else:                         # as the standard decorator: a new class with __slots__
        namespace = dict(cls.__dict__)
        for name in ("__dict__", "__weakref__", *names):
            namespace.pop(name, None)
        namespace.update(made, __slots__=names)
        if frozen:
            namespace["__getstate__"] = _getstate(names)
            namespace["__setstate__"] = _setstate(names)
        metaclass: Any = type(cls)
        result = metaclass(cls.__name__, cls.__bases__, namespace)
        result.__qualname__ = cls.__qualname__
    if frozen:
        result.__setattr__, result.__delattr__ = _frozen(result, names)  # type: ignore[method-assign, assignment]
    return result


def _params(**given: bool) -> Any:
    """`__dataclass_params__`, whose fields differ between Python versions."""
    every = dict(init=True, repr=True, eq=True, order=False, unsafe_hash=False, frozen=False,
                 match_args=True, kw_only=False, slots=False, weakref_slot=False) | given
    try:
        return _PARAMS(**every)
    except TypeError:             # Python 3.11: six of them
        return _PARAMS(**{k: every[k] for k in
                          ("init", "repr", "eq", "order", "unsafe_hash", "frozen")})


def _repr(names: list[str]) -> Callable[[Any], str]:
    def __repr__(self: Any) -> str:
        inner = ", ".join(f"{name}={getattr(self, name)!r}" for name in names)
        return f"{self.__class__.__qualname__}({inner})"
    return __repr__


def _eq(key: Callable[[Any], tuple[Any, ...]]) -> Callable[[Any, object], Any]:
    def __eq__(self: Any, other: object) -> Any:
        if other.__class__ is self.__class__:
            return key(self) == key(other)
        return NotImplemented
    return __eq__


def _hash(key: Callable[[Any], tuple[Any, ...]]) -> Callable[[Any], int]:
    def __hash__(self: Any) -> int:
        return hash(key(self))
    return __hash__


def _frozen(cls: type[Any], names: tuple[str, ...]) -> tuple[Callable[[Any, str, Any], None],
                                                             Callable[[Any, str], None]]:
    def __setattr__(self: Any, name: str, value: Any) -> None:
        if type(self) is cls or name in names:
            raise dataclasses.FrozenInstanceError(f"cannot assign to field {name!r}")
        super(cls, self).__setattr__(name, value)

    def __delattr__(self: Any, name: str) -> None:
        if type(self) is cls or name in names:
            raise dataclasses.FrozenInstanceError(f"cannot delete field {name!r}")
        super(cls, self).__delattr__(name)

    return __setattr__, __delattr__


def _getstate(names: tuple[str, ...]) -> Callable[[Any], list[Any]]:
    def __getstate__(self: Any) -> list[Any]:
        return [getattr(self, name) for name in names]
    return __getstate__


def _setstate(names: tuple[str, ...]) -> Callable[[Any, list[Any]], None]:
    def __setstate__(self: Any, state: list[Any]) -> None:
        for name, value in zip(names, state, strict=True):
            object.__setattr__(self, name, value)
    return __setstate__


if TYPE_CHECKING:
    from dataclasses import dataclass as dataclass
else:
    dataclass = _dataclass
