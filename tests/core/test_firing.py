"""The firing rule of rssm_core.firing, case by case."""

from __future__ import annotations

import pytest

from rssm_core.firing import Firing, Net, NetError, NotEnabled, UnsafeFiring

# p0 -> t0 -> p1, p2 (fork); p1, p2 -> t1 -> p3 (join); p3 -> t2 -> p0 (loop);
# t3: test arc on p1 (p1 -> t3 -> p1, p4); t4: no input place (a source) -> p4
NET = Net([(0,), (1, 2), (3,), (1,), ()], [(1, 2), (3,), (0,), (1, 4), (4,)], 5)


def test_structure_is_derived_from_the_pre_and_post_sets() -> None:
    assert NET.ntransitions == 5 and NET.nplaces == 5
    assert NET.consumers == ((0,), (1, 3), (1,), (2,), ())
    assert NET.consume == ((0,), (1, 2), (3,), (), ())          # pre \ post
    assert NET.produce == ((1, 2), (3,), (0,), (4,), (4,))      # post \ pre
    assert NET.producers == ((2,), (0,), (0,), (1,), (3, 4))
    assert NET.sources == (4,)
    assert NET.conflict(1) == (1, 3) and NET.conflict(4) == (4,)
    assert NET.may_disable(1) == (1, 3) and NET.may_enable(0) == (1, 3)
    # arcs are kept sorted whatever the order given
    assert Net([(2, 0)], [(1,)], 3).pre == ((0, 2),)


def test_enabled_when_every_input_place_is_marked() -> None:
    assert NET.enabled(frozenset({0}), 0)
    assert not NET.enabled(frozenset({1}), 1)
    assert NET.missing(frozenset({1}), 1) == (2,)
    assert NET.enabled(frozenset({1, 2}), 1)
    assert NET.enabled(frozenset(), 4)              # no input place: always enabled
    assert NET.enabled_set(frozenset({1, 2})) == (1, 3, 4)
    assert NET.enabled_set(frozenset()) == (4,)
    assert not NET.is_dead(frozenset())
    assert Net([(0,)], [()], 1).is_dead(frozenset())


def test_firing_moves_the_tokens() -> None:
    f = NET.fire(frozenset({0}), 0)
    assert f == Firing(0, frozenset({1, 2}), ())
    assert f.safe
    assert NET.fire(frozenset({1, 2}), 1).marking == frozenset({3})
    assert NET.fire(frozenset({3}), 2).marking == frozenset({0})


def test_a_test_arc_needs_its_token_and_keeps_it() -> None:
    f = NET.fire(frozenset({1}), 3)
    assert f.marking == frozenset({1, 4}) and f.safe
    with pytest.raises(NotEnabled) as e:
        NET.fire(frozenset({4}), 3)
    assert e.value.transition == 3 and e.value.missing == (1,)


def test_a_second_token_is_reported_as_unsafe() -> None:
    # t0 fires with p1 already marked: p1 would hold two tokens
    f = NET.fire(frozenset({0, 1}), 0)
    assert f.unsafe == (1,) and not f.safe
    assert f.marking == frozenset({1, 2})           # a set: the second token is not counted
    assert NET.unsafe(frozenset({0, 1, 2}), 0) == (1, 2)
    # the source t4 is unsafe as soon as p4 is marked; t3's test arc on p1 is not unsafe
    assert NET.fire(frozenset({4}), 4).unsafe == (4,)
    assert NET.fire(frozenset({1}), 3).unsafe == ()
    assert NET.fire(frozenset({1, 4}), 3).unsafe == (4,)


def test_firing_a_disabled_transition_is_an_error() -> None:
    with pytest.raises(NotEnabled, match=r"transition 1 is not enabled: place\(s\) 1, 2"):
        NET.fire(frozenset(), 1)


def test_fire_in_place_updates_the_set() -> None:
    marked = {0, 1}
    assert NET.fire_in_place(marked, 0) == (1,)
    assert marked == {1, 2}
    with pytest.raises(NotEnabled):
        NET.fire_in_place(marked, 2)
    assert marked == {1, 2}                         # untouched by a refused firing


def test_successors_and_runs() -> None:
    succ = NET.successors(frozenset({1, 2}))
    assert [(f.transition, f.marking, f.unsafe) for f in succ] == [
        (1, frozenset({3}), ()), (3, frozenset({1, 2, 4}), ()), (4, frozenset({1, 2, 4}), ())]
    run = NET.run(frozenset({0}), [0, 1, 2, 0])
    assert [f.marking for f in run] == [frozenset({1, 2}), frozenset({3}), frozenset({0}),
                                        frozenset({1, 2})]
    with pytest.raises(NotEnabled):
        NET.run(frozenset({0}), [0, 2])


def test_bad_structures_are_refused() -> None:
    with pytest.raises(NetError, match="transition 0: pre-set place 3"):
        Net([(3,)], [()], 3)
    with pytest.raises(NetError, match="transition 1: post-set place -1"):
        Net([(), ()], [(), (-1,)], 3)
    with pytest.raises(NetError, match="twice"):
        Net([(1, 1)], [()], 3)
    with pytest.raises(NetError, match="2 pre-sets but 1 post-sets"):
        Net([(), ()], [()], 3)
    assert isinstance(NetError(0, "x"), ValueError)


def test_unsafe_firing_keeps_the_interpreters_interface() -> None:
    e = UnsafeFiring(3, 7)
    assert (e.transition, e.place, e.places) == (3, 7, (7,))
    assert "transition 3 would mark place 7 twice" in str(e)
