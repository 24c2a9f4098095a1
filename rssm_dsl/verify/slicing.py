"""Slices of the flat net at the channels nobody waits on.

A channel is *free* when neither of its ends can wait on it: both the send and the receive are
non-blocking. Structurally: every transition of either end that takes the channel's ``full``
or ``empty`` place has a sibling of the same subsystem taking the other one from the same
places (a non-blocking receive takes new data or finds none; a non-blocking send starts on an
empty buffer or overwrites a full one). A blocking end has a step with no such sibling (it
waits for ``full``, or for ``empty`` after its send).

The subsystems joined by channels that are not free form *blocking groups*
(:func:`blocking_groups`): the control subsystems of agents talking over blocking channels
form one group; an effector, a receptor or a device talking non-blocking to everyone is a
group of its own. A group never waits on anything outside it, and nothing outside it waits on
it.

The slice of a group (:func:`slice_net`) keeps the group's transitions and places and the
system's own plumbing, and replaces everything else by an *environment* for each free
channel crossing the border: ``env-write`` (``empty -> full``) where the producer is outside,
``env-take`` (``full -> empty``) where the consumer is. The environment may fire them at any
time or never, so the slice can do everything the group can do in the whole net, whatever the
rest is doing (an outside producer between its two send steps is simply not written yet).
Hence, for the group's places and for what it can reach:

* the slice is safe if the group is safe in the whole net (and every place lies in some slice);
* a reachable deadlock of the whole net is a reachable deadlock of every slice (in it, no
  outside end is between two steps, and the environment's moves enable nothing of the group),
  so one deadlock-free slice makes the whole net deadlock-free;
* the group's subsystems never wait on the environment, and the data cases a fresh or a stale
  value selects all end in the same place, so the group's own moves in a slice run can be
  replayed, token for token, in the whole net with the outside standing still
  (:func:`replay_group`; the values the environment gave are another matter: ``sliced``
  lifts them with the values tracked): every violation found in a slice is lifted to a
  firing sequence of the whole net and checked there before it is reported.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable, Collection, Sequence

from rssm_core.records import dataclass
from rssm_dsl.hpn.flat import FlatNet, FlatPlace, FlatTransition, NewSites, Role


@dataclass(frozen=True)
class Channel:
    name: str
    full: int
    empty: int
    producer: str | None
    consumer: str | None
    free: bool                       # neither end waits on it
    producer_waits: bool = False     # the producer's end can wait (a blocking send)
    consumer_waits: bool = False     # the consumer's end can wait (a blocking receive)


def channels(net: FlatNet) -> list[Channel]:
    """The net's channels (their fused ``full``/``empty`` places, their ends) and whether
    they are free (the module docstring). Computed once per net."""
    cached = _CHANNELS.get(id(net))
    if cached is not None and cached[0] is net:
        return cached[1]
    places: dict[str, list[int]] = {}
    for p in net.places:
        if p.channel is not None and p.subsystem is None:
            places.setdefault(p.channel, []).append(p.index)
    users: dict[str, list[FlatTransition]] = {}
    by_sub: dict[str | None, list[FlatTransition]] = {}
    for t in net.transitions:
        by_sub.setdefault(t.subsystem, []).append(t)
        if t.channel in places and t.subsystem is not None:
            users.setdefault(t.channel, []).append(t)
    pres = {sub: {frozenset(t.pre) for t in ts} for sub, ts in by_sub.items()}
    out = []
    for name, ps in places.items():
        mine = users.get(name, [])
        senders = {t.subsystem for t in mine if t.role is Role.SEND}
        receivers = {t.subsystem for t in mine if t.role is Role.RECEIVE}
        filled = {p for t in mine if t.role is Role.SEND for p in t.post
                  if p in ps and p not in t.pre}
        if len(ps) != 2 or len(filled) != 1 or len(senders) != 1 or len(receivers) != 1:
            continue            # not a channel's full/empty pair (e.g. new(x) of a subsystem)
        full = filled.pop()
        empty = ps[0] if ps[1] == full else ps[1]
        producer, consumer = senders.pop(), receivers.pop()
        sends, takes = (not _never_waits(by_sub.get(s, []), pres.get(s, set()), full, empty)
                        for s in (producer, consumer))
        out.append(Channel(name, full, empty, producer, consumer, not (sends or takes),
                           sends, takes))
    if len(_CHANNELS) > 64:
        _CHANNELS.clear()
    _CHANNELS[id(net)] = (net, out)
    return out


_CHANNELS: dict[int, tuple[FlatNet, list[Channel]]] = {}


def _never_waits(own: list[FlatTransition], pres: set[frozenset[int]], full: int,
                 empty: int) -> bool:
    pair = {full, empty}
    for t in own:
        took = pair.intersection(t.pre)
        if not took:
            continue
        if len(took) == 2:
            return False
        (x,) = took
        other = empty if x == full else full
        if frozenset(t.pre) - {x} | {other} not in pres:
            return False
    return True


def blocking_groups(net: FlatNet) -> list[tuple[str, ...]]:
    """The net's subsystems grouped by the channels that are not free (largest first)."""
    subs = list(net.subsystems) or sorted({t.subsystem for t in net.transitions
                                           if t.subsystem is not None})
    parent = {s: s for s in subs}

    def find(s: str) -> str:
        while parent[s] != s:
            parent[s] = parent[parent[s]]
            s = parent[s]
        return s

    for c in channels(net):
        if not c.free and c.producer in parent and c.consumer in parent:
            parent[find(c.producer)] = find(c.consumer)
    groups: dict[str, list[str]] = {}
    for s in subs:
        groups.setdefault(find(s), []).append(s)
    return sorted((tuple(g) for g in groups.values()), key=lambda g: (-len(g), g))


