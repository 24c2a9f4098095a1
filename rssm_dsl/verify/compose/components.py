"""A component of the flat net and its own LTS.

A *component* is a set of places. Its LTS is the token game on those places alone: every
transition touching them is an action, enabled when its input places *in the component* are
marked, whatever the rest of the net holds. The reachability graph of the net is exactly the
parallel composition of the LTSs of any partition of its places into components
(synchronising on the transitions they share); how the places are cut only decides how small
the pieces stay (``tree`` cuts along the HPN's pages).

A firing that would put a second token into a place of the component leads to a sink state
flagged ``UNSAFE``. Such a firing happens in the net exactly when it happens in the
composition, so safeness is decided without invariants.
"""

from __future__ import annotations

from rssm_core.records import dataclass
from rssm_dsl.verify.budget import Budget
from rssm_dsl.verify.compose.lts import BUSY, FINAL, OBSERVED, TAU, UNSAFE, VIOLATED, Edges, Lts
from rssm_dsl.verify.compose.product import TooLarge
from rssm_dsl.verify.netbits import NetBits, bits


@dataclass(frozen=True)
class Component:
    name: str                      # the page (or place) it stands for
    places: int                    # mask of its places
    transitions: tuple[int, ...]   # transitions touching its places: its alphabet

    @staticmethod
    def of(nb: NetBits, name: str, places: int) -> Component:
        return Component(name, places, _touching(nb, places))


def _touching(nb: NetBits, mask: int) -> tuple[int, ...]:
    ts = 0
    for p in bits(mask):
        ts |= nb.consumers[p] | nb.producers[p]
    # transitions with the place only as a test arc (pre and post) are consumers already
    return tuple(bits(ts))


def local_lts(nb: NetBits, comp: Component, visible: frozenset[int], max_states: int,
              observe: tuple[int, ...] = (), control: int = 0,
              entries: frozenset[int] = frozenset(), budget: Budget | None = None) -> Lts:
    """The component's own token game; transitions not in ``visible`` are silent.

    A state marking some place of ``observe[i]`` has flag ``OBSERVED << i``, one marking a
    place of ``control`` has ``BUSY``; an ``entries`` transition fired in a ``BUSY`` state
    leads to a ``VIOLATED`` sink (see ``check``)."""
    mask = comp.places
    final = nb.final & mask
    final_always = nb.final != 0 and final == 0
    trans = []
    for t in comp.transitions:
        pre = nb.pre[t] & mask
        consume = nb.consume[t] & mask
        produce = nb.produce[t] & mask
        trans.append((TAU if t not in visible else t, pre, ~consume, produce, t in entries))
    init = nb.initial & mask
    number = {init: 0}
    markings = [init]
    flags: list[int] = []
    out: list[Edges] = []
    sinks = {UNSAFE: -1, VIOLATED: -1}
    i = 0
    while i < len(markings):
        if budget is not None and i & 0xFFF == 0:
            budget.check(len(markings))
        m = markings[i]
        i += 1
        if m < 0:
            flags.append(-m)
            out.append([])
            continue
        f = FINAL if final_always or (final and m & final == final) else 0
        if m & control:
            f |= BUSY
        for bit, seen in enumerate(observe):
            if m & seen:
                f |= OBSERVED << bit
        flags.append(f)
        edges: Edges = []
        out.append(edges)
        for act, pre, keep, produce, entry in trans:
            if m & pre != pre:
                continue
            sink = (VIOLATED if entry and f & BUSY else
                    UNSAFE if m & keep & produce else 0)
            if sink:
                if sinks[sink] < 0:
                    sinks[sink] = len(markings)
                    markings.append(-sink)
                edges.append((act, sinks[sink]))
                continue
            m2 = (m & keep) | produce
            n = number.get(m2)
            if n is None:
                n = number[m2] = len(markings)
                markings.append(m2)
                if n >= max_states:
                    raise TooLarge(f"component {comp.name} alone exceeded {max_states:,} states")
            edges.append((act, n))
    return Lts(0, flags, out, visible & frozenset(comp.transitions))
