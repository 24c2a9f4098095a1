"""Finite values tracked in the net the verifier explores (docs/verify.md, "How values
are tracked"), after new(x) (rssm_dsl/verify/datanet.py) and in the same way: the values
become places and the transitions that read or write them are split into variants, so that
every engine (full and stubborn-set search, the compositional check, progress, slices, SPIN)
explores only the runs the data allows, with no change of its own.

The encoding, for each tracked value ``x`` with domain D (rssm_dsl/verify/dataplan.py says
which are tracked and what each transition does with them):

* one place ``p^d[x=d]`` per d in D, exactly one marked (a place invariant), initially the
  declared initial value;
* a transition that reads ``x`` (its :class:`~rssm_dsl.verify.dataplan.Step`) has one variant
  per value of what it reads, which takes and puts back the place of that value (a read arc);
  a guarded transition keeps only the variants whose guard holds or is unknown;
* a transition that writes ``x`` takes the place of the old value and marks the place of the
  new one; a written value that is unknown (computed from a float, an external operation...)
  gives one variant per value of D.

Which values are tracked in a given net (a slice has only some subsystems): the values of the
subsystems the net has, and a channel's slot only when every transition that fills the
channel is one of its producer's sends (a slice's environment fills a border channel with
anything). A transition of the flat net with more than ``MAX_VALUATIONS`` variants (those of
new(x) included) leaves the largest of its values untracked.

Back to the flat net: the variants keep the ``origin`` of the transition they split and the
value places have none, as new(x)'s, so counterexamples name the flat net's own steps.
"""

from __future__ import annotations

import dataclasses
import itertools
from collections.abc import Callable, Collection, Mapping
from typing import Any

from rssm_dsl.hpn.flat import FlatNet, FlatPlace, FlatTransition
from rssm_dsl.verify.datanet import TrackedNet
from rssm_dsl.verify.dataplan import ANY, MAX_VALUATIONS, Outcome, Step, ValuePlan, valuations
from rssm_dsl.verify.report import Chosen
from rssm_dsl.verify.slicing import channels


def valued(name: str, i: int) -> str:
    """The name of a variant: ``t[1,c,w,4]`` -> ``t^d[1,c,w,4,3]``."""
    head, _, rest = name.partition("[")
    return f"{head}^d[{rest.removesuffix(']')},{i}]" if rest else f"{head}^d[{i}]"


def _fork_step(plan: ValuePlan, name: str, known: tuple[bool | None, ...] | None,
               inputs: int) -> Step:
    # new(x) not tracked (None): the plan's step takes the cases of every combination of
    # the inputs the behaviour splits (rssm_dsl/semantics/cases.py), and only those
    return plan.forks[name](known if known is not None else (None,) * inputs)