def wait_closure(net: FlatNet, subsystems: Collection[str],
                 feeds: Callable[[Channel], bool] = lambda _c: False) -> tuple[str, ...]:
    """The smallest set of subsystems holding ``subsystems`` in which no subsystem waits on
    one outside it: with each subsystem, the other end of every channel on which its own end
    can wait (the producer it receives from blocking, the consumer it sends to blocking),
    and the producer of every channel into the set for which ``feeds`` is true. Those
    outside may wait on the set (a blocking receive of a non-blocking send); the slice of
    the set (:func:`slice_net`) has then all the set can do, and its own moves replay in the
    whole net with the rest standing still (:func:`replay_group`), as a group's do."""
    every = channels(net)
    keep = set(subsystems)
    todo = list(keep)
    while todo:
        s = todo.pop()
        for c in every:
            other = None
            if c.consumer == s and (c.consumer_waits or feeds(c)):
                other = c.producer
            elif c.producer == s and c.producer_waits:
                other = c.consumer
            if other is not None and other not in keep:
                keep.add(other)
                todo.append(other)
    return tuple(s for s in net.subsystems if s in keep) or tuple(sorted(keep))


@dataclass(frozen=True)
class Slice:
    """The slice of ``whole`` for the group ``keep``: ``net``, and per transition of ``net``
    the whole net's it is (-1: an environment move)."""

    whole: FlatNet
    net: FlatNet
    keep: frozenset[str]
    transition_of: tuple[int, ...]
    place_of: tuple[int, ...]
    cut: tuple[str, ...] = ()      # the free channels inside the group cut in two
    whole_inside: tuple[str, ...] = ()   # ... and those kept whole (``slice_net(cut=False)``)

    def whole_steps(self, steps: Sequence[FlatTransition]) -> list[int]:
        """The group's moves of a firing sequence of the slice, as the whole net's
        transitions (the environment's moves dropped)."""
        return [self.transition_of[t.index] for t in steps if self.transition_of[t.index] >= 0]


