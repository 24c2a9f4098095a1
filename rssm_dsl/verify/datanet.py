"""new(x) tracked in the net the verifier explores (docs/verify.md, "How new(x) is tracked";
rssm_core/iteration.py).

The flat net leaves every condition a free choice, the data cases of the partial functions
included: from the start of a partial function any of its cases may fire, whatever the
receives did. :func:`track_new` gives the flat net places for new(x), so that the data case
that fires is the one the receives allow, and every engine (full and stubborn-set search,
the compositional check, progress, the SPIN and 4ti2 cross-checks) explores only those runs
with no change of its own. The other conditions stay free choices (:func:`free_conditions`
lists them for the report).

The encoding, for each subsystem whose data cases split n >= 1 of its inputs (the inputs
some case clause of the subsystem reads, rssm_dsl/semantics/cases.py; the others are not
tracked: no case tells their new(x) apart):

* per tracked input x_k two complementary places, ``p^new[j,v,k,1]`` ("new(x_k)": a receive took
  fresh data into x_k since the transition function last used it) and ``p^new[j,v,k,2]``
  ("not new(x_k)", initially marked): one token between them, a place invariant;
* the step RECEIVED of x_k's receive page (from its ``op`` place to ``out``) sets new(x_k),
  in two variants ``t^new[...,1]`` (it was not new) and ``t^new[...,2]`` (it was new already
  and stays so);
* the fork of the transition function P^f (``t[j,v,w,f,in]``) freezes new(x) for the data
  cases and uses the data: one variant ``t^new[j,v,w,f,in,varpi]`` per combination varpi of
  the tracked inputs (varpi = 1 all new, the first input varying fastest), taking the places
  of varpi and putting back "not new" for every tracked input. The start place of each
  partial function is split by the combinations of the inputs its cases split
  (``p[j,v,w,psi,in]`` stands for "all new", ``p^new[j,v,w,psi,in,varpi]`` for the others),
  the variant marks those its combination gives, and the data case of a combination starts
  from its own: it is the only case that can fire. A partial function with one case (its
  behaviour's clauses split nothing) keeps its start place.

The interpreter clears new(x) at the join of P^f (rssm_dsl/interp/program.py); clearing it at
the fork gives the same runs: nothing sets or reads new(x) of the subsystem between its fork
and its join (the receives of a subsystem come after its send, and each data case reads the
combination its start place carries). It keeps new(x) at "not new" for longer, so the state
space is smaller than with a clearing join (measured against two such encodings in
docs/verify.md), and it adds no place that the data cases or the join share: they stay free
of conflicts for the stubborn sets and hidden early in the compositional check.

The places of new(x) belong to no subsystem and carry a ``channel`` of their own (``new(x)
of j.v``): like a channel's fused places they are shared by pages of the subsystem, so the
compositional check gives them a component of their own under the lowest page holding their
users, and progress does not count them as places of the subsystem.

Back to the flat net (:meth:`TrackedNet.report`): every transition of the tracked net stands
for one of the flat net (``origin``) and every place but new(x)'s for one (``place_origin``).
So the counterexamples printed and replayed (``rssmc simulate --replay``) name the flat net's
own transitions and places, and a transition of the flat net is dead when all its variants are.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Iterable
from dataclasses import field

from rssm_core.records import dataclass
from rssm_dsl.hpn.flat import FlatCondition, FlatNet, FlatPlace, FlatTransition
from rssm_dsl.hpn.flatten import flatten
from rssm_dsl.hpn.ir import HPN, Arc, FusionSet, Place
from rssm_dsl.semantics import cases as case_rule
from rssm_dsl.verify.report import (
    Chosen,
    Counterexample,
    FreeCondition,
    StepValue,
    VerifyReport,
)

MAX_INPUTS = 10           # 2^n variants of a fork: beyond, new(x) of the subsystem stays free


def varpi_of(new: tuple[bool | None, ...]) -> int:
    """The number of a combination (paper Eq. 5) over the inputs it fixes: 1 is all new,
    the first input varies fastest (rssm_dsl/semantics/cases.py)."""
    return case_rule.number_of(new)


def combination(varpi: int, n: int) -> tuple[bool, ...]:
    """new(x) per input of combination ``varpi`` of ``n`` inputs (the inverse of
    :func:`varpi_of`)."""
    return tuple(not (varpi - 1) >> k & 1 for k in range(n))


def derived(name: str, *extra: int) -> str:
    """The name of an element added for ``name``: ``t[1,c,w,f,in]`` -> ``t^new[1,c,w,f,in,3]``."""
    head, _, rest = name.partition("[")
    parts = [rest.removesuffix("]")] if rest else []
    return f"{head}^new[{','.join([*parts, *map(str, extra)])}]"


@dataclass(frozen=True)
class TrackedNet:
    """The net the verifier explores, and how it maps back to the flat net it was made from."""

    net: FlatNet
    source: FlatNet
    origin: tuple[int, ...]               # per transition of net: the source's it stands for
    place_origin: tuple[int | None, ...]  # per place of net: the source's; None: new(x)'s
    tracked: tuple[FlatCondition, ...]    # the source's conditions decided by the state
    free: tuple[FlatCondition, ...]       # the source's conditions left free choices
    # per fork variant of net (by name): new(x) of each input of its subsystem as the
    # variant takes it (None: not tracked, a free choice)
    combinations: dict[str, tuple[bool | None, ...]] = field(default_factory=dict)
    values: tuple[str, ...] = ()          # the values tracked (rssm_dsl/verify/valuenet.py)
    # per transition of net: the values its variant writes that the data does not decide
    # (a device's reading, a float...: any value of the domain), (subsystem, variable, value)
    chosen: dict[int, tuple[Chosen, ...]] = field(default_factory=dict)

    @property
    def changed(self) -> bool:
        return self.net is not self.source

    def steps(self, steps: Iterable[FlatTransition]) -> tuple[FlatTransition, ...]:
        """A firing sequence of ``net`` as the flat net's."""
        return tuple(self.source.transitions[self.origin[t.index]] for t in steps)

    def choices(self, steps: Iterable[FlatTransition]) -> tuple[StepValue, ...]:
        """The values chosen along a firing sequence of ``net`` (``chosen``), each with its
        position in the sequence."""
        return tuple((i, *c) for i, t in enumerate(steps) for c in self.chosen.get(t.index, ()))

    def labels(self, labels: Iterable[str]) -> tuple[str, ...]:
        """Place labels of ``net`` without new(x)'s."""
        hidden = {p.label or p.name for p in self.net.places
                  if self.place_origin[p.index] is None}
        return tuple(x for x in labels if x not in hidden)

    def counterexample(self, c: Counterexample) -> Counterexample:
        return dataclasses.replace(
            c, values=self.choices((*c.steps, *c.to_cycle, *c.cycle)) if self.chosen else (),
            steps=self.steps(c.steps), marking=self.labels(c.marking),
            doubled=self.labels(c.doubled), to_cycle=self.steps(c.to_cycle),
            cycle=self.steps(c.cycle), cycle_marking=self.labels(c.cycle_marking))

    def dead(self, dead: tuple[FlatTransition, ...] | None) -> tuple[FlatTransition, ...] | None:
        """The flat net's transitions all of whose variants are dead."""
        if dead is None:
            return None
        gone = {t.index for t in dead}
        alive = {o for t, o in enumerate(self.origin) if t not in gone}
        return tuple(t for t in self.source.transitions if t.index not in alive)

    def report(self, r: VerifyReport) -> VerifyReport:
        """The verifier's report on ``net`` told in the flat net's transitions and places."""
        return dataclasses.replace(
            r, deadlocks=tuple(self.counterexample(c) for c in r.deadlocks),
            unsafe=self.counterexample(r.unsafe) if r.unsafe is not None else None,
            progress=tuple(self.counterexample(c) for c in r.progress),
            dead_transitions=self.dead(r.dead_transitions),
            uncovered_places=self.labels(r.uncovered_places),
            free_conditions=free_conditions(self.source, self.free),
            new_tracked_cases=len([c for c in self.tracked if c.kind == "case"]),
            tracked_values=self.values)