class _Values:
    def __init__(self, t: TrackedNet, plan: ValuePlan) -> None:
        self.t, self.plan = t, plan
        net = t.net
        inputs = dict(t.source.new_sites.inputs)
        self.steps: dict[int, Step] = {}
        for u in net.transitions:
            name = t.source.transitions[t.origin[u.index]].name
            if name in plan.forks:
                self.steps[u.index] = _fork_step(plan, name, t.combinations.get(u.name),
                                                 len(inputs.get(u.subsystem or "", ())))
            elif name in plan.steps:
                self.steps[u.index] = plan.steps[name]

    def present(self) -> set[str]:
        """The values this net can track: its subsystems', and the slots only its
        producers' sends fill."""
        t, plan = self.t, self.plan
        subs = {p.subsystem for p in t.net.places if p.subsystem is not None}
        out = {k for k, s in plan.subsystem_of.items() if s is not None and s in subs}
        full = {c.name: c.full for c in channels(t.source)}
        rule, transitions = t.source.rule, t.source.transitions
        for slot, chan in plan.channel_of.items():
            writers = plan.slot_writers.get(slot, frozenset())
            if chan in full and {transitions[x].name
                                 for x in rule.producers[full[chan]]} <= writers:
                out.add(slot)
        return out

    def cone(self, present: set[str], extra: frozenset[str] = frozenset(),
             within: Collection[str] | None = None) -> set[str]:
        """The values the guards (and ``extra``) depend on, directly or through what is
        computed from them; only the guards of the subsystems ``within`` when given.

        Only the values that can be known count (``knowable``: not those every write leaves
        unknown, as a border channel's slot that a slice's environment fills), and of what a
        guard or a write reads only what can change its outcome once the rest is left
        unknown (``_Relevance``): in a slice of a dispatcher and one robot, the
        dispatcher's `all_done when ack1 == job1 and ack2 == job2 ...` cannot be decided
        by job2 while ack2 comes from outside, so job2 is not tracked for it, nor the
        whole fleet's values behind it."""
        net = self.t.net
        writers: dict[str, list[Step]] = {}
        for s in self.steps.values():
            for w in s.writes:
                writers.setdefault(w, []).append(s)
        knowable = self._determined(set(present), writers)
        rel = _Relevance(self.plan, knowable)
        want = {r for u, s in self.steps.items() if s.holds is not None
                and (within is None or net.transitions[u].subsystem in within)
                for r in rel.of_guard(s)} | (extra & knowable)
        # how far each value is from what the property reads, through what computes it
        near = _distances(extra & knowable, writers, rel)
        # and from the guards and the property: what they need, with what computes it
        far = _distances(want, writers, rel)
        want = set(far)
        # a value nothing writes... is still read; a value with a writer outside the plan
        # (e.g. an untracked producer) is written by none of the steps: it stays constant,
        # which is exact only when no transition outside the plan changes it (true by
        # construction: every change of a variable is a step of the plan)
        # at most MAX_VALUATIONS variants of one transition of the flat net, counting those
        # new(x) already made (a fork reading 7 inputs is 128 of them before any value)
        doms = self.plan.vars
        same: dict[int, list[Step]] = {}
        for u, s in self.steps.items():
            same.setdefault(self.t.origin[u], []).append(s)
        while True:
            over = [ss for ss in same.values()
                    if sum(_size(s, want, doms) for s in ss) > MAX_VALUATIONS]
            if not over:
                break
            # what the property reads goes last, then what computes it, the nearest last
            # (a dispatcher's counter that decides the robot's job before the other
            # robots' values that decide the counter); else what is furthest from the
            # guards and the property, the largest domain first
            drop = max((x for s in over[0] for x in (*s.reads, *s.writes) if x in want),
                       key=lambda x: (x not in extra, near.get(x, _FAR), far.get(x, 0),
                                      len(doms[x].domain)))
            want.discard(drop)
        return self._determined(want, writers)

    def _determined(self, want: set[str], writers: dict[str, list[Step]]) -> set[str]:
        """Without the values that every write leaves unknown (fed by a device, computed
        from floats...): tracking them would only multiply the states."""
        doms = self.plan.vars
        while True:
            free = {x for x in want if writers.get(x) and not any(
                _determines(s, x, want, doms) for s in writers[x])}
            if not free:
                return want
            want -= free


def _distances(start: Collection[str], writers: Mapping[str, list[Step]],
               rel: _Relevance) -> dict[str, int]:
    """Each value's distance from ``start``: the steps computing a value, what they read
    that can change it, and so on."""
    out = dict.fromkeys(start, 0)
    todo = sorted(start)
    while todo:
        x = todo.pop(0)
        for s in writers.get(x, []):
            for r in rel.of_write(s, x):
                if r not in out:
                    out[r] = out[x] + 1
                    todo.append(r)
    return out


_FAR = 1 << 30


class _Relevance:
    """What a step reads that can change what it does, the values outside ``knowable``
    left unknown: for a guard, its truth (true, false or unknown); for a written value,
    what each outcome writes there. A read is relevant when two valuations that differ in
    it alone give different answers; every valuation of the knowable reads is tried when
    there are at most ``RELEVANCE_VALUATIONS`` of them, else every read counts (as
    written). Tracking fewer values only leaves more of them unknown, which every engine
    explores as any value: this decides precision, never soundness."""

    def __init__(self, plan: ValuePlan, knowable: set[str]) -> None:
        self.doms = plan.vars
        self.knowable = knowable
        # per step that writes: its outcomes for each valuation of its knowable reads (in
        # the order of ``valuations``), run once for all the values it writes
        self._runs: dict[int, list[Any]] = {}

    def of_guard(self, s: Step) -> tuple[str, ...]:
        assert s.holds is not None
        holds = s.holds
        return self._relevant(s, [r for r in s.reads if r in self.knowable],
                              lambda val, _: holds(val))

    def of_write(self, s: Step, x: str) -> tuple[str, ...]:
        deps = s.reads if s.deps is None else s.deps.get(x, s.reads)
        keys = [r for r in deps if r in self.knowable]
        if x not in s.writes or len(keys) <= 1:
            return tuple(keys)
        found = self._relevant(s, [r for r in s.reads if r in self.knowable], lambda val, outs: (
            _UNDECIDED if outs is None else tuple(
                _outcome_key(o.get(x, val.get(x, ANY))) for o in outs)))
        return tuple(k for k in found if k in keys)

    def _relevant(self, s: Step, keys: list[str],
                  answer: Callable[[dict[str, Any], Any], Any]) -> tuple[str, ...]:
        if len(keys) <= 1:
            return tuple(keys)
        total = 1
        for k in keys:
            total *= len(self.doms[k].domain)
        if total > RELEVANCE_VALUATIONS:
            return tuple(keys)
        vals = list(valuations(keys, {k: self.doms[k].domain for k in keys}))
        runs: list[Any] = [None] * len(vals)
        if s.writes:
            if id(s) not in self._runs:
                self._runs[id(s)] = [self._run(s, val) for val in vals]
            runs = self._runs[id(s)]
        rows: list[tuple[tuple[Any, ...], Any]] = []
        for val, outs in zip(vals, runs, strict=True):
            try:
                a = answer(val, outs)
            except Exception:              # unknown here: an answer of its own
                a = _UNDECIDED
            rows.append((tuple(_outcome_key(val[k]) for k in keys), a))
        out: list[str] = []
        for i, k in enumerate(keys):
            seen: dict[tuple[Any, ...], Any] = {}
            for row, a in rows:
                if seen.setdefault(row[:i] + row[i + 1:], a) != a:
                    out.append(k)
                    break
        return tuple(out)

    def _run(self, s: Step, val: dict[str, Any]) -> Any:
        try:
            return s.run(val)
        except Exception:
            return None