def slice_net(net: FlatNet, keep: Sequence[str], cut: bool = True,
              quiet: Collection[str] = (), uncut: Collection[str] = (),
              env_new: bool = False) -> Slice:
    """The slice of ``net`` for the group ``keep`` (the module docstring); with ``cut``
    false, the free channels inside the group are kept whole (both ends and the value they
    carry as in the whole net) instead of cut, each end with its own environment.

    ``quiet`` names channels across the border on which the group's end never waits and
    whose value nothing explored reads: the slice drops their two places and their
    environment. With the environment free to fill or empty them at any time, they only
    select between data cases that end in the same place (and new(x) of such an input is a
    free choice anyway), so the group can do what it could with them, and no more than a
    stuttering of it; each place dropped halves the slice's markings. ``uncut`` names free
    channels inside the group kept whole even when ``cut`` (the values they carry are read:
    cut, the consumer's environment would send any value).

    new(x) of an input the environment feeds is a free choice, or with ``env_new`` tracked
    as in the whole net: set by a receive that takes what the environment wrote. Both cover
    the whole net (the environment can fill the channel whenever its producer does, and a
    dropped channel's receive may take or find nothing at any time); tracked, a data case
    of the slice's path fires only after a receive, as it does in the whole net, so the
    path replays there with the producer sending (the properties' slices, userprops.py)."""
    group = frozenset(keep)
    quiet_chans = [c for c in channels(net) if c.name in quiet and _quiet(c, group)]
    gone = {p.index for p in net.places if p.subsystem is not None and p.subsystem not in group}
    gone.update(p for c in quiet_chans for p in (c.full, c.empty))
    kept_t: list[tuple[FlatTransition, tuple[int, ...], tuple[int, ...]]] = []
    for t in net.transitions:
        if t.subsystem is not None and t.subsystem not in group:
            continue
        pre = tuple(p for p in t.pre if p not in gone)
        post = tuple(p for p in t.post if p not in gone)
        if t.pre and not pre:
            continue            # plumbing waiting only for what is gone
        kept_t.append((t, pre, post))
    kept_t = _prune(kept_t, net.final, net.places)
    every = channels(net)
    silent = {c.name for c in quiet_chans}
    border = [c for c in every if (c.producer in group) != (c.consumer in group)
              and c.name not in silent]
    # a free channel inside the group is cut in two: the producer's end gets places of its
    # own, each end its environment (the data's freshness is all it carries, and that the
    # environment covers)
    inside = [c for c in every if c.free and c.producer in group and c.consumer in group]
    inner = [c for c in inside if c.name not in uncut] if cut else []
    copies: dict[int, int] = {}                # producer's place -> -(k + 1), a new place
    own: dict[str | None, dict[int, int]] = {}
    for k, c in enumerate(inner):
        copies[c.full], copies[c.empty] = -(2 * k + 1), -(2 * k + 2)
        own.setdefault(c.producer, {}).update({c.full: -(2 * k + 1), c.empty: -(2 * k + 2)})
    if own:
        kept_t = [(t, tuple(own.get(t.subsystem, {}).get(p, p) for p in pre),
                   tuple(own.get(t.subsystem, {}).get(p, p) for p in post))
                  for t, pre, post in kept_t]
    used = {p for _, pre, post in kept_t for p in (*pre, *post) if p >= 0}
    used.update(p for c in (*border, *inner) for p in (c.full, c.empty))
    place_of = tuple(sorted(used))
    new_index = {p: i for i, p in enumerate(place_of)}
    places = [dataclasses.replace(net.places[p], index=i) for i, p in enumerate(place_of)]
    initial = {new_index[p] for p in net.initial if p in new_index}
    for p, q in copies.items():
        new_index[q] = len(places)
        places.append(dataclasses.replace(net.places[p], index=len(places),
                                          name=net.places[p].name + "'"))
        place_of += (p,)
        if p in net.initial:
            initial.add(new_index[q])
    transitions: list[FlatTransition] = []
    transition_of: list[int] = []
    t_index: dict[int, int] = {}
    for t, pre, post in kept_t:
        t_index[t.index] = len(transitions)
        transitions.append(dataclasses.replace(
            t, index=len(transitions), pre=tuple(sorted(new_index[p] for p in pre)),
            post=tuple(sorted(new_index[p] for p in post))))
        transition_of.append(t.index)
    for c in border:
        transitions.append(_environment(net, c, c.producer not in group, len(transitions),
                                        new_index[c.full], new_index[c.empty]))
        transition_of.append(-1)
    for c in inner:
        transitions.append(_environment(net, c, True, len(transitions),
                                        new_index[c.full], new_index[c.empty]))
        transitions.append(_environment(net, c, False, len(transitions),
                                        new_index[copies[c.full]], new_index[copies[c.empty]]))
        transition_of += [-1, -1]
    sites = net.new_sites
    # new(x) of an input the environment feeds is a free choice: the environment may have
    # written any number of times since the last use, or not at all
    from_env = {c.name for c in (*border, *inner, *quiet_chans) if c.consumer in group}
    free = set() if env_new else {(sub, k) for t, sub, k in sites.receives
                                  if sub in group and net.transitions[t].channel in from_env}
    new_sites = NewSites(
        inputs=tuple(x for x in sites.inputs if x[0] in group),
        receives=tuple((t_index[t], s, k) for t, s, k in sites.receives if t in t_index),
        forks=tuple((t_index[t], s) for t, s in sites.forks if t in t_index),
        joins=tuple((t_index[t], s) for t, s in sites.joins if t in t_index),
        free=tuple(sorted(free | {x for x in sites.free if x[0] in group})))
    sliced = FlatNet(
        system=net.system, places=tuple(places), transitions=tuple(transitions),
        initial=frozenset(initial),
        final=frozenset(new_index[p] for p in net.final if p in new_index),
        subsystems=tuple(s for s in net.subsystems if s in group),
        pages=net.pages,
        conditions=tuple(dataclasses.replace(c, transition=t_index[c.transition])
                         for c in net.conditions if c.transition in t_index),
        new_sites=new_sites)
    return Slice(net, sliced, group, tuple(transition_of), place_of,
                 tuple(c.name for c in inner),
                 tuple(c.name for c in inside if c not in inner))


