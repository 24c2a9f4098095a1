"""The firing rule of the flat net, defined once.

The flat net (``rssm_dsl.hpn.flat``) is a safe place/transition net: a marking is the set of
places that hold a token (at most one each). Here a net is only its structure, the pre-set
and the post-set of every transition (tuples of place indices), which is all the rule needs:

* transition ``t`` is **enabled** in marking ``M`` when every input place of ``t`` is marked
  (``pre(t) ⊆ M``; a transition without input places is always enabled). Conditions on data
  are not part of the rule: a backend that has them evaluates them on the enabled
  transitions;
* **firing** ``t`` removes the token of each input place and then puts one token into each
  output place: ``M' = (M \\ pre(t)) ∪ post(t)``. A place both in ``pre(t)`` and in
  ``post(t)`` (a test arc) must be marked and stays marked;
* the firing is **unsafe** when an output place already holds a token after the input places
  were emptied, i.e. the places ``(M \\ pre(t)) ∩ post(t) = M ∩ (post(t) \\ pre(t))``: the net
  would hold two tokens in one place, which is an error (the nets of RSSM are meant to be
  safe). :meth:`Net.fire` still gives the marking as a set (the second token is lost) and
  reports those places; what to do about them is the caller's decision (the interpreter stops
  with E807, the verifier reports the firing sequence, the playback shows it).

Every backend follows this rule: the playback (``rssm_dsl.render.playback``) and the replay
(``rssm_dsl.interp.replay``) call it; the fast paths (the interpreter's token game and its
compiled firing code, the verifier's bitsets and vectorised search) take the structure from a
:class:`Net` and are proved equal to it by the property tests of ``tests/core``.

Only the standard library is used.
"""

from __future__ import annotations

from collections.abc import Iterable, Sequence, Set
from typing import Protocol

from rssm_core.records import dataclass

Marking = frozenset[int]


class Arcs(Protocol):
    """Anything with the input and output places of a transition (a flat transition)."""

    @property
    def pre(self) -> tuple[int, ...]: ...

    @property
    def post(self) -> tuple[int, ...]: ...


class NetError(ValueError):
    """The pre- and post-sets do not describe a net (``transition``: the culprit)."""

    def __init__(self, transition: int | None, problem: str) -> None:
        super().__init__(problem if transition is None else f"transition {transition}: {problem}")
        self.transition = transition
        self.problem = problem


class NotEnabled(Exception):
    """A transition was fired in a marking where some of its input places hold no token."""

    def __init__(self, transition: int, missing: tuple[int, ...]) -> None:
        places = ", ".join(str(p) for p in missing)
        super().__init__(f"transition {transition} is not enabled: place(s) {places} unmarked")
        self.transition = transition
        self.missing = missing


class UnsafeFiring(Exception):
    """Firing ``transition`` would put a second token into ``place`` (the first such output
    place; ``places`` lists all of them)."""

    def __init__(self, transition: int, place: int, places: tuple[int, ...] = ()) -> None:
        super().__init__(f"transition {transition} would mark place {place} twice")
        self.transition = transition
        self.place = place
        self.places = places or (place,)


@dataclass(frozen=True, slots=True)
class Firing:
    """The outcome of one firing: the marking reached and the places marked twice."""

    transition: int
    marking: Marking
    unsafe: tuple[int, ...] = ()   # ascending; empty when the firing is safe

    @property
    def safe(self) -> bool:
        return not self.unsafe


def _arcs(places: Iterable[int], nplaces: int, t: int, side: str) -> tuple[int, ...]:
    try:
        out = tuple(sorted(places))
    except TypeError:
        out = ()
        bad: object = places
    else:
        bad = next((p for p in out if type(p) is not int), None)
        if bad is None and out and (out[0] < 0 or out[-1] >= nplaces):
            bad = out[0] if out[0] < 0 else out[-1]
    if bad is not None:
        raise NetError(t, f"{side}-set place {bad!r} is not a place index (0..{nplaces - 1})")
    if len(set(out)) != len(out):
        raise NetError(t, f"a place occurs twice in its {side}-set (arcs have weight 1)")
    return out


