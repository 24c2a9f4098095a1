"""The properties stated in the spec (`property NAME: always P`, `property NAME: whenever P
eventually Q`; docs/language.md, "Properties"), checked on the reachable states.

Where: the slice (slicing.py) of the subsystems a property mentions, what they wait on
(``property_subsystems``: the producers they receive from blocking and the consumers they
send to blocking, and so on) and the producers of the values the property and the
conditions of those subsystems read, grown to a fixpoint (for a response property also the
producers that can end); the whole net when that is all of it. new(x) (of the inputs the
slice's environment feeds too: ``slice_net(env_new=True)``) and the values the property and
the conditions read are tracked (datanet.py, valuenet.py). The border channels whose value
nothing there reads are dropped (``slice_net(quiet=...)``).
Nothing in the slice waits on anything outside it, so the slice can do all its subsystems
can do in the whole net, and their moves replay in the whole net with the rest standing
still (the argument the progress check rests on): a property of those subsystems holds in
the whole net when it holds in the slice; a violation found in the slice is replayed in the
whole net before it is reported. With values tracked, the slice's environment fills its free
channels with any value, which the replay of tokens does not check: such a violation is
checked again on the whole net (``_check_batch``), whose verdict is reported. A limit of the
run reached while a property is judged leaves it (and those after it) not decided.

What: the states of the slice are explored once for all the properties on it, by the engine
``reduction`` names (the one the deadlock check uses): "off", the full breadth-first search of
statespace.py (markings as rows of 64-bit words, a whole level fired at once in numpy);
"on", stubborn sets (stubborn.py) in which every transition that can change an atom of one of
the properties is *visible* (a set holding an enabled visible transition holds them all), with
the cycle proviso (every cycle of the reduced graph has a fully expanded marking); "auto" and
"compositional" (which checks no properties itself), the full search up to
``AUTO_FULL_STATES`` markings, then stubborn sets. Each property's atoms are read from every
state explored, all states at once: `SUB in BEH` is true when a place of BEH's page of SUB is
marked, `SUB.NAME` is the value whose place is marked. The expression itself is evaluated by
:class:`rssm_dsl.semantics.properties.Formula` (the interpreter's compiled code), once per
distinct combination of atom values.

* `always P` is violated by a reachable state where P is false; the counterexample is the
  shortest firing sequence to it (in the graph explored).
* `whenever P eventually Q` is read as the progress check reads "completes another
  iteration" (report.PROGRESS_ASSUMPTION, strong fairness): it is violated by a reachable
  state where P holds and from which no continuation reaches a state where Q holds; the
  counterexample is a lasso: the firing sequence to it, on to a terminal component of what
  it can reach, and a cycle there (none when that is a deadlock), Q false all along.

Why the stubborn graph decides both (D1, D2, V and the proviso; stubborn.py): from every
explored state, a firing sequence of the full graph to a state with given atom values has a
counterpart in the reduced graph (its first stubborn transition moved to the front, or an
invisible key transition fired first, which changes no atom; the proviso bounds how often).
So the reduced graph reaches every combination of the atoms the full one does (`always`),
and a state of it reaches Q in the reduced graph iff it does in the full one; a reachable
P-state that cannot reach Q has an explored counterpart (the same argument, the transitions
added to it invisible and "cannot reach Q" kept by any firing), so `whenever` is decided
exactly too.

A state where the property reads a value the verifier does not track (a float...) leaves the
property undecided there: it is reported as not decided, never as holding.
"""

from __future__ import annotations

import dataclasses
import itertools
from collections.abc import Sequence
from typing import Any

import numpy as np

from rssm_core.records import dataclass
from rssm_dsl.hpn.flat import FlatNet, FlatTransition, Role
from rssm_dsl.semantics.model import Property, System
from rssm_dsl.semantics.properties import Formula, InBehaviour, UnknownValue, Value
from rssm_dsl.verify.budget import Budget, LimitReached
from rssm_dsl.verify.cover import one_token_semiflows
from rssm_dsl.verify.datanet import TrackedNet, track_new
from rssm_dsl.verify.dataplan import ValuePlan
from rssm_dsl.verify.netbits import NetBits
from rssm_dsl.verify.progress import (
    backward_closure,
    live_places,
    shortest_path,
    terminal_component,
)
from rssm_dsl.verify.report import Counterexample, PropertyResult, marking_labels
from rssm_dsl.verify.slicing import (
    Channel,
    ReplayError,
    Slice,
    channels,
    fire_steps,
    replay_group,
    run_outside,
    slice_net,
    wait_closure,
)
from rssm_dsl.verify.statespace import Graph, SearchResult, explore_full
from rssm_dsl.verify.stubborn import explore_reduced
from rssm_dsl.verify.valuenet import track_values, tracked_labels