def _quiet(c: Channel, group: frozenset[str]) -> bool:
    """``c`` crosses the border of ``group`` and the group's end never waits on it."""
    if c.producer in group and c.consumer not in group:
        return not c.producer_waits
    if c.consumer in group and c.producer not in group:
        return not c.consumer_waits
    return False


def _never_waits_in(c: Channel, group: frozenset[str]) -> bool:
    """No end of ``c`` in ``group`` can wait on it."""
    return not ((c.producer in group and c.producer_waits)
                or (c.consumer in group and c.consumer_waits))


def _prune(kept: list[tuple[FlatTransition, tuple[int, ...], tuple[int, ...]]],
           final: frozenset[int], places: tuple[FlatPlace, ...],
           ) -> list[tuple[FlatTransition, tuple[int, ...], tuple[int, ...]]]:
    """Drop the system's plumbing for the agents the group is not in: a transition of no
    subsystem that puts nothing into the slice and is the only consumer of what it takes
    only empties places nobody else reads (the start of another agent), and a place of no
    subsystem that no transition of the slice takes and that is not final only collects
    tokens. Removing them
    changes no move of the group and no deadlock of the slice, and keeps each slice small as
    the system grows (those places lie in the slices of their own agents' groups)."""
    while True:
        consumers: dict[int, int] = {}
        for _, pre, _ in kept:
            for p in pre:
                consumers[p] = consumers.get(p, 0) + 1
        idle = [i for i, (t, pre, post) in enumerate(kept)
                if t.subsystem is None and not post and pre
                and all(consumers[p] == 1 for p in pre)]
        if idle:
            gone = set(idle)
            kept = [k for i, k in enumerate(kept) if i not in gone]
            continue
        sinks = {p for _, _, post in kept for p in post
                 if p not in consumers and p not in final and places[p].subsystem is None}
        if not sinks:
            return kept
        kept = [(t, pre, tuple(p for p in post if p not in sinks)) for t, pre, post in kept]


