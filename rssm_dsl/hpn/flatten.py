"""Flatten the HPN into a plain safe P/T net: an arc into a page goes to its input place,
an arc out of a page leaves from its output place, a fusion set is one place, and a
transition whose condition is constant false (e.g. t_out of `terminal never when false`)
is left out. The conditions that are not constant are listed (``FlatNet.conditions``), with
the transitions where new(x) is set, frozen and used (``FlatNet.new_sites``): the verifier
tracks new(x) in the state from them (rssm_dsl/verify/datanet.py), the interpreter binds them
itself (rssm_dsl/interp/program.py)."""

from __future__ import annotations

from rssm_core.records import dataclass
from rssm_dsl.hpn.flat import FlatCondition, FlatNet, FlatPage, FlatPlace, FlatTransition, NewSites
from rssm_dsl.hpn.ir import HPN, Condition, CondKind, OpKind, Page, PageKind


def _subsystem_of(hpn: HPN, page: str) -> tuple[str | None, str | None]:
    p = hpn.pages[page]
    if p.kind.value in ("system", "agent"):
        return None, None
    return p.owner, p.behaviour


@dataclass(frozen=True, slots=True)
class FlatStructure:
    """The places and arcs of the flattened net, without what it binds to them: what
    :func:`flatten` starts from, and all the flat PNML shows (rssm_dsl/emit/pnml.py)."""

    flat_of: dict[str, str]            # IR place -> the flat place it is (its fusion set)
    names: list[str]                   # the flat places' names, by index (sorted)
    index: dict[str, int]              # flat place name -> index
    transitions: list[str]             # the IR transitions kept, in the flat net's order
    pre: dict[str, set[int]]           # IR transition -> its input places (indices)
    post: dict[str, set[int]]          # IR transition -> its output places


def flat_structure(hpn: HPN) -> FlatStructure:
    """The places of the flattened net (a fusion set is one place; sorted by name), the
    transitions kept (by name; a constant false condition leaves one out), and each IR
    transition's pre- and post-set among the flat places (an arc into a page goes to its
    input place, an arc out of a page leaves from its output place)."""
    flat_of = {pid: place.fusion or pid for pid, place in hpn.places.items()}
    names = sorted(set(flat_of.values()))
    index = dict(zip(names, range(len(names)), strict=True))
    # the flat place each node stands for as the source of an arc (a page: its output
    # place) and as its target (a page: its input place)
    at = dict(zip(flat_of, map(index.__getitem__, flat_of.values()), strict=True))
    source, target = dict(at), at
    for pid, page in hpn.pages.items():
        out, into = page.out_place, page.in_place       # (places, unless hand-made)
        source[pid] = at[out] if out in at and out not in hpn.pages else \
            _resolve(hpn, pid, at, entering=False)
        target[pid] = at[into] if into in at and into not in hpn.pages else \
            _resolve(hpn, pid, at, entering=True)
    pre: dict[str, set[int]] = {t: set() for t in hpn.transitions}
    post: dict[str, set[int]] = {t: set() for t in hpn.transitions}
    for a in hpn.arcs:
        if a.target in pre:
            pre[a.target].add(source[a.source])
        else:
            post[a.source].add(target[a.target])
    table = hpn.transitions
    kept = [tid for tid in sorted(table)
            if (c := table[tid].condition) is None or c.constant is not False]
    return FlatStructure(flat_of, names, index, kept, pre, post)


def _resolve(hpn: HPN, node: str, at: dict[str, int], entering: bool) -> int:
    """The flat place an arc into (``entering``) or out of a page goes to or leaves from."""
    while node in hpn.pages:
        page = hpn.pages[node]
        node = page.in_place if entering else page.out_place
    return at[node]


def flat_initial(hpn: HPN, st: FlatStructure) -> frozenset[int]:
    """The flat places marked initially."""
    return frozenset(st.index[st.flat_of[p.id]] for p in hpn.places.values() if p.initial)