def check_properties(net: FlatNet, system: System, plan: ValuePlan | None,
                     budget: Budget, max_states: int, reduction: str = "auto",
                     sliced: bool = True) -> tuple[PropertyResult, ...]:
    """Every property of ``system`` checked on ``net`` (the module docstring), on the
    slice of what its subsystems wait on (``sliced``) or on the whole net. The properties
    on the same slice share one exploration (the engine ``reduction`` names: "off" full,
    "on" stubborn sets, "auto" and "compositional" full then stubborn sets)."""
    batches: dict[tuple[str, ...], list[tuple[Property, list[Formula]]]] = {}
    small: dict[tuple[str, ...], list[tuple[Property, list[Formula]]]] = {}
    for prop in system.properties:
        formulas = [Formula(system, e) for e in prop.expressions]
        keep = (property_subsystems(net, prop, formulas, plan) if sliced
                else tuple(net.subsystems))
        batches.setdefault(keep, []).append((prop, formulas))
        if sliced and prop.kind == "always":
            mine = wait_closure(net, {a.subsystem_id for f in formulas for a in f.atoms})
            if len(mine) < len(keep):
                small.setdefault(mine, []).append((prop, formulas))
    results: dict[str, PropertyResult] = {}
    if small:
        _first_on_less(net, small, plan, budget, max_states, reduction, results)
    # the smallest slices first: a property whose slice is the whole net does not spend
    # the time of those decided on a few subsystems
    for keep, whole_batch in sorted(batches.items(), key=lambda kv: len(kv[0])):
        batch = [(p, fs) for p, fs in whole_batch if p.name not in results]
        if not batch:
            continue
        if budget.stop is not None:
            for prop, _ in batch:
                results[prop.name] = PropertyResult(
                    prop.name, prop.kind, _text(prop), None, None,
                    f"not checked: {budget.stop.message}", prop.span)
            continue
        try:
            _check_batch(net, batch, keep, plan, budget, max_states, reduction, results)
        except LimitReached as e:     # a limit in a closure or a lasso: what is left of
            for prop, _ in batch:     # the batch is not decided (the report's stop says why)
                if prop.name not in results:
                    results[prop.name] = PropertyResult(
                        prop.name, prop.kind, _text(prop), None, None,
                        f"not decided: {e.stop.message}", prop.span)
    return tuple(results[p.name] for p in system.properties)


def _first_on_less(net: FlatNet, small: dict[tuple[str, ...], list[tuple[Property,
                                                                      list[Formula]]]],
                   plan: ValuePlan | None, budget: Budget, max_states: int, reduction: str,
                   results: dict[str, PropertyResult]) -> None:
    """`always` properties first on the slice of what their subsystems wait on alone,
    without the producers of the values they track (``small``: per slice, its
    properties): the environment sends any value there, so what holds there holds in the
    whole net, and a violation counts once its path, replayed in the whole net with the
    values tracked, shows it (``_confirm_with_values``). What that leaves open goes on to
    the slice with those producers. Each slice gets at most ``LESS_SECONDS`` (a share)."""
    for keep, batch in small.items():
        left = budget.run_remaining()
        cap = min(LESS_SECONDS, left / 4) if left is not None else LESS_SECONDS
        try:
            with budget.capped(cap) as tried:
                ex = _explore(net, keep, [f for _, fs in batch for f in fs], plan, budget,
                              max_states, reduction)
                found = {p.name: _judge(net, p, fs, ex, budget) for p, fs in batch}
        except LimitReached:
            continue
        if tried.hit or budget.stop is not None:
            continue
        for prop, formulas in batch:
            r = found[prop.name]
            if r.holds is True:
                results[prop.name] = r
            elif r.holds is False and ex.slice is not None:
                cx = (_confirm_with_values(net, ex.slice, plan, budget, prop, formulas,
                                           r.counterexample) if plan is not None
                      else r.counterexample)
                if cx is not None:
                    results[prop.name] = dataclasses.replace(r, counterexample=cx)


LESS_SECONDS = 10.0     # at most, of the run's time: an `always` on its smaller slice first


def not_decided(system: System, why: str) -> tuple[PropertyResult, ...]:
    """Every property of ``system``, not decided for the reason ``why`` (a run stopped
    before they were checked)."""
    return tuple(PropertyResult(p.name, p.kind, _text(p), None, None, f"not decided: {why}",
                                p.span) for p in system.properties)


def _check_batch(net: FlatNet, batch: list[tuple[Property, list[Formula]]],
                 keep: tuple[str, ...], plan: ValuePlan | None, budget: Budget,
                 max_states: int, reduction: str, results: dict[str, PropertyResult]) -> None:
    """The properties of ``batch`` (all on the slice of ``keep``) into ``results``.

    A violation found on a slice whose environment writes values (``plan``: values are
    tracked) is not reported on the slice's word: the environment of a free channel may
    have written a value the whole net never sends. Those properties are checked again on
    the whole net, whose verdict (with its own counterexample) is the one reported; not
    decided when the whole net is not explored to the end."""
    ex = _explore(net, keep, [f for _, fs in batch for f in fs], plan, budget,
                  max_states, reduction)
    paths: dict[str, tuple[list[int], list[int]]] = {}
    found = {prop.name: _judge(net, prop, formulas, ex, budget, paths)
             for prop, formulas in batch}
    again = [(prop, fs) for prop, fs in batch
             if ex.slice is not None and plan is not None and found[prop.name].holds is False]
    # a response property that holds on a slice fed from outside is not taken on the
    # slice's word either: the environment may write a value that leads to Q which the whole
    # net never sends (a value the whole net tracks), and a way to Q the whole net lacks
    # makes a violation disappear
    held = [(prop, fs) for prop, fs in batch
            if prop.kind == "response" and found[prop.name].holds is True]
    if held and ex.slice is not None and plan is not None and _fed_values(net, ex.slice, plan,
                                                                          held):
        again += held
    if again and ex.slice is not None and plan is not None:
        # first the slice's own path, replayed in the whole net with the values tracked
        for prop, formulas in list(again):
            if found[prop.name].holds is not False:
                continue
            if prop.kind == "always":
                cx = _confirm_with_values(net, ex.slice, plan, budget, prop, formulas,
                                          found[prop.name].counterexample)
            else:
                cx = _confirm_response_with_values(net, ex, plan, budget, prop,
                                                   formulas, *paths[prop.name])
            if cx is not None:
                found[prop.name] = dataclasses.replace(found[prop.name], counterexample=cx)
                again.remove((prop, formulas))
    if again:
        # a share of the run's time: inside a capped first try (the falsifier's) the try's
        # cap cuts it, and the caller, seeing its cap hit, tries again with the rest
        left = budget.run_remaining()
        cap = min(WHOLE_SECONDS, left / 3) if left is not None else WHOLE_SECONDS
        with budget.capped(cap):
            whole = _explore(net, tuple(net.subsystems), [f for _, fs in again for f in fs],
                             plan, budget, max_states, reduction)
        for prop, formulas in again:
            r = _judge(net, prop, formulas, whole, budget)
            if r.holds is None:
                word = "violated" if found[prop.name].holds is False else "holds"
                r = dataclasses.replace(r, why=f"not decided: {word} in {ex.where}, whose "
                                        f"environment may send values the whole net does "
                                        f"not, and in the whole net {r.why}")
            found[prop.name] = r
    results.update(found)


