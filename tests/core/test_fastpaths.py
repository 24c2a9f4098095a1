"""The fast paths of the backends follow the one firing rule (rssm_core.firing).

On random small nets, safe and unsafe (tests/core/nets.py), each fast path is run next to the
core rule and compared: markings, enabled sets, missing-token counts, successor sets and unsafe
reports. Fast paths: the interpreter's token game (``TokenGame.fire``, ``run_free``) and its
compiled firing code (one function per transition, and macro steps), the verifier's bitmasks
(``NetBits``), its vectorised kernel and breadth-first search (``explore_full``) and the
stubborn-set search with and without reduction.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
import pytest
from hypothesis import HealthCheck, find, given, settings
from hypothesis import strategies as st

from rssm_core.firing import Marking, Net
from rssm_dsl.interp.codegen import FiringCode, exclusive_places
from rssm_dsl.interp.engine import TokenGame, UnsafeFiring
from rssm_dsl.verify.netbits import NetBits, bits, from_words, to_mask, to_words
from rssm_dsl.verify.statespace import _Kernel, explore_full
from rssm_dsl.verify.stubborn import explore_reduced
from tests.core.nets import RandomNet, explore, markings_of, mask, nets

PROPERTY = settings(max_examples=150, deadline=None,
                    suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large])
STEPS = 12


class Unsafe(Exception):
    def __init__(self, t: int | str, p: int) -> None:
        super().__init__(t, p)
        self.t, self.p = int(t), p


def _raise_unsafe(t: int, p: int) -> None:
    raise Unsafe(t, p)


def _no_failure(p: int, e: Exception) -> None:
    raise AssertionError(f"no operation runs here ({p}: {e})")


def _check_game(game: TokenGame, rule: Net, marking: Marking, eager: bytearray) -> None:
    """The token array, the missing-token counts and the enabled set say ``marking``."""
    assert game.marking() == marking
    assert game.missing == [len(rule.missing(marking, u)) for u in range(rule.ntransitions)]
    assert game.enabled == {u for u in rule.enabled_set(marking) if not eager[u]}


def _code(game: TokenGame, rule: Net, eager: bytearray, local: list[int],
          macros: bool) -> FiringCode:
    n = rule.ntransitions
    none: list[Callable[[], None] | None] = [None] * n
    return FiringCode(game, [None] * rule.nplaces, none, [None] * n, [None] * n, eager, local,
                      {}, _no_failure, _raise_unsafe, macros)


# ---------------------------------------------------------------- the interpreter


@PROPERTY
@given(nets(), st.data())
def test_token_game_fire_is_the_rule(net: RandomNet, data: st.DataObject) -> None:
    rule, game = net.rule(), TokenGame(net.flat())
    assert game.pre == list(rule.pre) and game.post == list(rule.post)
    marking = net.initial
    none = bytearray(rule.ntransitions)
    _check_game(game, rule, marking, none)
    for _ in range(STEPS):
        enabled = rule.enabled_set(marking)
        if not enabled:
            break
        t = data.draw(st.sampled_from(enabled))
        expected = rule.fire(marking, t)
        if expected.unsafe:
            with pytest.raises(UnsafeFiring) as e:
                game.fire(t)
            assert (e.value.transition, e.value.place) == (t, expected.unsafe[0])
            return
        game.fire(t)
        marking = expected.marking
        _check_game(game, rule, marking, none)


@PROPERTY
@given(nets(), st.integers(0, 2**32))
def test_token_game_free_run_takes_successors_of_the_rule(net: RandomNet, seed: int) -> None:
    rule, game = net.rule(), TokenGame(net.flat())
    marking = net.initial
    none = bytearray(rule.ntransitions)
    for k in range(STEPS):
        successors = rule.successors(marking)
        if not successors:
            assert game.run_free(1, seed + k) == 0
            break
        try:
            assert game.run_free(1, seed + k) == 1
        except UnsafeFiring as e:
            assert e.place == rule.unsafe(marking, e.transition)[0]
            assert rule.enabled(marking, e.transition)
            return
        marking = game.marking()
        assert marking in {f.marking for f in successors if f.safe}
        _check_game(game, rule, marking, none)


@PROPERTY
@given(nets(), st.data())
def test_compiled_firing_code_is_the_rule(net: RandomNet, data: st.DataObject) -> None:
    """fire[t]() of codegen: same tokens, counts and enabled set; the eager (local) steps made
    enabled by a firing are the ones pushed on the stack of local steps; unsafe at the same
    place."""
    rule, game = net.rule(), TokenGame(net.flat())
    n = rule.ntransitions
    eager = bytearray(data.draw(st.lists(st.booleans(), min_size=n, max_size=n)))
    local: list[int] = []
    code = _code(game, rule, eager, local, macros=False)
    game.enabled.difference_update(u for u in range(n) if eager[u])   # as the scheduler does
    marking = net.initial
    _check_game(game, rule, marking, eager)
    for _ in range(STEPS):
        enabled = rule.enabled_set(marking)
        if not enabled:
            break
        t = data.draw(st.sampled_from(enabled))
        expected = rule.fire(marking, t)
        before = len(local)
        if expected.unsafe:
            with pytest.raises(Unsafe) as e:
                code.fire[t]()
            assert (e.value.t, e.value.p) == (t, expected.unsafe[0])
            return
        code.fire[t]()
        marking = expected.marking
        _check_game(game, rule, marking, eager)
        woken = {u for u in rule.enabled_set(marking)
                 if eager[u] and set(rule.pre[u]) & set(rule.post[t])}
        assert sorted(local[before:]) == sorted(woken)


@PROPERTY
@given(nets())
def test_exclusive_places_are_never_marked_together(net: RandomNet) -> None:
    """What the place invariants prove and the compiled firing code relies on (it leaves out
    the checks and counts they decide): in every marking reached by safe firings, no place is
    marked together with a place exclusive with it."""
    rule, exclusive = net.rule(), exclusive_places(net.flat())
    seen, frontier = {net.initial}, [net.initial]
    while frontier:
        marking = frontier.pop()
        for q in marking:
            assert not exclusive[q] & marking, (q, marking)
        for f in rule.successors(marking):
            if f.safe and f.marking not in seen:
                seen.add(f.marking)
                frontier.append(f.marking)


def _macro_outcomes(rule: Net, marking: Marking, t: int, length: int,
                    eager: bytearray) -> tuple[set[Marking], bool]:
    """By the rule: the markings reached by firing ``t`` and then ``length - 1`` more distinct
    eager transitions, and whether some such sequence makes an unsafe firing on the way."""
    ends: set[Marking] = set()
    unsafe = False

    def go(m: Marking, used: frozenset[int], left: int, step: int) -> None:
        nonlocal unsafe
        f = rule.fire(m, step)
        if f.unsafe:
            unsafe = True
            return
        if left == 0:
            ends.add(f.marking)
            return
        for u in rule.enabled_set(f.marking):
            if eager[u] and u not in used:
                go(f.marking, used | {u}, left - 1, u)

    go(marking, frozenset({t}), length - 1, t)
    return ends, unsafe


@PROPERTY
@given(nets(), st.data())
def test_compiled_macro_steps_are_firing_sequences_of_the_rule(net: RandomNet,
                                                               data: st.DataObject) -> None:
    """macro[t]() fires t and then local steps in one function: it must end in a marking the
    rule reaches by t and macro_len[t] - 1 eager firings, and report an unsafe firing only if
    such a sequence has one."""
    rule, game = net.rule(), TokenGame(net.flat())
    n = rule.ntransitions
    eager = bytearray(data.draw(st.lists(st.booleans(), min_size=n, max_size=n)))
    local: list[int] = []
    code = _code(game, rule, eager, local, macros=True)
    assert code.macros is not None
    game.enabled.difference_update(u for u in range(n) if eager[u])
    marking = net.initial
    for _ in range(STEPS // 2):
        enabled = rule.enabled_set(marking)
        if not enabled:
            break
        t = data.draw(st.sampled_from(enabled))
        ends, unsafe = _macro_outcomes(rule, marking, t, code.macro_len[t], eager)
        try:
            code.macros[t]()
        except Unsafe:
            assert unsafe
            return
        marking = game.marking()
        assert marking in ends
        _check_game(game, rule, marking, eager)
        assert all(eager[u] and rule.enabled(marking, u) for u in local)
        local.clear()


class _Unheld(FiringCode):
    """Macro steps that empty and mark every test-arc place (none left marked)."""

    def _macro(self, t: int) -> tuple[list[str], int]:
        return self._steps(t, ())


@PROPERTY
@given(nets(), st.data())
def test_macro_steps_leave_test_arcs_marked_only_where_it_cannot_be_seen(
        net: RandomNet, data: st.DataObject) -> None:
    """A macro step leaves a place it empties and marks again untouched only where nothing can
    tell: from the same markings, with operations (on some places) that record the token game
    when they run, it ends as the macro step that empties and marks it does (tokens, counts,
    enabled set, the stack of local steps in its order, the unsafe report) and its operations
    see the same."""
    rule = net.rule()
    n = rule.ntransitions
    eager = bytearray(data.draw(st.lists(st.booleans(), min_size=n, max_size=n)))
    observed = set(data.draw(st.lists(st.sampled_from(net.pool), max_size=2)))
    picks = data.draw(st.lists(st.integers(0, 1 << 16), min_size=STEPS // 2,
                               max_size=STEPS // 2))
    runs: list[list[object]] = []
    for kind in (FiringCode, _Unheld):
        game = TokenGame(net.flat())
        local: list[int] = []
        seen: list[object] = []

        def record(game: TokenGame = game, seen: list[object] = seen) -> None:
            seen.append((list(game.tokens), list(game.missing), set(game.enabled)))

        ops = [record if q in observed else None for q in range(rule.nplaces)]
        none: list[Callable[[], None] | None] = [None] * n
        code = kind(game, ops, none, [None] * n, [None] * n, eager, local, {}, _no_failure,
                    _raise_unsafe, True)
        assert code.macros is not None
        game.enabled.difference_update(u for u in range(n) if eager[u])
        for pick in picks:
            enabled = rule.enabled_set(game.marking())
            if not enabled:
                break
            try:
                code.macros[enabled[pick % len(enabled)]]()
            except Unsafe as e:
                seen.append(("unsafe", e.t, e.p))
                break
            seen.append((list(game.tokens), list(game.missing), set(game.enabled), list(local)))
            local.clear()
        runs.append(seen)
    assert runs[0] == runs[1]


# ---------------------------------------------------------------- the verifier


@PROPERTY
@given(nets().flatmap(lambda net: st.tuples(st.just(net), st.lists(markings_of(net),
                                                                    min_size=1, max_size=6))))
def test_bitmasks_and_the_vectorised_kernel_are_the_rule(
        case: tuple[RandomNet, list[Marking]]) -> None:
    net, markings = case
    rule, nb = net.rule(), NetBits.of(net.flat())
    assert nb.rule.pre == rule.pre and nb.rule.post == rule.post
    for t in range(nb.ntrans):         # built from the consumers' masks: the rule's sets
        assert bits(nb.conflict[t]) == list(rule.conflict(t))
        assert bits(nb.pre[t]) == list(rule.pre[t])
    for p in range(nb.nplaces):
        assert bits(nb.consumers[p]) == list(rule.consumers[p])
    kernel = _Kernel(nb)
    perm = [int(t) for t in kernel.perm]
    rows = np.array([to_words(mask(m), nb.nwords) for m in markings], dtype=np.uint64)
    en = kernel.enabled(rows)
    for s, m in enumerate(markings):
        enabled = rule.enabled_set(m)
        assert nb.enabled(mask(m)) == list(enabled)
        assert sorted(perm[j] for j in np.flatnonzero(en[s])) == list(enabled)
        for t in enabled:
            f = rule.fire(m, t)
            assert nb.fire(mask(m), t) == mask(f.marking)
            assert nb.unsafe_places(mask(m), t) == mask(f.unsafe)
    si, ti = np.nonzero(en)
    succ, clash = kernel.fire(rows, si, ti)
    for k in range(si.size):
        m, t = markings[int(si[k])], perm[int(ti[k])]
        f = rule.fire(m, t)
        assert frozenset(bits(from_words([int(x) for x in succ[k]]))) == f.marking
        assert (clash is not None and bool(clash[k])) == bool(f.unsafe)
        assert kernel.clash_places(rows[int(si[k])], int(ti[k])) == mask(f.unsafe)


@PROPERTY
@given(nets())
def test_vectorised_search_explores_what_the_rule_reaches(net: RandomNet) -> None:
    rule, nb = net.rule(), NetBits.of(net.flat())
    ref = explore(rule, net.initial)
    r = explore_full(nb, max_counterexamples=10**6)
    if net.safe:
        assert ref.unsafe_depth is None
    if ref.unsafe_depth is None:
        assert r.unsafe is None and r.complete and r.graph is not None
        g = r.graph
        states = [frozenset(bits(g.marking(s))) for s in range(g.size)]
        assert len(states) == len(set(states)) and set(states) == ref.states
        assert {(states[int(a)], int(t), states[int(b)])
                for a, t, b in zip(g.src, g.trans, g.dst, strict=True)} == ref.edges
        assert r.edges == len(ref.edges)
        assert {frozenset(bits(d.marking)) for d in r.deadlocks} == ref.dead
        assert r.deadlock_count == len(ref.dead)
        assert r.fired == frozenset(ref.fired)
        assert r.ever_marked == mask(frozenset().union(*ref.states))
        for s in range(g.size):     # BFS tree paths are firing sequences of the rule
            reached = rule.run(net.initial, g.path(s))
            assert (reached[-1].marking if reached else net.initial) == states[s]
    else:
        assert r.unsafe is not None and not r.complete
        *prefix, last = r.unsafe.steps
        assert len(r.unsafe.steps) == ref.unsafe_depth + 1       # a shortest one
        run = rule.run(net.initial, prefix)
        assert all(f.safe for f in run)
        m = run[-1].marking if run else net.initial
        assert r.unsafe.marking == mask(m) and r.unsafe.transition == last
        assert r.unsafe.places == mask(rule.fire(m, last).unsafe) != 0


@PROPERTY
@given(nets(), st.booleans())
def test_stubborn_search_agrees_with_the_rule(net: RandomNet, reduce: bool) -> None:
    rule, nb = net.rule(), NetBits.of(net.flat())
    ref = explore(rule, net.initial)
    r = explore_reduced(nb, reduce=reduce, max_counterexamples=10**6)
    assert (r.unsafe is None) == (ref.unsafe_depth is None)
    if r.unsafe is None:
        assert {frozenset(bits(d.marking)) for d in r.deadlocks} == ref.dead
        if not reduce:
            assert r.states == len(ref.states)
    else:
        firings = rule.run(net.initial, r.unsafe.steps)
        assert all(f.safe for f in firings[:-1]) and not firings[-1].safe


@pytest.mark.parametrize("what", ["unsafe", "dead", "test arc", "source", "words"])
def test_the_random_nets_contain_the_cases_that_matter(what: str) -> None:
    """The generator reaches unsafe firings, deadlocks, test arcs, transitions without input
    places and markings of several 64-bit words (else the properties above prove little)."""
    def wanted(net: RandomNet) -> bool:
        rule = net.rule()
        return {
            "unsafe": lambda: explore(rule, net.initial).unsafe_depth is not None,
            "dead": lambda: bool(explore(rule, net.initial).dead),
            "test arc": lambda: any(set(a) & set(b) for a, b in zip(rule.pre, rule.post,
                                                                    strict=True)),
            "source": lambda: bool(rule.sources),
            "words": lambda: NetBits.of(net.flat()).nwords > 1 and max(net.pool) >= 64,
        }[what]()

    found = find(nets(), wanted, settings=settings(max_examples=2000, deadline=None,
                                                   database=None))
    assert wanted(found)


@given(st.sets(st.integers(min_value=0, max_value=5000), max_size=300))
def test_a_mask_has_exactly_the_bits_given(indices: set[int]) -> None:
    """Short lists are OR-ed bit by bit, long ones set in a byte array: the same mask."""
    for form in (sorted(indices), tuple(indices), frozenset(indices)):
        mask = to_mask(form)
        assert bits(mask) == sorted(indices)