def free_conditions(net: FlatNet, conditions: Iterable[FlatCondition],
                    ) -> tuple[FreeCondition, ...]:
    """The conditions left free choices in the user's words, each once (a behaviour's t_4
    and t_out test the same terminal and error conditions)."""
    out: dict[tuple[str, str, str], FreeCondition] = {}
    for c in conditions:
        t = net.transitions[c.transition]
        if c.kind == "switch":
            where, kind, text = t.label.removesuffix(f" [{c.text}]"), "switch", c.text
        else:
            where = t.subsystem or net.system
            if t.behaviour is not None:
                where += f" ({t.behaviour})"
            kind = "data case" if c.kind == "case" else "terminal/error"
            text = c.text
            if c.kind == "continue" and text.startswith("not (") and text.endswith(")"):
                text = text[len("not ("):-1]
        out.setdefault((where, kind, text), FreeCondition(kind, where, text, t.span))
    return tuple(out.values())


def untracked(net: FlatNet) -> TrackedNet:
    """Nothing tracked: ``net`` itself, without its conditions when it has any (all free)."""
    explored = dataclasses.replace(net, conditions=()) if net.conditions else net
    return TrackedNet(explored, net, tuple(range(len(net.transitions))),
                      tuple(range(len(net.places))), (), net.conditions)