def property_subsystems(net: FlatNet, prop: Property, formulas: list[Formula],
                        plan: ValuePlan | None) -> tuple[str, ...]:
    """Where ``prop`` is checked: the subsystems it mentions, what they wait on
    (slicing.wait_closure), and the producers feeding them a value the verifier tracks for
    it (the slice's environment would write any value there) or, for a response property,
    a producer that can end (the environment never stops writing)."""
    mentioned = {a.subsystem_id for f in formulas for a in f.atoms}
    keys = frozenset(f"{a.subsystem_id}.{a.variable_name}" for f in formulas
                     for a in f.atoms if isinstance(a, Value))
    ends: dict[str, bool] = {}
    # the guards of the set decide which values it needs fed: grown to a fixpoint, so that
    # a coordinator reading every robot brings in only the robots whose values its guards
    # (and those of the robots already in) depend on
    keep: tuple[str, ...] = tuple(sorted(mentioned))
    while True:
        tracked = _tracked(net, plan, keys, keep)

        def feeds(c: Channel, tracked: frozenset[str] = tracked) -> bool:
            if f"channel {c.name}" in tracked:
                return True
            if prop.kind != "response" or c.producer is None:
                return False
            if c.producer not in ends:
                ends[c.producer] = _may_end(net, c.producer)
            return ends[c.producer]

        grown = wait_closure(net, mentioned, feeds)
        if set(grown) <= set(keep):
            return grown
        keep = tuple(sorted(set(keep) | set(grown)))


def _tracked(net: FlatNet, plan: ValuePlan | None, keys: frozenset[str],
             within: Sequence[str]) -> frozenset[str]:
    """The values (``channel NAME``, ``SUB.NAME``) tracked in ``net`` for the property
    values ``keys`` and the conditions of the subsystems ``within`` (valuenet.py)."""
    if plan is None:
        return frozenset()
    key = (id(net), id(plan), keys, tuple(within))
    hit = _TRACKED.get(key)
    if hit is None or hit[0] is not net:
        if len(_TRACKED) > 64:
            _TRACKED.clear()
        hit = _TRACKED[key] = (net, tracked_labels(track_new(net), plan, keys, within))
    return hit[1]


_TRACKED: dict[tuple[int, int, frozenset[str], tuple[str, ...]],
               tuple[FlatNet, frozenset[str]]] = {}


def _fed_values(net: FlatNet, sl: Slice, plan: ValuePlan,
                batch: list[tuple[Property, list[Formula]]]) -> bool:
    """Does a channel from outside ``sl`` into it carry a value the whole net tracks for
    these properties and the slice's conditions, or come from a producer that can end? The slice's environment writes
    any value there, at any time, the whole net only what its producer computes, while it
    runs."""
    inbound = [c for c in channels(net) if c.consumer in sl.keep and c.producer not in sl.keep]
    if not inbound:
        return False
    # a producer that can end stops writing for good, which the environment never does: the
    # slice may then keep a way to Q (fresh data) that the whole net has lost
    if any(c.producer is not None and _may_end(net, c.producer) for c in inbound):
        return True
    keys = frozenset(f"{a.subsystem_id}.{a.variable_name}" for _, fs in batch for f in fs
                     for a in f.atoms if isinstance(a, Value))
    # a value only the conditions outside the slice depend on changes nothing inside it
    tracked = _tracked(net, plan, keys, tuple(s for s in net.subsystems if s in sl.keep))
    return any(f"channel {c.name}" in tracked for c in inbound)


def _may_end(net: FlatNet, subsystem: str) -> bool:
    """Can ``subsystem`` switch to where no iteration of it follows (its end)?"""
    live = live_places(net, subsystem)
    return any(t.subsystem == subsystem and t.role is Role.SWITCH
               and any(net.places[p].subsystem == subsystem and not live >> p & 1
                       for p in t.post)
               for t in net.transitions)


WHOLE_SECONDS = 30.0     # at most, of the run's time: a slice's violation checked in the whole net
AUTO_FULL_STATES = 200_000      # "auto": the full search's share before the stubborn sets (as for deadlocks)


@dataclass
class _Explored:
    """A slice (or the whole net) explored for some properties."""

    tracked: TrackedNet               # the net explored, and its steps told back
    slice: Slice | None               # None: the whole net
    graph: Graph | None               # None: not decided (``why``)
    where: str
    why: str
    how: str = ""                     # the engine, its states per second


