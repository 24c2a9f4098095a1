"""The flat net compiled to bitmasks: the one representation every explorer shares.

A marking of a safe net is a Python ``int`` whose bit ``p`` is set when place ``p`` holds a
token. Transition ``t`` is enabled in ``m`` when ``m & pre[t] == pre[t]``; firing it gives
``(m & ~pre[t]) | post[t]``, and the firing is *unsafe* (it would put a second token into a
place) when ``(m & ~pre[t]) & post[t]`` is not zero. A place in both the pre- and the post-set
of a transition is a test (read) arc: it must be marked and stays marked.

The vectorised explorer works on the same masks split into 64-bit words (``words``).

This is the firing rule of :mod:`rssm_core.firing` in bitmask form: the masks are derived from
the :class:`~rssm_core.firing.Net` of the flat net (``NetBits.rule``: its pre-sets, post-sets,
``consume``, ``produce``, consumers and producers), and ``tests/core`` checks ``enabled``,
``fire``, ``unsafe_places`` and the vectorised search against the rule on random nets.
"""

from __future__ import annotations

import numpy as np
import numpy.typing as npt

from rssm_core.firing import Net, NetError
from rssm_core.records import dataclass
from rssm_dsl.hpn.flat import FlatNet, Role

U64 = npt.NDArray[np.uint64]


def bits(mask: int) -> list[int]:
    """The indices of the set bits of ``mask``, ascending."""
    out: list[int] = []
    while mask:
        low = mask & -mask
        out.append(low.bit_length() - 1)
        mask ^= low
    return out


def to_mask(indices: frozenset[int] | tuple[int, ...] | list[int]) -> int:
    """The mask with the bits ``indices`` set. A long list is set in a byte array and made
    one int at the end: OR-ing bit by bit into a big int copies it each time (quadratic)."""
    if len(indices) < 64:
        mask = 0
        for i in indices:
            mask |= 1 << i
        return mask
    top = max(indices)
    buf = bytearray(top // 8 + 1)
    for i in indices:
        buf[i >> 3] |= 1 << (i & 7)
    return int.from_bytes(buf, "little")


def _union(masks: tuple[int, ...], indices: tuple[int, ...]) -> int:
    out = 0
    for i in indices:
        out |= masks[i]
    return out


def to_words(mask: int, nwords: int) -> list[int]:
    return [(mask >> (64 * w)) & 0xFFFF_FFFF_FFFF_FFFF for w in range(nwords)]


def from_words(words: list[int] | tuple[int, ...]) -> int:
    mask = 0
    for w, value in enumerate(words):
        mask |= int(value) << (64 * w)
    return mask


@dataclass(frozen=True)
class NetBits:
    """Per-transition and per-place masks of a flat net, computed once."""

    net: FlatNet
    nplaces: int
    ntrans: int
    initial: int
    final: int                      # mask of net.final; m is final iff final != 0, m ⊇ final
    pre: tuple[int, ...]            # per transition: input places
    post: tuple[int, ...]           # per transition: output places
    consume: tuple[int, ...]        # per transition: pre \ post (places emptied by the firing)
    produce: tuple[int, ...]        # per transition: post \ pre (places filled by the firing)
    consumers: tuple[int, ...]      # per place: transitions with the place in their pre-set
    producers: tuple[int, ...]      # per place: transitions that fill the place (post \ pre)
    conflict: tuple[int, ...]       # per transition: transitions sharing an input place with it
    nwords: int
    pre_words: U64                  # (ntrans, nwords)
    post_words: U64                 # (ntrans, nwords)
    rule: Net                       # the structure the masks are made of

    @staticmethod
    def of(net: FlatNet) -> NetBits:
        nplaces = len(net.places)
        ntrans = len(net.transitions)
        for i, place in enumerate(net.places):
            if place.index != i:
                raise ValueError(f"place {place.name!r} has index {place.index}, expected {i}")
        for i, tr in enumerate(net.transitions):
            if tr.index != i:
                raise ValueError(f"transition {tr.name!r} has index {tr.index}, expected {i}")
        try:
            rule = net.rule
        except NetError as e:
            if e.transition is None:
                raise
            name = net.transitions[e.transition].name
            raise ValueError(f"transition {name!r}: {e.problem}") from None
        pre = tuple(to_mask(ps) for ps in rule.pre)
        post = tuple(to_mask(ps) for ps in rule.post)
        consume = tuple(to_mask(ps) for ps in rule.consume)
        produce = tuple(to_mask(ps) for ps in rule.produce)
        consumers = tuple(to_mask(ts) for ts in rule.consumers)
        producers = tuple(to_mask(ts) for ts in rule.producers)
        # t and the transitions sharing an input place with it (rule.conflict), as the union
        # of its input places' consumers: the variants of one transition over tracked values
        # share their input places, so building each set first was quadratic
        conflict = tuple(_union(consumers, ps) | (1 << t) for t, ps in enumerate(rule.pre))
        nwords = max(1, (nplaces + 63) // 64)
        pre_words = np.array([to_words(m, nwords) for m in pre], dtype=np.uint64).reshape(
            ntrans, nwords)
        post_words = np.array([to_words(m, nwords) for m in post], dtype=np.uint64).reshape(
            ntrans, nwords)
        return NetBits(
            net=net, nplaces=nplaces, ntrans=ntrans,
            initial=to_mask(net.initial), final=to_mask(net.final),
            pre=pre, post=post, consume=consume, produce=produce,
            consumers=consumers, producers=producers, conflict=conflict,
            nwords=nwords, pre_words=pre_words, post_words=post_words, rule=rule,
        )

    def is_final(self, marking: int) -> bool:
        return self.final != 0 and marking & self.final == self.final

    def enabled(self, marking: int) -> list[int]:
        pre = self.pre
        return [t for t in range(self.ntrans) if marking & pre[t] == pre[t]]

    def fire(self, marking: int, t: int) -> int:
        return (marking & ~self.pre[t]) | self.post[t]

    def unsafe_places(self, marking: int, t: int) -> int:
        """Places that firing ``t`` in ``marking`` would mark a second time (0 if safe)."""
        return marking & self.produce[t]

    def iteration_mask(self, subsystem: str) -> int:
        mask = 0
        for tr in self.net.transitions:
            if tr.role is Role.ITERATION and tr.subsystem == subsystem:
                mask |= 1 << tr.index
        return mask

    def marking_of(self, mask: int) -> frozenset[int]:
        return frozenset(bits(mask))
