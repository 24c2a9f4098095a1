"""The verifier's state space of a specification's flat net (the full breadth-first
exploration of rssm_dsl.verify, with its reachability graph, of the net the verifier explores:
the flat net with new(x) in its places, rssm_dsl.verify.datanet), and reachability questions
over it: about markings, about firings (edges), and about firing sequences (a small monitor
run along every path: the product of the graph with the monitor)."""

from __future__ import annotations

from collections.abc import Callable, Iterable
from dataclasses import dataclass
from pathlib import Path

from rssm_dsl.hpn.flat import FlatNet
from rssm_dsl.pipeline import Compilation
from rssm_dsl.verify import VerifyOptions, VerifyReport, verify
from rssm_dsl.verify.datanet import track_new
from rssm_dsl.verify.netbits import NetBits
from rssm_dsl.verify.statespace import explore_full
from tests.semantics.netview import compile_spec, flat_net

Monitor = Callable[[int, int], int | None]   # (monitor state, transition) -> next, None: bad


@dataclass
class StateSpace:
    comp: Compilation
    net: FlatNet
    markings: list[int]                  # bit p set: place p marked; 0 is the initial state
    edges: list[tuple[int, int, int]]    # (source state, transition, target state)

    def marked(self, state: int, place: int) -> bool:
        return bool(self.markings[state] >> place & 1)

    def any_marked(self, state: int, places: Iterable[int]) -> bool:
        return any(self.marked(state, p) for p in places)

    def enabled(self, state: int, t: int) -> bool:
        return all(self.marked(state, p) for p in self.net.transitions[t].pre)

    def states_where(self, pred: Callable[[int], bool]) -> list[int]:
        return [s for s in range(len(self.markings)) if pred(s)]

    def firings(self, transitions: Iterable[int]) -> list[tuple[int, int, int]]:
        ts = set(transitions)
        return [e for e in self.edges if e[1] in ts]

    def bad_paths(self, monitor: Monitor, start: int = 0) -> list[tuple[int, int, int]]:
        """Edges (state, monitor state, transition) of the product with ``monitor`` at which
        it rejects the firing: empty when every firing sequence of the net is accepted."""
        out = {s: [] for s in range(len(self.markings))}  # type: dict[int, list[tuple[int, int]]]
        for src, t, dst in self.edges:
            out[src].append((t, dst))
        seen = {(0, start)}
        todo = [(0, start)]
        bad: list[tuple[int, int, int]] = []
        while todo:
            s, q = todo.pop()
            for t, dst in out[s]:
                q2 = monitor(q, t)
                if q2 is None:
                    bad.append((s, q, t))
                    continue
                if (dst, q2) not in seen:
                    seen.add((dst, q2))
                    todo.append((dst, q2))
        return bad


def state_space(path: Path, max_states: int = 2_000_000) -> StateSpace:
    comp = compile_spec(path)
    net = track_new(flat_net(comp)).net
    result = explore_full(NetBits.of(net), max_states=max_states)
    assert result.complete and result.graph is not None, result.stopped
    g = result.graph
    markings = [g.marking(s) for s in range(g.size)]
    edges = list(zip(g.src.tolist(), g.trans.tolist(), g.dst.tolist(), strict=True))
    return StateSpace(comp, net, markings, edges)


def verdict(space: StateSpace) -> VerifyReport:
    """The verifier's own verdict on the same net (full exploration)."""
    return verify(space.net, VerifyOptions(reduction="off", time_limit=120.0))
