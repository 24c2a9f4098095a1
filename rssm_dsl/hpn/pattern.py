"""The behaviour pattern as the HPN states it, for backends that do not run the net itself
(the ROS 2 generator): the steps of one iteration of a behaviour in the order its page's net
runs them, and the arrangement of each send and receive page, recovered from the page's net.

A behaviour page sH^B_{j,v,omega} is a chain from its input place to the place its
iteration and termination transitions leave from (paper IV): the transition function page
P^f, the send page P_snd, the place of ``i := i + 1``, the receive page P_rcv (either
communication page may be absent). :func:`iteration` follows that chain.

A communication page holds one mode page per buffer between its transitions ``t_in`` and
``t_out``, joined by transitions that sequence them; every mode page has exactly one
transition before and one after it. :func:`arrangement` recovers the series-parallel term by
reduction: two mode pages between the same two transitions run in parallel; a transition
with one page before and one after it puts them in sequence.
"""

from __future__ import annotations

from rssm_core.records import dataclass
from rssm_dsl.hpn.ir import HPN, CondKind, HpnIndex, OpKind, Page, PageKind
from rssm_dsl.semantics.model import Arrangement, ArrLeaf, ArrPar, ArrSeq


@dataclass(frozen=True)
class Compute:
    """P^f: every partial transition function from the pre-state, then the commit."""

    page: Page


@dataclass(frozen=True)
class Send:
    page: Page
    arrangement: Arrangement


@dataclass(frozen=True)
class Increment:
    """The place of ``i := i + 1``."""

    place: str


@dataclass(frozen=True)
class Receive:
    page: Page
    arrangement: Arrangement


Step = Compute | Send | Increment | Receive


class PatternError(Exception):
    """The net of a page does not have the shape the pattern needs (a compiler bug)."""


def behaviour_pages(hpn: HPN, subsystem_page: str) -> tuple[Page, ...]:
    """The behaviour pages of a subsystem page, in the order of the IR."""
    return tuple(p for p in hpn.index().children(subsystem_page)
                 if p.kind is PageKind.BEHAVIOUR)


def iteration(hpn: HPN, page: Page) -> tuple[Step, ...]:
    """The steps of one iteration of the behaviour of ``page``, in the order the net runs
    them, up to where the terminal and error conditions are evaluated."""
    idx = hpn.index()
    steps: list[Step] = []
    node = page.in_place
    seen = {node}
    while True:
        after = [a.target for a in idx.out_of(node) if a.page == page.id]
        if any(_ends_iteration(hpn, t) for t in after):
            return tuple(steps)
        if len(after) != 1:
            raise PatternError(f"{node} in {page.id}: {len(after)} transitions follow it")
        outs = [a.target for a in idx.out_of(after[0]) if a.page == page.id]
        if len(outs) != 1 or outs[0] in seen:
            raise PatternError(f"{after[0]} in {page.id} does not lead to one new node")
        node = outs[0]
        seen.add(node)
        steps.append(_step(hpn, idx, node))


def _ends_iteration(hpn: HPN, transition: str) -> bool:
    t = hpn.transitions.get(transition)
    return (t is not None and t.condition is not None
            and t.condition.kind in (CondKind.CONTINUE, CondKind.STOP))


def _step(hpn: HPN, idx: HpnIndex, node: str) -> Step:
    sub = hpn.pages.get(node)
    if sub is not None:
        match sub.kind:
            case PageKind.FUNCTION:
                return Compute(sub)
            case PageKind.SEND:
                return Send(sub, arrangement(hpn, sub))
            case PageKind.RECEIVE:
                return Receive(sub, arrangement(hpn, sub))
    place = hpn.places.get(node)
    if place is not None and place.operation is not None \
            and place.operation.kind is OpKind.INCREMENT:
        return Increment(node)
    raise PatternError(f"{node} is not a step of the behaviour pattern")


def arrangement(hpn: HPN, page: Page) -> Arrangement:
    """The series-parallel arrangement of the mode pages of a send or receive page."""
    idx = hpn.index()
    net = idx.net(page.id)
    terms: dict[int, Arrangement] = {}
    before: dict[int, str] = {}
    after: dict[int, str] = {}
    for k, child in enumerate(net.children):
        terms[k] = ArrLeaf(_buffer(idx, child), child.span)
        (pre,) = [a.source for a in idx.into(child.id) if a.page == page.id]
        (post,) = [a.target for a in idx.out_of(child.id) if a.page == page.id]
        before[k], after[k] = pre, post
    if not terms:
        raise PatternError(f"{page.id} has no mode pages")
    fresh = len(terms)
    while len(terms) > 1:
        fresh, changed = _parallel(terms, before, after, fresh)
        fresh, sequenced = _series(terms, before, after, fresh)
        if not (changed or sequenced):
            raise PatternError(f"the net of {page.id} is not series-parallel")
    (term,) = terms.values()
    return term


def _parallel(terms: dict[int, Arrangement], before: dict[int, str], after: dict[int, str],
              fresh: int) -> tuple[int, bool]:
    """Merge the nodes that lie between the same two transitions."""
    groups: dict[tuple[str, str], list[int]] = {}
    for k in terms:
        groups.setdefault((before[k], after[k]), []).append(k)
    changed = False
    for (pre, post), ks in groups.items():
        if len(ks) < 2:
            continue
        items = [x for k in ks for x in _flat(terms.pop(k), ArrPar)]
        for k in ks:
            del before[k], after[k]
        terms[fresh] = ArrPar(tuple(items), items[0].span)
        before[fresh], after[fresh] = pre, post
        fresh += 1
        changed = True
    return fresh, changed


def _series(terms: dict[int, Arrangement], before: dict[int, str], after: dict[int, str],
            fresh: int) -> tuple[int, bool]:
    """Merge x and y where a transition has x alone before it and y alone after it."""
    ins: dict[str, list[int]] = {}
    outs: dict[str, list[int]] = {}
    for k in terms:
        ins.setdefault(after[k], []).append(k)
        outs.setdefault(before[k], []).append(k)
    for t, xs in ins.items():
        ys = outs.get(t, [])
        if len(xs) == 1 and len(ys) == 1:
            (x,), (y,) = xs, ys
            items = [*_flat(terms[x], ArrSeq), *_flat(terms[y], ArrSeq)]
            terms[fresh] = ArrSeq(tuple(items), items[0].span)
            before[fresh], after[fresh] = before[x], after[y]
            for k in (x, y):
                del terms[k], before[k], after[k]
            return fresh + 1, True
    return fresh, False


def _flat(term: Arrangement, kind: type[ArrSeq] | type[ArrPar]) -> tuple[Arrangement, ...]:
    return term.items if isinstance(term, kind) else (term,)


def _buffer(idx: HpnIndex, mode_page: Page) -> str:
    """The buffer a mode page sends or receives (the target of its operation)."""
    for place in idx.net(mode_page.id).places:
        op = place.operation
        if op is not None and op.kind in (OpKind.SEND, OpKind.RECEIVE) and op.target:
            return op.target
    # an unconnected device buffer's page has no operation: its label names the buffer
    raise PatternError(f"mode page {mode_page.id} has no send or receive operation")