def _explore(net: FlatNet, keep: tuple[str, ...], formulas: list[Formula],
             plan: ValuePlan | None, budget: Budget, max_states: int,
             reduction: str = "auto") -> _Explored:
    atoms = [a for f in formulas for a in f.atoms]
    keys = frozenset(f"{a.subsystem_id}.{a.variable_name}" for a in atoms
                     if isinstance(a, Value))
    sl = None
    if set(keep) != set(net.subsystems) and keep:
        # the border's channels whose value nothing here reads are dropped (slice_net)
        read = _tracked(net, plan, keys, keep)
        quiet = [c.name for c in channels(net) if f"channel {c.name}" not in read]
        if plan is not None:
            # and what the slice itself reads of its free channels inside, kept whole: the
            # whole net's guards may read more than its transitions can track (a
            # dispatcher's transition function reading every robot's value), where the
            # slice's, with the rest left unknown, need only what decides them
            inside = [c.name for c in channels(net) if c.free and c.producer in keep
                      and c.consumer in keep and f"channel {c.name}" not in read]
            if inside:
                whole = slice_net(net, keep, quiet=quiet, uncut=inside, env_new=True)
                read = read | tracked_labels(track_new(whole.net), plan, keys, keep)
        sl = slice_net(net, keep, quiet=[c for c in quiet if f"channel {c}" not in read],
                       uncut=[c.name for c in channels(net) if f"channel {c.name}" in read],
                       env_new=True)
    base = sl.net if sl is not None else net
    tracked = track_values(track_new(base), plan, keys)
    nb = NetBits.of(tracked.net)
    where = "the whole net" if sl is None else f"the slice of {', '.join(keep)}"
    result: SearchResult | None = None
    if reduction != "on":        # the compact bit-matrix search (statespace.py)
        limit = max_states if reduction == "off" else min(max_states, AUTO_FULL_STATES)
        result = explore_full(nb, max_states=limit, keep_graph=True,
                              max_counterexamples=1, budget=budget)
        if reduction == "off" or result.complete or budget.stop is not None \
                or "state limit" not in (result.stopped or ""):
            return _explored(tracked, sl, result, where, reduction)
    # stubborn sets keeping every transition that can change an atom visible, with the
    # cycle proviso (stubborn.py): they keep both kinds of property (docs/verify.md)
    safe, flows = _flows(tracked.net, budget)
    reduced = explore_reduced(nb, safe_places=safe, max_states=max_states,
                              max_counterexamples=1, for_progress=True, budget=budget,
                              visible=visible_transitions(tracked.net, atoms),
                              semiflows=flows)
    return _explored(tracked, sl, reduced, where, reduction)


def _flows(net: FlatNet, budget: Budget) -> tuple[int, list[int]]:
    """The places one-token semiflows prove safe (they need no up-set), and the semiflows
    carrying one token (they give necessary enabling sets), as place masks."""
    safe = 0
    flows: list[int] = []
    for f in one_token_semiflows(net, range(len(net.places)),
                                 lambda: budget.poll() is not None):
        mask = 0
        for p in f.support:
            mask |= 1 << p
        safe |= mask
        if f.tokens == 1 and all(w == 1 for _, w in f.weights):
            flows.append(mask)
    return safe, flows


def _explored(tracked: TrackedNet, sl: Slice | None, result: SearchResult,
              where: str, reduction: str) -> _Explored:
    engine = "full exploration" if result.method == "full" else "stubborn sets"
    rate = result.states / result.seconds if result.seconds > 0 else 0.0
    how = f"{engine}, {rate:,.0f} states/s"
    if reduction == "compositional":
        how += "; the compositional check does not check properties"
    if not result.complete or result.graph is None:
        why = result.stopped or "the exploration stopped"
        return _Explored(tracked, sl, None, where,
                         f"not decided: {why} ({result.states:,} states of {where}; {how})",
                         how)
    return _Explored(tracked, sl, result.graph, where, "", how)