def _environment(net: FlatNet, c: Channel, writes: bool, index: int, full: int,
                 empty: int) -> FlatTransition:
    place: FlatPlace = net.places[c.full]
    outside = c.producer if writes else c.consumer
    verb = "sends" if writes else "takes"
    return FlatTransition(
        index=index, name=f"env[{c.name},{'write' if writes else 'take'}]",
        label=f"{outside} {verb} (environment of the slice, channel {c.name})",
        span=place.span, pre=(empty,) if writes else (full,),
        post=(full,) if writes else (empty,),
        role=Role.SEND if writes else Role.RECEIVE, channel=c.name)


# ------------------------------------------------------------------ back to the whole net


class ReplayError(Exception):
    pass


def replay_group(sl: Slice, steps: Sequence[int], marking: frozenset[int] | None = None,
                 ) -> tuple[list[int], frozenset[int]]:
    """The group's moves ``steps`` (whole-net transitions, in order) fired in the whole net
    with every subsystem outside the group standing still, from ``marking`` (default: the
    initial one); the firing sequence and the marking reached.

    With the outside still, a non-blocking receive from it finds no new data: where the slice
    took new data (``takes new x``, then ``has received x``), the whole net fires the
    receive's ``finds no new x`` instead and skips the ``has received``; a non-blocking send
    to it overwrites its unread value instead of starting on an empty buffer (or the other way
    round). Both lead the group to the same place. ``ReplayError`` when a step cannot fire."""
    net = sl.whole
    rule = net.rule
    m = set(net.initial if marking is None else marking)
    out: list[int] = []
    skip: set[int] = set()            # op places of receives replaced by "finds no new"
    ahead: dict[int, int] = {}        # steps fired early, to skip when their turn comes
    chans = channels(net)
    fulls = {c.name: c.full for c in chans}
    alt = _alternatives(net, sl.keep, chans)
    finish = _send_ends(net, sl.keep, chans)
    pending: list[int] = []           # plumbing steps waiting for the outside
    searched = 0                      # states the searches of the outside's moves took
    for t in steps:
        pre = net.transitions[t].pre
        if ahead.get(t):
            ahead[t] -= 1
            continue
        if skip.intersection(pre):
            skip.difference_update(pre)
            continue
        _fire_pending(net, m, pending, out)
        if not m.issuperset(pre) and net.transitions[t].subsystem is None \
                and _waits_outside(net, t, sl.keep):
            # the system's plumbing waiting for subsystems outside the group as well (an
            # agent's end: the slice has only the group's subsystems of it): it fires once
            # they are there, if ever; nothing of the group waits for it
            pending.append(t)
            continue
        if not m.issuperset(pre) and _swap(net, m, t, alt) is None:
            searched += _outside_first(sl, m, t, alt, OUTSIDE_STATES - searched, out)
        if not m.issuperset(pre):
            swap = _swap(net, m, t, alt)
            if swap is None:
                # a peer of the group between the two steps of a non-blocking send (the
                # slice cut that channel): its send ends first
                for u in finish:
                    if m.issuperset(rule.pre[u]):
                        m.difference_update(rule.consume[u])
                        m.update(rule.produce[u])
                        out.append(u)
                        ahead[u] = ahead.get(u, 0) + 1
                swap = t if m.issuperset(pre) else _swap(net, m, t, alt)
            if swap is None:
                raise ReplayError(f"{net.transitions[t].label} cannot fire (step "
                                  f"{steps.index(t) + 1} of the group's {len(steps)}; "
                                  f"{searched:,} states of the other subsystems' moves "
                                  "searched for a marking that enables it)")
            if swap != t and _is_take(net, t, fulls):
                skip.update(set(net.transitions[t].post) - set(net.transitions[swap].post))
            taken = swap != t and _is_take(net, swap, fulls)
            t = swap
            if taken:       # data where the slice found none: take it, then go on
                m.difference_update(rule.consume[t])
                m.update(rule.produce[t])
                out.append(t)
                t = _receive_end(net, t)
        m.difference_update(rule.consume[t])
        m.update(rule.produce[t])
        out.append(t)
    _fire_pending(net, m, pending, out)
    return out, frozenset(m)