def flatten(hpn: HPN) -> FlatNet:
    # (subsystem, behaviour) of each page, once per page, not once per element
    owned = {pid: _subsystem_of(hpn, pid) for pid in hpn.pages}
    st = flat_structure(hpn)
    flat_of, names, index, pre, post = st.flat_of, st.names, st.index, st.pre, st.post

    places: list[FlatPlace] = []
    for n in names:
        if n in hpn.fusions:
            fs = hpn.fusions[n]
            on = [hpn.pages[hpn.places[m].page] for m in fs.places]
            consumer = [pg.id for pg in on if pg.kind is PageKind.RECEIVE_BUFFER]
            places.append(FlatPlace(index[n], n, fs.label, fs.span, fs.places, None, None, None,
                                    fs.channel, (consumer or [pg.id for pg in on])[0]))
            continue
        p = hpn.places[n]
        sub, beh = owned[p.page]
        op = p.operation
        places.append(FlatPlace(index[n], n, p.label, p.span, (n,),
                                n if op is not None else None, sub, beh,
                                op.channel if op is not None else None, p.page))

    transitions: list[FlatTransition] = []
    conditions: list[FlatCondition] = []
    choices = _choices(hpn)
    for tid in st.transitions:
        t = hpn.transitions[tid]
        if tid in choices:
            c = choices[tid]
            conditions.append(FlatCondition(len(transitions), c.kind.value, c.text,
                                            c.new if c.kind is CondKind.CASE else None))
        sub, beh = owned[t.page]
        channel = None
        for pl in pre[tid] | post[tid]:
            channel = channel or places[pl].channel
        transitions.append(FlatTransition(
            len(transitions), tid, t.label, t.span, tuple(sorted(pre[tid])),
            tuple(sorted(post[tid])), t.role, tid if t.condition is not None else None,
            sub, beh, channel,
        ))

    initial = flat_initial(hpn, st)
    final = frozenset({index[flat_of[hpn.pages[hpn.root].out_place]]})
    subsystems = tuple(sorted({p.owner for p in hpn.pages.values()
                               if p.kind.value in ("subsystem", "device")}))
    depth: dict[str, int] = {}

    def level(pid: str) -> int:
        if pid not in depth:
            parent = hpn.pages[pid].parent
            depth[pid] = 0 if parent is None else level(parent) + 1
        return depth[pid]

    # the agent of a page is the owner of the agent page P[j] of its scope's j
    agents = {pg.key.scope.j: pg.owner for pg in hpn.pages.values()
              if pg.kind is PageKind.AGENT and pg.key is not None}

    def agent(pg: Page) -> str | None:
        return agents.get(pg.key.scope.j) if pg.key is not None and pg.key.scope.j else None

    hierarchy = tuple(FlatPage(pg.id, pg.parent, pg.kind.value, pg.owner, agent(pg))
                      for pg in sorted(hpn.pages.values(), key=lambda pg: (level(pg.id), pg.id)))
    return FlatNet(hpn.system, tuple(places), tuple(transitions), initial, final, subsystems,
                   hierarchy, tuple(conditions),
                   _new_sites(hpn, {t.name: t.index for t in transitions}))


def _choices(hpn: HPN) -> dict[str, Condition]:
    """The conditions that choose between transitions: those not known without data, and
    an `otherwise` switch (constant true) beside another switch from the same behaviour."""
    switches: dict[tuple[str, str | None], int] = {}
    for t in hpn.transitions.values():
        c = t.condition
        if c is not None and c.kind is CondKind.SWITCH and c.constant is not False:
            switches[c.subsystem, c.behaviour] = switches.get((c.subsystem, c.behaviour), 0) + 1
    out: dict[str, Condition] = {}
    for t in hpn.transitions.values():
        c = t.condition
        if c is None or c.constant is False or (
                c.kind is CondKind.CASE and all(v is None for v in c.new or ())):
            continue                  # not a choice (the one case of a function: no split)
        if c.constant is None or (c.kind is CondKind.SWITCH
                                  and switches[c.subsystem, c.behaviour] > 1):
            out[t.id] = c
    return out


def _new_sites(hpn: HPN, tindex: dict[str, int]) -> NewSites:
    """The receives into the inputs of every subsystem (by the input's index k: the mode
    page's kappa - 1, the order of the data cases' new(x)), and the forks and joins of their
    transition functions."""
    subsystems = {pg.owner for pg in hpn.pages.values() if pg.kind is PageKind.SUBSYSTEM}
    index = hpn.index()
    names: dict[str, dict[int, str]] = {}
    receives: list[tuple[int, str, int]] = []
    for pl in hpn.places.values():
        op = pl.operation
        page = hpn.pages[pl.page]
        if (op is None or op.kind is not OpKind.RECEIVE or op.subsystem not in subsystems
                or page.key is None or page.key.scope.k is None or op.target is None):
            continue
        k = page.key.scope.k - 1
        names.setdefault(op.subsystem, {})[k] = op.target
        receives += [(tindex[a.target], op.subsystem, k) for a in index.out_of(pl.id)
                     if a.target in tindex]
    forks: list[tuple[int, str]] = []
    joins: list[tuple[int, str]] = []
    for pg in hpn.pages.values():
        if pg.kind is not PageKind.FUNCTION or pg.owner not in subsystems:
            continue
        forks += [(tindex[a.target], pg.owner) for a in index.out_of(pg.in_place)
                  if a.target in tindex]
        joins += [(tindex[a.source], pg.owner) for a in index.into(pg.out_place)
                  if a.source in tindex]
    inputs = tuple((sub, tuple(ks.get(k, f"input {k + 1}") for k in range(max(ks) + 1)))
                   for sub, ks in sorted(names.items()))
    return NewSites(inputs, tuple(sorted(receives)), tuple(sorted(forks)), tuple(sorted(joins)))