def _judge(net: FlatNet, prop: Property, formulas: list[Formula], ex: _Explored,
           budget: Budget, paths: dict[str, tuple[list[int], list[int]]] | None = None,
           ) -> PropertyResult:
    """The verdict of ``prop`` on what ``ex`` explored. A violation on a slice also leaves
    in ``paths`` its group's moves (the whole net's transitions): to the P-state, and on
    to the state from which Q is lost for good."""
    graph, tracked, where = ex.graph, ex.tracked, ex.where
    if graph is None:
        return PropertyResult(prop.name, prop.kind, _text(prop), None, None, ex.why,
                              prop.span)
    truth = [_truth(f, graph, tracked.net) for f in formulas]
    if prop.kind == "always":
        bad = ~truth[0][0]
        unknown = truth[0][1]
    else:
        # whenever P eventually Q is violated by a reachable P-state from which a path that
        # never meets Q leads to a state that can never reach Q again (a deadlock, the end
        # of the system, a part of the state space it never leaves): every run on from there
        # misses Q. Unknown values count for Q where that makes no violation.
        (p, pu), (q, qu) = truth
        never = ~backward_closure(graph, q | qu, budget=budget)
        bad_from = backward_closure(graph, never, ~q & ~qu, budget)
        hopeless = ~backward_closure(graph, q & ~qu, budget=budget)
        may_from = backward_closure(graph, hopeless, ~q & ~qu | qu, budget)
        bad = p & ~pu & bad_from
        unknown = (p | pu) & may_from & ~bad
    bad &= ~unknown
    states = f"{graph.size:,} states of {where}; {ex.how}"
    if bad.any():
        # the state shown: one where no subsystem whose values the property reads stands
        # inside its transition function, if there is one (``_settled``)
        settled = bad & _settled(graph, tracked, {a.subsystem_id for f in formulas
                                                  for a in f.atoms if isinstance(a, Value)})
        state = int(np.flatnonzero(settled if settled.any() else bad)[0])
        to_cycle: tuple[int, ...] = ()
        cycle: tuple[int, ...] = ()
        reach = 0                       # steps of to_cycle to the state Q is lost for good
        if prop.kind != "always":       # the lasso: on, Q never again
            to_never, x = shortest_path(graph, state, never, within=~q & ~qu)
            rest, cycle = _lasso(graph, x, budget)
            to_cycle, reach = (*to_never, *rest), len(to_never)
        if paths is not None and ex.slice is not None:
            tn = tracked.net.transitions
            paths[prop.name] = (
                ex.slice.whole_steps(tracked.steps(tn[t] for t in graph.path(state))),
                ex.slice.whole_steps(tracked.steps(tn[t] for t in to_cycle[:reach])))
        try:
            cx = _lift(net, ex.slice, tracked, graph.path(state), to_cycle, cycle, prop, reach)
        except ReplayError as e:
            return PropertyResult(prop.name, prop.kind, _text(prop), None, None,
                                  f"not decided: a violation found in {where} was not "
                                  f"reproduced in the whole net ({e})", prop.span)
        return PropertyResult(prop.name, prop.kind, _text(prop), False, cx,
                              f"violated ({states})", prop.span, graph.size)
    if unknown.any():
        missing = _untracked(formulas, tracked.net)
        what = (f"{', '.join(missing)}, which the verifier does not track there (docs/verify.md, "
                f"\"How values are tracked\")" if missing
                else "a value the verifier does not track")
        return PropertyResult(prop.name, prop.kind, _text(prop), None, None,
                              f"not decided: it reads {what}, unknown in "
                              f"{int(unknown.sum()):,} of {states}", prop.span, graph.size)
    return PropertyResult(prop.name, prop.kind, _text(prop), True, None, f"holds ({states})",
                          prop.span, graph.size)


def _confirm_with_values(net: FlatNet, sl: Slice, plan: ValuePlan, budget: Budget,
                         prop: Property, formulas: list[Formula],
                         cx: Counterexample | None) -> Counterexample | None:
    """An ``always`` property violated on a slice whose environment writes values: the
    slice's path replayed in the whole net with the values tracked (the lift of
    ``sliced._Whole``: the outside producers run until they have sent what the slice read),
    and the counterexample when the property is false in a state the replay reaches there;
    None when that does not show it (the whole net is then explored)."""
    from rssm_dsl.verify.sliced import _Whole

    if prop.kind != "always" or cx is None:
        return None
    whole = _Whole(net, plan, budget)
    if whole.net is None:
        return None
    try:
        ends = whole.replay(sl, [t.index for t in cx.steps])
    except (ReplayError, LimitReached):
        return None
    for node in ends:
        if _value_at(formulas[0], whole.net, node.marking) is False:
            return Counterexample("property", whole.steps(node.path()),
                                  marking_labels(net, whole.raw(node.marking)),
                                  subsystem=prop.name, values=whole.values(node.path()))
    return None


def _confirm_response_with_values(net: FlatNet, ex: _Explored, plan: ValuePlan,
                                  budget: Budget, prop: Property, formulas: list[Formula],
                                  prefix: Sequence[int], on: Sequence[int],
                                  ) -> Counterexample | None:
    """A `whenever P eventually Q` violated on a slice whose environment writes values: the
    slice's moves to the P-state and on to where Q is lost (``prefix``, ``on``) replayed in
    the whole net with the values tracked (as ``_confirm_with_values``). It is a violation
    of the whole net when, along the replay, P holds at a state after which Q never holds,
    and at its end Q can never hold again (``_lost_for_good``, ``_lost_in_slice``). The counterexample goes on
    with the rest of the system running (everyone in turn). None when that does not show
    it (the whole net is then explored)."""
    from rssm_dsl.verify.sliced import _Whole

    sl = ex.slice
    whole = _Whole(net, plan, budget)
    if whole.net is None or sl is None:
        return None
    try:
        ends = whole.replay(sl, [*prefix, *on])
    except (ReplayError, LimitReached):
        return None
    trigger, goal = formulas
    rule = whole.net.rule
    inside = _inside(net, {a.subsystem_id for f in formulas for a in f.atoms
                           if isinstance(a, Value)})
    for node in ends:
        end = whole.raw(node.marking)
        if not (_lost_for_good(net, whole.net, node.marking, end, goal)
                or _lost_in_slice(ex, whole.net, node.marking, goal, budget)):
            continue
        path = node.path()
        m = set(whole.net.initial)
        marks = [frozenset(m)]
        for u in path:
            m.difference_update(rule.consume[u])
            m.update(rule.produce[u])
            marks.append(frozenset(m))
        last_q = max((i for i, mk in enumerate(marks)
                      if _value_at(goal, whole.net, mk) is not False), default=-1)
        # the P-state where no subsystem whose values they read is inside its transition
        # function (``_settled``: the interpreter reads the same values there)
        at = next((i for i in range(last_q + 1, len(marks))
                   if _value_at(trigger, whole.net, marks[i]) is True
                   and not inside.intersection(whole.raw(marks[i]))), None)
        if at is None:
            continue
        # the rest of the system runs on, everyone in turn, with the values (a cycle of
        # the net without them may not be one of the system: a counter would overflow)
        try:
            tail, around, _ = run_outside(whole.net, node.marking, frozenset())
        except ReplayError:         # no cycle found soon: the lasso ends where Q is lost
            tail, around = [], []
        after = fire_steps(whole.net, node.marking, tail)
        return Counterexample(
            "property", whole.steps(path[:at]), marking_labels(net, whole.raw(marks[at])),
            subsystem=prop.name, to_cycle=whole.steps([*path[at:], *tail]),
            cycle=whole.steps(around),
            cycle_marking=marking_labels(net, whole.raw(after)) if around else (),
            values=whole.values([*path, *tail, *around]))
    return None