RELEVANCE_VALUATIONS = 8192     # per step: beyond, every read counts as relevant
_UNDECIDED = ("undecided",)


def _outcome_key(v: Any) -> Any:
    """A hashable stand-in for a value an outcome writes (ANY, a domain's value)."""
    if v is ANY:
        return ("any",)
    if isinstance(v, bool):
        return ("bool", v)
    try:
        hash(v)
    except TypeError:
        return ("repr", repr(v))
    return (type(v).__name__, v)


def _determines(s: Step, x: str, want: set[str], doms: Mapping[str, Any]) -> bool:
    """Some values of what ``s`` reads make it write a known value into ``x``."""
    keys = [r for r in s.reads if r in want]
    domains = {k: doms[k].domain for k in keys}
    return any(o.get(x, ANY) is not ANY for val in valuations(keys, domains)
               for o in s.run(val))


def _size(s: Step, want: set[str], doms: Mapping[str, Any]) -> int:
    """The variants of ``s`` with the values ``want`` tracked: one per valuation of what it
    reads and writes (the old value), times the values a write computed from something
    not tracked may take (each one a variant)."""
    n = 1
    for x in {*s.reads, *s.writes} & want:
        n *= len(doms[x].domain)
    for x in set(s.writes) & want:
        if any(r not in want for r in (s.reads if s.deps is None else s.deps.get(x, s.reads))):
            n *= len(doms[x].domain)
    return n


def track_values(t: TrackedNet, plan: ValuePlan | None,
                 extra: frozenset[str] = frozenset(), values: bool = True) -> TrackedNet:
    """``t`` with the values of ``plan`` in its places (the module docstring), and the
    values ``extra`` (keys of ``plan.vars``: those a property reads); ``t`` itself when no
    guard depends on a value this net can track. With ``values`` false, no value: only the
    guards that read parameters and constants alone are decided (the pass with the
    conditions as free choices: a parameter is never abstracted)."""
    if plan is None:
        return t
    v = _Values(t, plan)
    cone = v.cone(v.present(), extra) if values else set()
    if not cone and not any(s.holds is not None and not s.reads and s.holds({}) is not None
                            for s in v.steps.values()):
        return t
    net = t.net
    places: list[FlatPlace] = list(net.places)
    place_origin: list[int | None] = list(t.place_origin)
    initial = set(net.initial)
    at: dict[tuple[str, Any], int] = {}
    for key in sorted(cone):
        var = plan.vars[key]
        sub = plan.subsystem_of[key]
        page = next((pg.id for pg in net.pages if pg.kind == "subsystem" and pg.owner == sub),
                    None)
        for d in var.domain:
            i = len(places)
            name = f"p^d[{key}={d}]"
            places.append(FlatPlace(i, name, f"{var.label} = {_show(d)}", var.span, (name,),
                                    subsystem=None, channel=f"value {key}", page=page))
            place_origin.append(None)
            at[key, d] = i
            if type(d) is type(var.initial) and d == var.initial:
                initial.add(i)
    transitions: list[FlatTransition] = []
    origin: list[int] = []
    decided: set[int] = set()        # source transitions whose guard the values decide
    chosen: dict[int, tuple[Chosen, ...]] = {}
    for u in net.transitions:
        s = v.steps.get(u.index)
        variants = _variants(u, s, cone, plan, at) if s is not None else None
        if variants is None and s is not None and s.holds is not None and not s.reads:
            # a guard that reads no variable, only parameters and constants (`when done and
            # quick`, `quick` a param): decided as it is, never a free choice; false: the
            # transition never fires, so the tracked net leaves it out
            fixed = s.holds({})
            if fixed is not None:
                decided.add(t.origin[u.index])
                if fixed is False:
                    continue
        if variants is None:
            variants = [(u.name, u.pre, u.post, ())]
        elif s is not None and s.holds is not None and _decides(s, cone, plan):
            decided.add(t.origin[u.index])
        for name, pre, post, undecided in variants:
            if undecided:
                chosen[len(transitions)] = tuple(
                    (sub, key[len(sub) + 1:], d) for key, d in undecided
                    if (sub := plan.subsystem_of.get(key)) is not None)
            transitions.append(dataclasses.replace(
                u, index=len(transitions), name=name, pre=tuple(sorted(set(pre))),
                post=tuple(sorted(set(post)))))
            origin.append(t.origin[u.index])
    out = FlatNet(net.system, tuple(places), tuple(transitions), frozenset(initial),
                  net.final, net.subsystems, net.pages)
    tracked = (*t.tracked, *(c for c in t.free if c.transition in decided))
    free = tuple(c for c in t.free if c.transition not in decided)
    combos: dict[str, tuple[bool | None, ...]] = {}   # forks renamed: nothing reads them now
    return TrackedNet(out, t.source, tuple(origin), tuple(place_origin), tracked, free, combos,
                      tuple(sorted(plan.vars[k].label for k in cone)),
                      {k: c for k, c in chosen.items() if c})