OUTSIDE_STATES = 20_000     # markings a replay searches at most for the outside's moves


@dataclass(frozen=True)
class OutsideSearch:
    steps: list[int] | None     # the outside's moves to a marking that satisfies the goal
    states: int                 # markings searched


def outside_until(net: FlatNet, marking: set[int] | frozenset[int], group: frozenset[str],
                  goal: Callable[[frozenset[int]], bool], max_states: int,
                  ) -> OutsideSearch:
    """A breadth-first search over the moves of everything outside ``group`` (the other
    subsystems and the system's plumbing), the group standing still, from ``marking`` to a
    marking where ``goal`` holds; at most ``max_states`` markings."""
    rule = net.rule
    movers = [t.index for t in net.transitions if t.subsystem not in group]
    start = frozenset(marking)
    if goal(start):
        return OutsideSearch([], 1)
    parent: dict[frozenset[int], tuple[frozenset[int], int] | None] = {start: None}
    frontier = [start]
    while frontier and len(parent) < max_states:
        nxt: list[frozenset[int]] = []
        for m in frontier:
            for u in movers:
                if not m.issuperset(rule.pre[u]):
                    continue
                m2 = m.difference(rule.consume[u]).union(rule.produce[u])
                if m2 in parent:
                    continue
                parent[m2] = (m, u)
                if goal(m2):
                    path: list[int] = []
                    at: frozenset[int] = m2
                    while (link := parent[at]) is not None:
                        at, step = link
                        path.append(step)
                    return OutsideSearch(path[::-1], len(parent))
                nxt.append(m2)
                if len(parent) >= max_states:
                    break
        frontier = nxt
    return OutsideSearch(None, len(parent))


def _waits_outside(net: FlatNet, t: int, group: frozenset[str]) -> bool:
    """Plumbing ``t`` takes a place of a subsystem outside ``group``."""
    return any(net.places[p].subsystem is not None and net.places[p].subsystem not in group
               for p in net.transitions[t].pre)


def _outside_first(sl: Slice, m: set[int], t: int, alt: dict[int, list[int]],
                   max_states: int, out: list[int]) -> int:
    """The rest of the system may have to move first (a step of the group that needs what
    the slice's environment gave it at once): a bounded search of the outside's moves until
    ``t``, or a sibling of it, is enabled; its steps fired (``m``, ``out``). The markings
    searched."""
    net = sl.whole
    rule = net.rule

    def enabled(mm: frozenset[int]) -> bool:
        return mm.issuperset(rule.pre[t]) or _swap(net, set(mm), t, alt) is not None

    found = outside_until(net, m, sl.keep, enabled, max_states)
    for u in found.steps or ():
        m.difference_update(rule.consume[u])
        m.update(rule.produce[u])
        out.append(u)
    return found.states


def _fire_pending(net: FlatNet, m: set[int], pending: list[int], out: list[int]) -> None:
    """Fire the plumbing steps put aside that are enabled now, in their order."""
    rule = net.rule
    fired = True
    while fired:
        fired = False
        for u in list(pending):
            if m.issuperset(rule.pre[u]):
                m.difference_update(rule.consume[u])
                m.update(rule.produce[u])
                out.append(u)
                pending.remove(u)
                fired = True


def _receive_end(net: FlatNet, take: int) -> int:
    """The step after ``take`` (``in + full -> op``): the one from its op place alone."""
    op = set(net.transitions[take].post)
    sub = net.transitions[take].subsystem
    for u in net.rule.consumers[min(op)]:
        if net.transitions[u].subsystem == sub and set(net.transitions[u].pre) == op:
            return u
    raise ReplayError(f"no end for {net.transitions[take].label}")