def _lost_in_slice(ex: _Explored, whole: FlatNet, marking: frozenset[int], goal: Formula,
                   budget: Budget) -> bool:
    """Can ``goal`` never hold again from ``marking`` (of the whole net with the values
    tracked, ``whole``)? The slice ``ex`` explored can do all its subsystems can do in the
    whole net, whatever the rest does (and with any value from outside), so it is so when
    the slice, started from the marking's counterpart (its places by name: the producer's
    copy of a cut channel as the channel), reaches no state where ``goal`` may hold. False
    when a place of the slice has no counterpart, the counterpart does not mark one value
    of each value the slice tracks, or the exploration is cut (``LOST_STATES``)."""
    net = ex.tracked.net
    named = {whole.places[p].name for p in marking}
    known = {p.name for p in whole.places}
    start: set[int] = set()
    for p in net.places:
        name = p.name.removesuffix("'")
        if name not in known:
            return False
        if name in named:
            start.add(p.index)
    per_value: dict[str, int] = {}
    for p in net.places:
        if (p.channel or "").startswith("value "):
            per_value[p.channel or ""] = per_value.get(p.channel or "", 0) + (p.index in start)
    if any(n != 1 for n in per_value.values()):
        return False
    from_there = dataclasses.replace(net, initial=frozenset(start))
    nb = NetBits.of(from_there)
    try:
        result = explore_full(nb, max_states=LOST_STATES, keep_graph=True,
                              max_counterexamples=0, budget=budget)
        if result.graph is None and "state limit" in (result.stopped or ""):
            # stubborn sets with the goal's atoms visible (they reach every combination
            # of the atoms the full search reaches, as for `always`)
            safe, flows = _flows(from_there, budget)
            result = explore_reduced(nb, safe_places=safe, max_states=LOST_STATES,
                                     max_counterexamples=0, for_progress=True, budget=budget,
                                     visible=visible_transitions(from_there, goal.atoms),
                                     semiflows=flows)
    except LimitReached:
        return False
    if not result.complete or result.graph is None:
        return False
    value, unknown = _truth(goal, result.graph, from_there)
    return not (value | unknown).any()


LOST_STATES = 200_000   # at most, from where a slice's response violation ends in the whole net


def _lost_for_good(net: FlatNet, tracked: FlatNet, marking: frozenset[int],
                   raw: frozenset[int], goal: Formula) -> bool:
    """Can ``goal`` never hold again from ``marking`` (of the whole net with the values
    tracked, ``tracked``)? Over-approximated: from the marking, every transition of the
    flat net that could fire with every place some firing could mark marked at once
    (``_could_fire``); a subsystem none of whose transitions is among them keeps its
    behaviour and its values, another one may be in any behaviour whose places could be
    marked, or in none. False when some such combination makes ``goal`` true, or it reads
    a value of a subsystem that may still move. ``raw``: ``marking`` as the flat net's."""
    markable, fire = _could_fire(net, raw)
    moving = {net.transitions[t].subsystem for t in fire}
    options: list[tuple[bool, ...]] = []
    for a in goal.atoms:
        if isinstance(a, Value):
            if a.subsystem_id in moving:
                return False
            continue
        now = any(p.index in raw for p in net.places
                  if p.subsystem == a.subsystem_id and p.behaviour == a.behaviour)
        if a.subsystem_id not in moving:
            options.append((now,))
        else:
            options.append((False, True) if any(
                p.index in markable for p in net.places
                if p.subsystem == a.subsystem_id and p.behaviour == a.behaviour) else (False,))
    if sum(len(o) > 1 for o in options) > 12:
        return False
    ins = [a for a in goal.atoms if isinstance(a, InBehaviour)]
    for combo in itertools.product(*options):
        chosen = {(a.subsystem_id, a.behaviour): v for a, v in zip(ins, combo, strict=True)}
        if _value_at(goal, tracked, marking, chosen) is not False:
            return False
    return True


def _could_fire(net: FlatNet, marking: frozenset[int]) -> tuple[set[int], set[int]]:
    """The places some firing sequence from ``marking`` could mark and the transitions that
    could fire, over-approximated: every place once marked is taken as marked for good."""
    marked = set(marking)
    fired: set[int] = set()
    consumers: dict[int, list[FlatTransition]] = {}
    for t in net.transitions:
        for p in t.pre:
            consumers.setdefault(p, []).append(t)
    todo = [t for t in net.transitions if marked.issuperset(t.pre)]
    while todo:
        t = todo.pop()
        if t.index in fired:
            continue
        fired.add(t.index)
        for p in t.post:
            if p not in marked:
                marked.add(p)
                todo.extend(u for u in consumers.get(p, ()) if u.index not in fired
                            and marked.issuperset(u.pre))
    return marked, fired


