"""Strongly connected components, for the reduction of ``compose.lts`` and the cycle
proviso of ``stubborn``."""

from __future__ import annotations

from collections.abc import Callable


def components(succ: list[list[int]], check: Callable[[], object] | None = None,
               ) -> tuple[list[int], int]:
    """Tarjan, iteratively: the strongly connected component of every node and their number;
    components are numbered in the order Tarjan closes them, successors first. ``check`` is
    called every 65,536 nodes closed (a budget's check, which may raise)."""
    n = len(succ)
    index = [-1] * n
    low = [0] * n
    comp = [-1] * n
    on_stack = [False] * n
    stack: list[int] = []
    counter = 0
    ncomp = 0
    for root in range(n):
        if index[root] >= 0:
            continue
        work: list[tuple[int, int]] = [(root, 0)]
        index[root] = low[root] = counter
        counter += 1
        stack.append(root)
        on_stack[root] = True
        while work:
            v, i = work[-1]
            edges = succ[v]
            advanced = False
            while i < len(edges):
                w = edges[i]
                i += 1
                if index[w] < 0:
                    work[-1] = (v, i)
                    index[w] = low[w] = counter
                    counter += 1
                    stack.append(w)
                    on_stack[w] = True
                    work.append((w, 0))
                    advanced = True
                    break
                if on_stack[w] and index[w] < low[v]:
                    low[v] = index[w]
            if advanced:
                continue
            work.pop()
            if work:
                u = work[-1][0]
                if low[v] < low[u]:
                    low[u] = low[v]
            if check is not None and v & 0xFFFF == 0:
                check()
            if low[v] == index[v]:
                while True:
                    w = stack.pop()
                    on_stack[w] = False
                    comp[w] = ncomp
                    if w == v:
                        break
                ncomp += 1
    return comp, ncomp