# ---------------------------------------------------------------------- which subsystems


@dataclass
class _Sub:
    """A subsystem whose new(x) is tracked: its n inputs and where new(x) is decided."""

    name: str
    buffers: tuple[str, ...]          # by k
    cases: dict[int, tuple[bool | None, ...]] = field(default_factory=dict)  # t -> new(x)
    receives: dict[int, int] = field(default_factory=dict)            # RECEIVED -> k
    forks: set[int] = field(default_factory=set)
    consistent: bool = True
    flags: dict[int, tuple[int, int]] = field(default_factory=dict)  # k: (new, not new) place
    tracked: tuple[int, ...] = ()     # the inputs k tracked (the others: free, NewSites.free)

    @property
    def n(self) -> int:
        return len(self.buffers)


def _subsystems(net: FlatNet) -> list[_Sub]:
    """The subsystems with data cases whose new(x) can be tracked: every case of the
    compiler's shape (:func:`_cases_start_at_forks`), the forks and receives known."""
    sites = net.new_sites
    buffers = dict(sites.inputs)
    subs: dict[str, _Sub] = {}
    for c in net.conditions:
        sub = net.transitions[c.transition].subsystem
        if c.kind != "case" or not c.new or sub is None:
            continue
        names = buffers.get(sub, ())
        s = subs.setdefault(sub, _Sub(sub, tuple(names[k] if k < len(names) else
                                                 f"input {k + 1}" for k in range(len(c.new)))))
        s.consistent = s.consistent and len(c.new) == s.n
        s.cases[c.transition] = c.new
    for t, sub, k in sites.receives:
        if sub in subs:
            subs[sub].receives[t] = k
    for t, sub in sites.forks:
        if sub in subs:
            subs[sub].forks.add(t)
    free = set(sites.free)
    for s in subs.values():
        split = {k for new in s.cases.values() for k in case_rule.split_of(new)}
        s.tracked = tuple(k for k in range(s.n) if k in split and (s.name, k) not in free)
    return [s for s in subs.values()
            if s.consistent and 0 < len(s.tracked) <= MAX_INPUTS and s.forks
            and all(k < s.n for k in s.receives.values()) and _cases_start_at_forks(net, s)]


def _cases_start_at_forks(net: FlatNet, s: _Sub) -> bool:
    """Each data case leaves from one place, which only forks of the subsystem mark and only
    its data cases take, one case per combination of the inputs they split (the shape the
    compiler builds)."""
    rule = net.rule
    seen: dict[int, set[tuple[bool | None, ...]]] = {}
    for t, new in s.cases.items():
        pre = net.transitions[t].pre
        if len(pre) != 1:
            return False
        p = pre[0]
        if not set(rule.producers[p]) <= s.forks or not set(rule.consumers[p]) <= s.cases.keys():
            return False
        combos = seen.setdefault(p, set())
        if new in combos or (combos and case_rule.split_of(new)
                             != case_rule.split_of(next(iter(combos)))):
            return False
        combos.add(new)
    return all(len(c) == 1 << len(case_rule.split_of(next(iter(c)))) for c in seen.values())


# ---------------------------------------------------------------------- the tracked net

Variant = tuple[str, tuple[int, ...], tuple[int, ...]]     # (name, pre, post)