def _value_at(f: Formula, net: FlatNet, marking: frozenset[int],
              ins: dict[tuple[str, str], bool] | None = None) -> bool | None:
    """The formula in one marking of a net with the values tracked (as ``_truth`` reads the
    states of a graph); ``ins``: `SUB in BEH` atoms given other values."""
    row: list[int] = []
    getters: list[Any] = []
    for a in f.atoms:
        if isinstance(a, InBehaviour):
            given = ins.get((a.subsystem_id, a.behaviour)) if ins is not None else None
            row.append(int(given) if given is not None else int(any(
                p.index in marking for p in net.places
                if p.subsystem == a.subsystem_id and p.behaviour == a.behaviour)))
            getters.append(("in", a))
        else:
            key = f"value {a.subsystem_id}.{a.variable_name}"
            vals = [(p.index, p.label.rpartition(" = ")[2]) for p in net.places
                    if p.channel == key]
            row.append(next((i for i, (place, _) in enumerate(vals) if place in marking), -1))
            getters.append(("value", a, _domain_of(a, [v for _, v in vals])))
    return _evaluate(f, tuple(row), getters)


def _lasso(graph: Graph, state: int, budget: Budget) -> tuple[tuple[int, ...],
                                                              tuple[int, ...]]:
    """From a state that cannot reach the goal: a path to a terminal component and a cycle
    in it (none when the component is a deadlock). Every state reachable from ``state``
    misses the goal, so the run repeats the cycle forever without it."""
    _, component = terminal_component(graph, state, budget)
    to_cycle, entry = shortest_path(graph, state, component)
    ptr, _ = graph.forward()
    if ptr[entry + 1] == ptr[entry]:
        return to_cycle, ()
    goal = np.zeros(graph.size, dtype=np.bool_)
    goal[entry] = True
    cycle, _ = shortest_path(graph, entry, goal, allow_empty=False)
    return to_cycle, cycle


def _text(prop: Property) -> str:
    from rssm_dsl.syntax.printer import expr_text

    if prop.kind == "always":
        assert prop.condition is not None
        return f"always {expr_text(prop.condition)}"
    assert prop.trigger is not None and prop.goal is not None
    return f"whenever {expr_text(prop.trigger)} eventually {expr_text(prop.goal)}"


def _lift(net: FlatNet, sl: Slice | None, tracked: TrackedNet, prefix: Sequence[int],
          to_cycle: Sequence[int], cycle: Sequence[int], prop: Property,
          reach: int = 0) -> Counterexample:
    """The counterexample in the whole net's words: the prefix (and for a response
    property the path on to the cycle, and the cycle) replayed there. A slice's path on
    that needs the rest of the system (the system's end, which waits for every agent) is
    replayed up to the state from which Q is lost for good (its first ``reach`` steps),
    and the whole net runs on from there, everyone in turn (``slicing.run_outside``): the
    slice's subsystems can do nothing there that reaches Q."""
    tn = tracked.net.transitions

    def told(ts: Sequence[int]) -> tuple[FlatTransition, ...]:
        return tracked.steps(tn[t] for t in ts)

    steps, more, loop = told(prefix), told(to_cycle), told(cycle)
    if sl is None:
        return Counterexample("property", steps, _marking_after(net, steps),
                              subsystem=prop.name, to_cycle=more, cycle=loop,
                              cycle_marking=_marking_after(net, (*steps, *more)) if loop
                              else (),
                              values=tracked.choices(tn[t] for t in (*prefix, *to_cycle,
                                                                     *cycle)))
    fired, m = replay_group(sl, sl.whole_steps(steps))
    reached = marking_labels(net, m)
    if not more and not loop:
        return Counterexample("property", tuple(net.transitions[t] for t in fired), reached,
                              subsystem=prop.name)
    try:
        on, m2 = replay_group(sl, sl.whole_steps(more), m)
    except ReplayError:             # the path on needs the rest of the system
        on, m2 = replay_group(sl, sl.whole_steps(more[:reach]), m)
        tail, around, _ = run_outside(net, m2, frozenset())
        m2 = fire_steps(net, m2, tail)
        return Counterexample("property", tuple(net.transitions[t] for t in fired), reached,
                              subsystem=prop.name,
                              to_cycle=tuple(net.transitions[t] for t in (*on, *tail)),
                              cycle=tuple(net.transitions[t] for t in around),
                              cycle_marking=marking_labels(net, m2) if around else ())
    try:
        around, _ = replay_group(sl, sl.whole_steps(loop), m2)
    except ReplayError:             # the cycle needs the rest of the system: the path only
        around = []
    return Counterexample("property", tuple(net.transitions[t] for t in fired), reached,
                          subsystem=prop.name,
                          to_cycle=tuple(net.transitions[t] for t in on),
                          cycle=tuple(net.transitions[t] for t in around),
                          cycle_marking=marking_labels(net, m2) if around else ())


def _marking_after(net: FlatNet, steps: Sequence[FlatTransition]) -> tuple[str, ...]:
    marking = set(net.initial)
    for t in steps:
        marking -= set(t.pre)
        marking |= set(t.post)
    return marking_labels(net, frozenset(marking))