def _swap(net: FlatNet, m: set[int], t: int, alt: dict[int, list[int]]) -> int | None:
    """An enabled sibling of ``t`` on a free channel, or None."""
    return next((u for u in alt.get(t, ()) if m.issuperset(net.transitions[u].pre)), None)


def _send_ends(net: FlatNet, group: frozenset[str], chans: list[Channel]) -> list[int]:
    """The group's last steps of non-blocking sends on free channels (``op -> out + full``)."""
    free = {c.name: c for c in chans if _never_waits_in(c, group)}
    return [t.index for t in net.transitions
            if t.subsystem in group and t.role is Role.SEND and t.channel in free
            and free[t.channel].full in t.post and free[t.channel].full not in t.pre
            and free[t.channel].empty not in t.pre]


def _is_take(net: FlatNet, t: int, fulls: dict[str, int]) -> bool:
    """``t`` is a receive taking new data (``in + full -> op``)."""
    tr = net.transitions[t]
    return tr.role is Role.RECEIVE and fulls.get(tr.channel or "") in tr.pre


def _alternatives(net: FlatNet, group: frozenset[str], chans: list[Channel],
                  ) -> dict[int, list[int]]:
    """Per transition of the group touching a free channel: its siblings taking the other
    place of the channel from the same places."""
    out: dict[int, list[int]] = {}
    by_pre: dict[tuple[str | None, frozenset[int]], list[int]] = {}
    for t in net.transitions:
        if t.subsystem in group:
            by_pre.setdefault((t.subsystem, frozenset(t.pre)), []).append(t.index)
    for c in chans:
        if not _never_waits_in(c, group):
            continue
        for t in net.transitions:
            if t.subsystem not in group:
                continue
            for x, y in ((c.full, c.empty), (c.empty, c.full)):
                if x in t.pre:
                    key = (t.subsystem, frozenset(t.pre) - {x} | {y})
                    out.setdefault(t.index, []).extend(by_pre.get(key, []))
    return out


def fire_steps(net: FlatNet, m: frozenset[int], steps: Sequence[int]) -> frozenset[int]:
    """The marking ``steps`` lead to from ``m`` (fired as given, not checked)."""
    rule = net.rule
    out = set(m)
    for t in steps:
        out.difference_update(rule.consume[t])
        out.update(rule.produce[t])
    return frozenset(out)


def run_outside(net: FlatNet, marking: frozenset[int], group: frozenset[str],
                max_steps: int = 100_000) -> tuple[list[int], list[int], bool]:
    """What the rest of the system does while ``group`` stands still: from ``marking``, the
    subsystems outside the group (and the system's plumbing) fire in turn, one enabled
    transition each (the lowest), until the marking and turn repeat. Returns the steps to the
    start of the cycle, the cycle, and whether the run stopped instead in a marking where
    nothing outside can fire (``cycle`` is then empty)."""
    rule = net.rule
    movers = sorted({t.subsystem or "" for t in net.transitions if t.subsystem not in group})
    by_mover: dict[str, list[int]] = {s: [] for s in movers}
    for t in net.transitions:
        if t.subsystem not in group:
            by_mover[t.subsystem or ""].append(t.index)
    m = set(marking)
    seen: dict[tuple[frozenset[int], int], int] = {(frozenset(m), 0): 0}
    steps: list[int] = []
    turn = 0
    while len(steps) < max_steps:
        fired = None
        for _ in movers:              # the next mover in turn that can fire
            s = movers[turn]
            turn = (turn + 1) % len(movers)
            fired = next((t for t in by_mover[s] if m.issuperset(rule.pre[t])), None)
            if fired is not None:
                break
        if fired is None:
            return steps, [], True
        m.difference_update(rule.consume[fired])
        m.update(rule.produce[fired])
        steps.append(fired)
        key = (frozenset(m), turn)
        if key in seen:
            k = seen[key]
            return steps[:k], steps[k:], False
        seen[key] = len(steps)
    raise ReplayError(f"no repetition within {max_steps} steps")