class _Builder:
    """The flat net's places and transitions with new(x)'s added (the module docstring)."""

    def __init__(self, net: FlatNet) -> None:
        self.src = net
        self.places: list[FlatPlace] = list(net.places)
        self.place_origin: list[int | None] = list(range(len(net.places)))
        self.initial = set(net.initial)
        self.variants: dict[int, list[Variant]] = {}     # source transition -> its variants
        self.combinations: dict[str, tuple[bool | None, ...]] = {}

    def add_place(self, p: FlatPlace, origin: int | None) -> int:
        i = len(self.places)
        self.places.append(dataclasses.replace(p, index=i))
        self.place_origin.append(origin)
        return i

    def flags(self, s: _Sub) -> None:
        """The places new(x_k) and not new(x_k), on the subsystem's page."""
        page = next((pg for pg in self.src.pages if pg.kind == "subsystem"
                     and pg.owner == s.name), None)
        prefix = page.id.partition("[")[2].removesuffix("]") if page else s.name
        span = self.src.transitions[min(s.forks)].span
        for k in s.tracked:
            x = s.buffers[k]
            base, words = f"p[{prefix},{k + 1}]", f"new({x}) of {s.name}"
            yes, no = [self.add_place(FlatPlace(
                0, derived(base, which), label, span, (derived(base, which),), channel=words,
                page=page.id if page else None), None)
                for which, label in ((1, words), (2, f"not {words}"))]
            self.initial.add(no)
            s.flags[k] = (yes, no)

    def receives(self, s: _Sub) -> None:
        """RECEIVED sets new(x_k): from "not new", or keeping "new"."""
        for t, k in s.receives.items():
            if k not in s.flags:
                continue                # new(x_k) left free
            tr = self.src.transitions[t]
            yes, no = s.flags[k]
            self.variants[t] = [(derived(tr.name, 1), (*tr.pre, no), (*tr.post, yes)),
                                (derived(tr.name, 2), (*tr.pre, yes), (*tr.post, yes))]

    def forks(self, s: _Sub) -> None:
        """The fork of P^f takes new(x) of a combination and clears it; each partial
        function's start place is split by combination, its data cases start from theirs."""
        src, tracked = self.src, s.tracked
        n = len(tracked)
        split: dict[int, list[int]] = {}       # start place -> per varpi - 1: its place
        keys: dict[int, tuple[int, ...]] = {}  # start place -> the tracked inputs it splits
        for t, new in s.cases.items():
            tr = src.transitions[t]
            p = tr.pre[0]
            if p not in split:
                keys[p] = tuple(k for k in tracked if new[k] is not None)
                like = src.places[p]
                split[p] = [p] + [self.add_place(dataclasses.replace(
                    like, name=derived(like.name, v), origin=(derived(like.name, v),)), p)
                    for v in range(2, (1 << len(keys[p])) + 1)]
            varpi = varpi_of(tuple(new[k] for k in keys[p]))
            self.variants[t] = [(tr.name, (split[p][varpi - 1],), tr.post)]
        clear = tuple(s.flags[k][1] for k in tracked)
        for f in s.forks:
            tr = src.transitions[f]
            rest = tuple(q for q in tr.post if q not in split)
            variants: list[Variant] = []
            for varpi in range(1, (1 << n) + 1):
                known = dict(zip(tracked, combination(varpi, n), strict=True))
                self.combinations[derived(tr.name, varpi)] = tuple(known.get(k)
                                                                   for k in range(s.n))
                variants.append((
                    derived(tr.name, varpi),
                    (*tr.pre, *(s.flags[k][0 if known[k] else 1] for k in tracked)),
                    (*rest, *(split[q][varpi_of(tuple(known[k] for k in keys[q])) - 1]
                              for q in tr.post if q in split), *clear)))
            self.variants[f] = variants

    def build(self, subs: list[_Sub]) -> TrackedNet:
        src = self.src
        transitions: list[FlatTransition] = []
        origin: list[int] = []
        for tr in src.transitions:
            for name, pre, post in self.variants.get(tr.index, [(tr.name, tr.pre, tr.post)]):
                transitions.append(dataclasses.replace(
                    tr, index=len(transitions), name=name, pre=tuple(sorted(set(pre))),
                    post=tuple(sorted(set(post)))))
                origin.append(tr.index)
        cases = {t for s in subs for t in s.cases}
        tracked = tuple(c for c in src.conditions if c.transition in cases)
        free = tuple(c for c in src.conditions if c.transition not in cases)
        net = FlatNet(src.system, tuple(self.places), tuple(transitions),
                      frozenset(self.initial), src.final, src.subsystems, src.pages)
        return TrackedNet(net, src, tuple(origin), tuple(self.place_origin), tracked, free,
                          self.combinations)


