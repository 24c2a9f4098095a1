"""Random small nets for the property tests, and a reference explorer built on the core rule.

Two families: *random* nets (any pre- and post-sets over a few places: many are unsafe, some
dead, some with test arcs and source transitions) and *safe* nets (components that each hold
one token, transitions moving it within one or two components at once, so forks, joins and
test arcs occur but no place ever gets a second token). The few places used are spread over up
to 200 place indices, so bitsets of several 64-bit words are exercised too.
"""

from __future__ import annotations

from dataclasses import dataclass, field

from hypothesis import strategies as st

from rssm_core.firing import Marking, Net
from rssm_dsl.hpn.flat import FlatNet, FlatPlace, FlatTransition
from rssm_dsl.source import Span

SPAN = Span("random.rssm", 1, 1, 1, 1)


@dataclass(frozen=True)
class RandomNet:
    nplaces: int
    pool: tuple[int, ...]                    # the places that occur in arcs or markings
    pre: tuple[tuple[int, ...], ...]
    post: tuple[tuple[int, ...], ...]
    initial: Marking
    safe: bool                               # built safe by construction

    def rule(self) -> Net:
        return Net(self.pre, self.post, self.nplaces)

    def flat(self) -> FlatNet:
        places = tuple(FlatPlace(i, f"p{i}", f"p{i}", SPAN, (f"p{i}",))
                       for i in range(self.nplaces))
        transitions = tuple(FlatTransition(t, f"t{t}", f"t{t}", SPAN, a, b)
                            for t, (a, b) in enumerate(zip(self.pre, self.post, strict=True)))
        return FlatNet("random", places, transitions, self.initial, frozenset())


@st.composite
def _pool(draw: st.DrawFn, size: int) -> tuple[int, tuple[int, ...]]:
    nplaces = draw(st.sampled_from([size, size + 2, 64, 65, 130, 200]))
    pool = draw(st.lists(st.integers(0, nplaces - 1), min_size=size, max_size=size,
                         unique=True))
    return nplaces, tuple(sorted(pool))


@st.composite
def random_nets(draw: st.DrawFn) -> RandomNet:
    nplaces, pool = draw(_pool(draw(st.integers(1, 6))))
    nt = draw(st.integers(1, 7))
    arcs = st.lists(st.sampled_from(pool), max_size=3, unique=True).map(lambda x: tuple(sorted(x)))
    pre = tuple(draw(arcs) for _ in range(nt))
    post = tuple(draw(arcs) for _ in range(nt))
    initial = frozenset(draw(st.lists(st.sampled_from(pool), unique=True)))
    return RandomNet(nplaces, pool, pre, post, initial, safe=False)


@st.composite
def safe_nets(draw: st.DrawFn) -> RandomNet:
    ncomp = draw(st.integers(1, 3))
    sizes = [draw(st.integers(1, 3)) for _ in range(ncomp)]
    nplaces, pool = draw(_pool(sum(sizes)))
    comps: list[tuple[int, ...]] = []
    k = 0
    for n in sizes:
        comps.append(pool[k:k + n])
        k += n
    nt = draw(st.integers(1, 7))
    pre: list[tuple[int, ...]] = []
    post: list[tuple[int, ...]] = []
    for _ in range(nt):
        chosen = draw(st.lists(st.integers(0, ncomp - 1), min_size=1, max_size=2, unique=True))
        pre.append(tuple(sorted(draw(st.sampled_from(comps[c])) for c in chosen)))
        post.append(tuple(sorted(draw(st.sampled_from(comps[c])) for c in chosen)))
    initial = frozenset(draw(st.sampled_from(c)) for c in comps)
    return RandomNet(nplaces, pool, tuple(pre), tuple(post), initial, safe=True)


def nets() -> st.SearchStrategy[RandomNet]:
    return st.one_of(random_nets(), safe_nets())


def markings_of(net: RandomNet) -> st.SearchStrategy[Marking]:
    return st.lists(st.sampled_from(net.pool), unique=True).map(frozenset)


@dataclass
class Explored:
    """Breadth-first exploration by the core rule, stopped after the first BFS level in which
    some enabled firing is unsafe (as the verifier stops)."""

    states: set[Marking] = field(default_factory=set)
    edges: set[tuple[Marking, int, Marking]] = field(default_factory=set)
    dead: set[Marking] = field(default_factory=set)
    fired: set[int] = field(default_factory=set)
    unsafe_depth: int | None = None     # BFS depth of the first marking with an unsafe firing


def explore(rule: Net, initial: Marking) -> Explored:
    out = Explored(states={initial})
    frontier = [initial]
    depth = 0
    while frontier:
        nxt: list[Marking] = []
        for m in frontier:
            succ = rule.successors(m)
            if not succ:
                out.dead.add(m)
            for f in succ:
                out.fired.add(f.transition)
                if f.unsafe and out.unsafe_depth is None:
                    out.unsafe_depth = depth
                out.edges.add((m, f.transition, f.marking))
                if f.marking not in out.states:
                    out.states.add(f.marking)
                    nxt.append(f.marking)
        if out.unsafe_depth is not None:
            break
        frontier = nxt
        depth += 1
    return out


def mask(places: frozenset[int] | tuple[int, ...]) -> int:
    m = 0
    for p in places:
        m |= 1 << p
    return m