def _truth(f: Formula, graph: Graph, net: FlatNet) -> tuple[Any, Any]:
    """Per state: the formula's value, and whether it is unknown there (bool arrays)."""
    n = graph.size
    columns: list[Any] = []
    getters: list[Any] = []
    for a in f.atoms:
        if isinstance(a, InBehaviour):
            places = [p.index for p in net.places if p.subsystem == a.subsystem_id
                      and p.behaviour == a.behaviour]
            columns.append(_any_marked(graph, places).astype(np.int64))
            getters.append(("in", a))
        else:
            key = f"value {a.subsystem_id}.{a.variable_name}"
            vals = [(p.index, p.label.rpartition(" = ")[2]) for p in net.places
                    if p.channel == key]
            col = np.full(n, -1, dtype=np.int64)
            for i, (place, _) in enumerate(vals):
                col[_any_marked(graph, [place])] = i
            columns.append(col)
            getters.append(("value", a, _domain_of(a, [v for _, v in vals])))
    if not columns:
        constant = _evaluate(f, (), getters)
        return np.full(n, constant is True), np.full(n, constant is None)
    table = np.stack(columns, axis=1)
    combos, inverse = np.unique(table, axis=0, return_inverse=True)
    results = [_evaluate(f, tuple(int(x) for x in row), getters) for row in combos]
    value = np.array([r is True for r in results])[inverse.reshape(-1)]
    unknown = np.array([r is None for r in results])[inverse.reshape(-1)]
    return value, unknown


def _untracked(formulas: list[Formula], net: FlatNet) -> list[str]:
    """The values the formulas read that ``net`` does not carry, in the user's words."""
    have = {p.channel for p in net.places if p.channel is not None}
    return sorted({f"{a.subsystem_id}.{a.variable_name}" for f in formulas for a in f.atoms
                   if isinstance(a, Value)
                   and f"value {a.subsystem_id}.{a.variable_name}" not in have})


def _domain_of(a: Value, labels: list[str]) -> tuple[Any, ...]:
    from rssm_dsl.semantics.types import finite_domain

    dom = finite_domain(a.type) or ()
    shown = {(str(d).lower() if isinstance(d, bool) else str(d)): d for d in dom}
    return tuple(shown[x] for x in labels if x in shown)


def _evaluate(f: Formula, row: tuple[int, ...], getters: list[Any]) -> bool | None:
    ins: dict[tuple[str, str], bool] = {}
    vals: dict[tuple[str, str], Any] = {}
    for x, g in zip(row, getters, strict=True):
        if g[0] == "in":
            ins[g[1].subsystem_id, g[1].behaviour] = bool(x)
        elif x >= 0:
            vals[g[1].subsystem_id, g[1].variable_name] = g[2][x]

    def value(sub: str, name: str) -> Any:
        return vals[sub, name]          # KeyError (a LookupError): not tracked

    try:
        return f(lambda s, b: ins.get((s, b), False), value)
    except UnknownValue:
        return None
    except Exception:
        return None


def visible_transitions(net: FlatNet, atoms: Sequence[Any]) -> int:
    """The transitions that can change an atom: those touching one side only of a
    behaviour's places, or of one value's place."""
    masks: list[int] = []
    for a in atoms:
        if isinstance(a, InBehaviour):
            masks.append(sum(1 << p.index for p in net.places
                             if p.subsystem == a.subsystem_id and p.behaviour == a.behaviour))
        else:
            key = f"value {a.subsystem_id}.{a.variable_name}"
            masks += [1 << p.index for p in net.places if p.channel == key]
    out = 0
    for t in net.transitions:
        pre = sum(1 << p for p in t.pre)
        post = sum(1 << p for p in t.post)
        if any(bool(pre & m) != bool(post & m) for m in masks):
            out |= 1 << t.index
    return out


def _settled(graph: Graph, tracked: TrackedNet, subsystems: set[str]) -> Any:
    """Per state: none of ``subsystems`` stands between the fork and the join of the
    transition function P^f of a behaviour (``t[j,v,w,f,in]``, ``t[j,v,w,f,out]``). Inside,
    the values tracked are already the function's results (dataplan.py applies it at the
    fork) while the interpreter and the ROS 2 nodes commit them at the join: a property's
    counterexample ends at a settled state, where both read the same values."""
    inside = _inside(tracked.source, subsystems)
    places = [p.index for p in tracked.net.places if tracked.place_origin[p.index] in inside]
    return ~_any_marked(graph, places)


def _inside(src: FlatNet, subsystems: set[str]) -> set[int]:
    """The places of ``src`` between the fork and the join of the transition functions of
    ``subsystems`` (``_settled``)."""
    by_name = {t.name: t for t in src.transitions}
    users: dict[int, list[FlatTransition]] = {}
    for t in src.transitions:
        for p in t.pre:
            users.setdefault(p, []).append(t)
    inside: set[int] = set()
    for fork in src.transitions:
        if fork.subsystem not in subsystems or not fork.name.endswith(",f,in]"):
            continue
        join = by_name.get(fork.name.removesuffix(",f,in]") + ",f,out]")
        if join is None:
            continue
        region = set(fork.post)
        frontier = list(fork.post)
        while frontier:
            for t in users.get(frontier.pop(), ()):
                if t is join or t.subsystem != fork.subsystem:
                    continue
                for q in t.post:
                    place = src.places[q]
                    if (q not in region and place.subsystem == fork.subsystem
                            and place.channel is None):
                        region.add(q)
                        frontier.append(q)
        inside |= region
    return inside


def _any_marked(graph: Graph, places: Sequence[int]) -> Any:
    """Per state: is one of ``places`` marked."""
    mask = np.zeros(graph.states.shape[1], dtype=np.uint64)
    for p in places:
        mask[p // 64] |= np.uint64(1 << (p % 64))
    return (graph.states & mask).any(axis=1)
