"""Parallel composition of two LTSs that synchronise on their shared visible actions.

An action in both alphabets fires in both at once; any other action (and every silent step)
moves one side only. This is exactly how two parts of a Petri net that share places behave:
a transition touching both parts is enabled when it is enabled in each. Flags combine as
``FINAL`` in both, every other flag (``UNSAFE``, ``VIOLATED``, ``BUSY``, observations) in
either; an unsafe or violated state is a sink. ``hidden`` actions
become silent in the result (all their participants are inside it).
"""

from __future__ import annotations

from rssm_dsl.verify.budget import Budget
from rssm_dsl.verify.compose.lts import FINAL, SINK, TAU, Edges, Lts


class TooLarge(Exception):
    """The product exceeded the state budget."""


def product(a: Lts, b: Lts, hidden: frozenset[int], max_states: int,
            budget: Budget | None = None) -> Lts:
    """The reachable part of ``a || b`` with ``hidden`` made silent (the budget checked
    every 4,096 states)."""
    sync = a.alphabet & b.alphabet
    nb = b.size
    # b's synchronising edges indexed by state and action
    b_sync: list[dict[int, list[int]]] = []
    b_free: list[Edges] = []
    for b_edges in b.out:
        table: dict[int, list[int]] = {}
        free: Edges = []
        for act, d in b_edges:
            if act in sync:
                table.setdefault(act, []).append(d)
            else:
                free.append((act, d))
        b_sync.append(table)
        b_free.append(free)

    def rename(act: int) -> int:
        return TAU if act == TAU or act in hidden else act

    names = {act: rename(act) for act in a.alphabet | b.alphabet}
    names[TAU] = TAU
    start = a.init * nb + b.init
    number = {start: 0}
    pairs = [start]
    flags: list[int] = []
    out: list[Edges] = []
    aflags, bflags, aout = a.flags, b.flags, a.out
    i = 0
    while i < len(pairs):
        if budget is not None and i & 0xFFF == 0:
            budget.check(len(pairs))
        key = pairs[i]
        i += 1
        ia, ib = divmod(key, nb)
        fa, fb = aflags[ia], bflags[ib]
        f = (fa & fb & FINAL) | ((fa | fb) & ~FINAL)
        flags.append(f)
        edges: Edges = []
        out.append(edges)
        if f & SINK:
            continue
        targets: list[tuple[int, int]] = []
        table = b_sync[ib]
        for act, da in aout[ia]:
            if act in sync:
                for db in table.get(act, ()):
                    targets.append((act, da * nb + db))
            else:
                targets.append((act, da * nb + ib))
        base = ia * nb
        for act, db in b_free[ib]:
            targets.append((act, base + db))
        for act, t in targets:
            n = number.get(t)
            if n is None:
                n = number[t] = len(pairs)
                pairs.append(t)
                if n >= max_states:
                    raise TooLarge(f"a composition exceeded {max_states:,} states")
            edges.append((names[act], n))
    return Lts(0, flags, out, (a.alphabet | b.alphabet) - hidden)