def tracked_labels(t: TrackedNet, plan: ValuePlan, extra: frozenset[str],
                   within: Collection[str]) -> frozenset[str]:
    """The labels of the values :func:`track_values` would track in ``t`` for ``extra``
    if only the guards of the subsystems ``within`` counted: what a slice of them needs
    from outside."""
    v = _Values(t, plan)
    return frozenset(plan.vars[k].label for k in v.cone(v.present(), extra, within))


def _show(d: Any) -> str:
    return str(d).lower() if isinstance(d, bool) else str(d)


def _decides(s: Step, cone: set[str], plan: ValuePlan) -> bool:
    """The guard's value is known for every value of what it reads."""
    assert s.holds is not None
    keys = [r for r in s.reads if r in cone]
    if len(keys) < len(s.reads):
        return False
    doms = {k: plan.vars[k].domain for k in keys}
    return all(s.holds(val) is not None for val in valuations(keys, doms))


Variant = tuple[str, tuple[int, ...], tuple[int, ...], tuple[tuple[str, Any], ...]]


def _variants(u: FlatTransition, s: Step, cone: set[str], plan: ValuePlan,
              at: Mapping[tuple[str, Any], int]) -> list[Variant] | None:
    """The variants of ``u``: name, pre and post places, and the values it writes that no
    outcome decides (chosen among the domain's: a device's reading...)."""
    reads = [r for r in s.reads if r in cone]
    writes = [w for w in s.writes if w in cone]
    if not reads and not writes:
        return None
    keys = [*reads, *(w for w in writes if w not in reads)]
    doms = {k: plan.vars[k].domain for k in keys}
    out: list[Variant] = []
    cache: dict[tuple[Any, ...], list[Outcome]] = {}
    for val in valuations(keys, doms):
        rkey = tuple(val[r] for r in reads)
        outcomes = cache.get(rkey)
        if outcomes is None:
            outcomes = cache[rkey] = s.run({r: val[r] for r in reads})
        pre = tuple(at[k, val[k]] for k in keys)
        seen: set[tuple[int, ...]] = set()
        for o in outcomes:
            choices = [_values_of(o.get(w, val[w]), plan.vars[w].domain, val[w])
                       for w in writes]
            for new in itertools.product(*choices):
                after = dict(val)
                after.update(zip(writes, new, strict=True))
                post = tuple(at[k, after[k]] for k in keys)
                if post in seen:
                    continue
                seen.add(post)
                free = tuple((w, d) for w, c, d in zip(writes, choices, new, strict=True)
                             if len(c) > 1)
                out.append((valued(u.name, len(out) + 1), (*u.pre, *pre), (*u.post, *post),
                            free))
    return out


def _values_of(v: Any, domain: tuple[Any, ...], old: Any) -> tuple[Any, ...]:
    """The values an outcome may give a variable: its own when it is one of the domain's,
    else (unknown, or outside the domain) any."""
    if v is ANY:
        return domain
    for d in domain:
        if type(d) is type(v) and d == v:
            return (d,)
    return domain
