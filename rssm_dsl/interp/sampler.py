"""Series of a run: the values of chosen variables of subsystems, and their active behaviour,
sampled once per iteration of the subsystem that owns them (when its iteration counter i
moves on), stored by column (rssm_core/series.py) and drawn by `rssmc plot`.

Names are the user's: ``SUBSYSTEM.VARIABLE`` for a memory variable, a parameter or a buffer
(``a1.c.phase``, ``a1.e.arm.cmd``), then ``.field`` and ``[k]`` down to numbers: a vector or
record is one series per component (``a1.e.arm.cmd[0]``, ``a1.c.goal.x``);
``SUBSYSTEM.behaviour`` is the active behaviour (``behaviour`` is a keyword, so no variable
has that name). A selection may use shell patterns (``a1.c.*``, ``*.behaviour``); without
one, every subsystem's behaviour and every numeric component of its memory is taken.
"""

from __future__ import annotations

from collections.abc import Callable, Iterator
from typing import Any

from rssm_core.series import Series, matches
from rssm_dsl.hpn.ir import OpKind
from rssm_dsl.interp.program import Runtime
from rssm_dsl.interp.state import SubsystemState
from rssm_dsl.semantics.types import ArrayT, EnumT, RangeT, RecordT, Scalar, Type

BEHAVIOUR = "behaviour"
MAX_SERIES = 500

Getter = Callable[[Any], Any]


class SelectionError(Exception):
    """A selection that names nothing, or too much."""


def _components(name: str, t: Type, get: Getter) -> Iterator[tuple[str, str, Getter]]:
    """(name, kind, value getter) of each plottable component of a value of type t."""
    if isinstance(t, Scalar | RangeT):
        yield name, "number", get
    elif isinstance(t, EnumT):
        yield name, "category", get
    elif isinstance(t, ArrayT):
        for k in range(t.size):
            yield from _components(f"{name}[{k}]", t.element, _item(get, k))
    elif isinstance(t, RecordT):
        for f, ft in t.fields:
            yield from _components(f"{name}.{f}", ft, _item(get, f))


def _identity(v: Any) -> Any:
    return v


def _item(get: Getter, key: int | str) -> Getter:
    def item(v: Any) -> Any:
        return get(v)[key]
    return item


def _behaviour(s: SubsystemState) -> Getter:
    def behaviour(variables: Any) -> Any:
        return s.behaviour or "end"
    return behaviour


def _variable(var: str, get: Getter) -> Getter:
    def variable(variables: Any) -> Any:
        return get(variables[var])
    return variable


def available(rt: Runtime) -> list[tuple[str, str, SubsystemState, Getter, bool]]:
    """Every series a run can record: (name, kind, owner, getter of the owner's variables,
    taken by default)."""
    out: list[tuple[str, str, SubsystemState, Getter, bool]] = []
    for s in rt.subsystems.values():
        m = s.model
        out.append((f"{s.id}.{BEHAVIOUR}", "category", s, _behaviour(s), True))
        named: list[tuple[str, Type, bool]] = [(v.name, v.type, True) for v in m.memory]
        named += [(v.name, v.type, False) for v in m.params]
        named += [(b.name, b.type, False) for b in (*m.inputs, *m.outputs)]
        for var, t, default in named:
            for name, kind, get in _components(f"{s.id}.{var}", t, _identity):
                out.append((name, kind, s, _variable(var, get), default and kind == "number"))
    return out


class Sampler:
    """Records the selected series of a run: call :meth:`attach` before the Simulator is
    made (it wraps the operation that counts each iteration), :meth:`series` after."""

    def __init__(self, rt: Runtime, patterns: list[str] | None = None) -> None:
        self.rt = rt
        chosen = []
        for name, kind, owner, get, default in available(rt):
            if (matches(name, patterns) if patterns else default):
                chosen.append((Series(name, owner.id, kind), owner, get))
        if patterns:
            for p in patterns:
                if not any(matches(s.name, [p]) for s, _, _ in chosen):
                    known = sorted({n.rsplit(".", 1)[0] for n, *_ in available(rt)})
                    raise SelectionError(f"--select {p} names no series; subsystems: "
                                         f"{', '.join(known)} (a series is SUBSYSTEM.VARIABLE"
                                         f" or SUBSYSTEM.{BEHAVIOUR})")
        if len(chosen) > MAX_SERIES:
            raise SelectionError(f"{len(chosen)} series selected; at most {MAX_SERIES}: "
                                 "narrow --select")
        self.chosen = chosen
        self.by_owner: dict[str, list[tuple[Series, Getter]]] = {}
        for series, owner, get in chosen:
            self.by_owner.setdefault(owner.id, []).append((series, get))

    def attach(self) -> None:
        rt = self.rt
        for p, op in enumerate(rt.ops):
            owner = rt.op_owner[p]
            fp = rt.net.places[p]
            if op is None or not isinstance(owner, SubsystemState) or fp.operation is None:
                continue
            operation = rt.hpn.places[fp.operation].operation
            if operation is None or operation.kind is not OpKind.INCREMENT:
                continue
            mine = self.by_owner.get(owner.id)
            if mine:
                rt.ops[p] = self._sampling(op, owner, mine)

    def _sampling(self, op: Callable[[], None], owner: SubsystemState,
                  mine: list[tuple[Series, Getter]]) -> Callable[[], None]:
        now = self.rt.clock.now
        variables = owner.vars

        def sample() -> None:
            op()
            t = now() / 1e9
            for series, get in mine:
                value = get(variables)
                series.t.append(t)
                if series.kind == "category":
                    series.v.append(float(series.label_index(str(value))))
                else:
                    series.v.append(float(value))
        return sample

    def series(self) -> list[Series]:
        return [s for s, _, _ in self.chosen]