def track_new(net: FlatNet) -> TrackedNet:
    """``net`` with new(x) of its subsystems' inputs in its places (the module docstring).
    The net explored has no conditions left (new(x)'s are places, the others free choices,
    kept in ``free``), so that it is its own tracked net; without data cases to track it
    is ``net`` itself, or ``net`` without its conditions."""
    subs = _subsystems(net)
    if not subs:
        return untracked(net)
    b = _Builder(net)
    for s in subs:
        b.flags(s)
        b.receives(s)
        b.forks(s)
    return b.build(subs)


# ---------------------------------------------------------------------- the same, on the HPN


def tracked_hpn(hpn: HPN) -> HPN:
    """The HPN whose flattening is the tracked net (for cpncheck, which expands the hierarchy
    itself): every place :func:`track_new` adds is a fusion set, with a member on each page
    whose transitions use it; a transition it changes is replaced, on its page, by its
    variants, which keep its arcs to the places it had. ``hpn`` itself when nothing is
    tracked."""
    net = flatten(hpn)
    t = track_new(net)
    return _Lift(hpn, net, t).hpn() if t.changed else hpn


class _Lift:
    def __init__(self, hpn: HPN, net: FlatNet, t: TrackedNet) -> None:
        self.src, self.net, self.t = hpn, net, t
        self.members: dict[int, dict[str, str]] = {}    # added place -> page -> member
        self.replaced: dict[str, list[FlatTransition]] = {}
        groups: dict[int, list[FlatTransition]] = {}
        for u in t.net.transitions:
            groups.setdefault(t.origin[u.index], []).append(u)
        for o, variants in groups.items():
            tr = net.transitions[o]
            if [(u.name, u.pre, u.post) for u in variants] != [(tr.name, tr.pre, tr.post)]:
                self.replaced[tr.name] = variants

    def flat_place(self, node: str, entering: bool) -> int:
        """The flat place an arc end of the HPN stands for (as flattening resolves it)."""
        hpn = self.src
        while node in hpn.pages:
            page = hpn.pages[node]
            node = page.in_place if entering else page.out_place
        return self.net.place_index[hpn.places[node].fusion or node]

    def member(self, q: int, page: str) -> str:
        if q < len(self.net.places):
            raise ValueError(f"{self.t.net.places[q].name} is not a place of the transition")
        return self.members.setdefault(q, {}).setdefault(page,
                                                         f"{self.t.net.places[q].name}@{page}")

    def hpn(self) -> HPN:
        src, index = self.src, self.src.index()
        transitions = {k: v for k, v in src.transitions.items() if k not in self.replaced}
        arcs = [a for a in src.arcs if a.source not in self.replaced
                and a.target not in self.replaced]
        for tid, variants in self.replaced.items():
            tr = src.transitions[tid]
            ins = {self.flat_place(a.source, False): a for a in index.into(tid)}
            outs = {self.flat_place(a.target, True): a for a in index.out_of(tid)}
            for u in variants:
                transitions[u.name] = dataclasses.replace(
                    tr, id=u.name, key=tr.key if u.name == tid else None)
                arcs += [Arc(ins[q].page, ins[q].source, u.name) if q in ins else
                         Arc(tr.page, self.member(q, tr.page), u.name) for q in u.pre]
                arcs += [Arc(outs[q].page, u.name, outs[q].target) if q in outs else
                         Arc(tr.page, u.name, self.member(q, tr.page)) for q in u.post]
        places, fusions = dict(src.places), dict(src.fusions)
        net = self.t.net
        for q, by_page in self.members.items():
            p, initial = net.places[q], q in net.initial
            for page, member in by_page.items():
                places[member] = Place(member, page, p.span, p.label, fusion=p.name,
                                       initial=initial)
            fusions[p.name] = FusionSet(p.name, p.label, p.channel or "",
                                        tuple(by_page.values()), initial, p.span)
        return HPN(src.system, src.root, dict(src.pages), places, transitions, arcs, fusions,
                   list(src.devices))