class Net:
    """The structure of a flat net and the firing rule over it (see the module docstring).

    ``pre[t]`` / ``post[t]``: the input / output places of transition ``t``, ascending.
    Derived, for the fast paths: ``consume[t] = pre \\ post`` (the places the firing empties),
    ``produce[t] = post \\ pre`` (the places it fills; only these can become unsafe),
    ``consumers[p]`` (the transitions with ``p`` in their pre-set: the only ones whose
    enabledness depends on ``p``), ``producers[p]`` (the transitions with ``p`` in their
    ``produce``) and ``sources`` (the transitions without input places).
    """

    __slots__ = ("consume", "consumers", "nplaces", "post", "pre", "produce", "producers",
                 "sources")

    def __init__(self, pre: Sequence[Iterable[int]], post: Sequence[Iterable[int]],
                 nplaces: int) -> None:
        if len(pre) != len(post):
            raise NetError(None, f"{len(pre)} pre-sets but {len(post)} post-sets")
        if nplaces < 0:
            raise NetError(None, "a negative number of places")
        self.nplaces = nplaces
        self.pre: tuple[tuple[int, ...], ...] = tuple(
            _arcs(ps, nplaces, t, "pre") for t, ps in enumerate(pre))
        self.post: tuple[tuple[int, ...], ...] = tuple(
            _arcs(ps, nplaces, t, "post") for t, ps in enumerate(post))
        self.consume: tuple[tuple[int, ...], ...] = tuple(
            tuple(p for p in a if p not in b) for a, b in zip(self.pre, self.post, strict=True))
        self.produce: tuple[tuple[int, ...], ...] = tuple(
            tuple(p for p in b if p not in a) for a, b in zip(self.pre, self.post, strict=True))
        consumers: list[list[int]] = [[] for _ in range(nplaces)]
        producers: list[list[int]] = [[] for _ in range(nplaces)]
        for t, ps in enumerate(self.pre):
            for p in ps:
                consumers[p].append(t)
        for t, ps in enumerate(self.produce):
            for p in ps:
                producers[p].append(t)
        self.consumers: tuple[tuple[int, ...], ...] = tuple(tuple(c) for c in consumers)
        self.producers: tuple[tuple[int, ...], ...] = tuple(tuple(c) for c in producers)
        self.sources: tuple[int, ...] = tuple(t for t, ps in enumerate(self.pre) if not ps)

    @classmethod
    def of(cls, transitions: Iterable[Arcs], nplaces: int) -> Net:
        """The net of transitions given in index order (e.g. ``FlatNet.transitions``)."""
        ts = list(transitions)
        return cls([t.pre for t in ts], [t.post for t in ts], nplaces)

    @property
    def ntransitions(self) -> int:
        return len(self.pre)

    def __repr__(self) -> str:
        return f"Net({self.nplaces} places, {self.ntransitions} transitions)"

    # ------------------------------------------------------------------ the rule
    def enabled(self, marking: Set[int], t: int) -> bool:
        """Is ``t`` enabled in ``marking`` (every input place marked)?"""
        return all(p in marking for p in self.pre[t])

    def missing(self, marking: Set[int], t: int) -> tuple[int, ...]:
        """The input places of ``t`` that ``marking`` leaves empty (none: ``t`` is enabled)."""
        return tuple(p for p in self.pre[t] if p not in marking)

    def unsafe(self, marking: Set[int], t: int) -> tuple[int, ...]:
        """The places that firing ``t`` in ``marking`` would mark a second time."""
        return tuple(p for p in self.produce[t] if p in marking)

    def fire(self, marking: Set[int], t: int) -> Firing:
        """Fire enabled ``t`` in ``marking``: the marking reached and the unsafe places.
        Raises :class:`NotEnabled` if ``t`` is not enabled."""
        gone = self.missing(marking, t)
        if gone:
            raise NotEnabled(t, gone)
        unsafe = self.unsafe(marking, t)
        return Firing(t, frozenset(marking).difference(self.pre[t]).union(self.post[t]),
                      unsafe)

    def fire_in_place(self, marked: set[int], t: int) -> tuple[int, ...]:
        """Fire enabled ``t`` on the mutable marking ``marked``; returns the unsafe places.
        Raises :class:`NotEnabled` (leaving ``marked`` as it was) if ``t`` is not enabled."""
        gone = self.missing(marked, t)
        if gone:
            raise NotEnabled(t, gone)
        unsafe = self.unsafe(marked, t)
        marked.difference_update(self.pre[t])
        marked.update(self.post[t])
        return unsafe

    # ------------------------------------------------------------------ derived views
    def enabled_set(self, marking: Set[int]) -> tuple[int, ...]:
        """The transitions enabled in ``marking``, ascending."""
        candidates = set(self.sources)
        consumers = self.consumers
        for p in marking:
            candidates.update(consumers[p])
        return tuple(sorted(t for t in candidates if self.enabled(marking, t)))

    def successors(self, marking: Set[int]) -> tuple[Firing, ...]:
        """One :class:`Firing` per enabled transition, in transition order."""
        return tuple(self.fire(marking, t) for t in self.enabled_set(marking))

    def is_dead(self, marking: Set[int]) -> bool:
        """No transition is enabled in ``marking``."""
        return not self.enabled_set(marking)

    def conflict(self, t: int) -> tuple[int, ...]:
        """``t`` and the transitions sharing an input place with it (ascending): the only
        ones whose firing can take a token ``t`` needs."""
        out = {t}
        for p in self.pre[t]:
            out.update(self.consumers[p])
        return tuple(sorted(out))

    def may_disable(self, t: int) -> tuple[int, ...]:
        """The transitions that firing ``t`` can disable: the consumers of the places it
        empties (ascending)."""
        return tuple(sorted({u for p in self.consume[t] for u in self.consumers[p]}))

    def may_enable(self, t: int) -> tuple[int, ...]:
        """The transitions that firing ``t`` can enable: the consumers of the places it
        fills (ascending)."""
        return tuple(sorted({u for p in self.produce[t] for u in self.consumers[p]}))

    def run(self, marking: Set[int], steps: Iterable[int]) -> list[Firing]:
        """Fire ``steps`` one after the other from ``marking``; the firings (each with the
        marking it reached). Raises :class:`NotEnabled` at the first step that cannot fire."""
        out: list[Firing] = []
        current: Set[int] = marking
        for t in steps:
            f = self.fire(current, t)
            out.append(f)
            current = f.marking
        return out
