"""The hierarchical Petri net IR: flat tables of pages, places, transitions and arcs.

Hierarchy is held as indices: every place, transition and arc belongs to the page whose net
contains it, every page names its parent page (the net it appears in as a node) and its
own input and output places. Element ids are their names in the paper's notation, e.g.
`p[1,lwr,move,rcv,2,in]`, `t[1,c,cw,4]`, `P^B[1,c,cw]`, so they are unique and readable.

Every element the compiler builds also carries its name as data (`key`): a :class:`Name`
holding the indices of the paper's notation by meaning (agent j, subsystem v, behaviour
omega, partial function psi or snd/rcv, buffer index, and the element's own indices on its
page); a fused place's name is a :class:`FusionName`. The printed id is derived from it
(``str(key) == id``), so consumers read the parts and never parse id strings.

Lookups go through :meth:`HPN.index`, built once in one pass over the tables and cached
until a table changes: page -> its net (places, transitions, sub-pages, arcs), node -> arcs
into and out of it, id -> element.

Layers (paper II-IV): 1 system H, 2 agent H_j, 3 subsystem sH_{j,v}, 4 behaviour
sH^B_{j,v,omega}, 5 action (sublayer 1: canonical decomposition / arrangement; sublayer 2:
data availability / communication mode). Device nets close the net for verification and
simulation; they are not part of H.
"""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import field
from enum import Enum
from typing import Any, ClassVar, NamedTuple, SupportsIndex, TypeVar

from rssm_core.records import dataclass
from rssm_dsl.hpn.flat import Role
from rssm_dsl.source import Span


class PageKind(str, Enum):
    SYSTEM = "system"                  # H
    AGENT = "agent"                    # P_j
    SUBSYSTEM = "subsystem"            # P_{j,v}
    BEHAVIOUR = "behaviour"            # P^B_{j,v,omega}
    FUNCTION = "function"              # P^f_{j,v,omega}
    PARTIAL = "partial"                # P^f_{j,v,omega,psi}
    SEND = "send"                      # P^B_{j,v,omega,snd}
    SEND_BUFFER = "send_buffer"        # P^B_{j,v,omega,snd,rho}
    RECEIVE = "receive"                # P^B_{j,v,omega,rcv}
    RECEIVE_BUFFER = "receive_buffer"  # P^B_{j,v,omega,rcv,kappa}
    DEVICE = "device"                  # device net of E_{j,h} / R_{j,l}


# The layer of the net that defines a page of each kind, and its sublayer.
LAYER: dict[PageKind, tuple[int, int]] = {
    PageKind.SYSTEM: (1, 0), PageKind.AGENT: (2, 0), PageKind.SUBSYSTEM: (3, 0),
    PageKind.BEHAVIOUR: (4, 0), PageKind.FUNCTION: (5, 1), PageKind.SEND: (5, 1),
    PageKind.RECEIVE: (5, 1), PageKind.PARTIAL: (5, 2), PageKind.SEND_BUFFER: (5, 2),
    PageKind.RECEIVE_BUFFER: (5, 2), PageKind.DEVICE: (0, 0),
}


# ---------------------------------------------------------------------- structured names

Part = str | int
"""One index of the paper's notation: a designator or name (`1`, `lwr`, `move`, `snd`,
`in`, `op`) or a number (psi, a buffer index, a case, a step of the behaviour pattern)."""


@dataclass(frozen=True, slots=True)
class Scope:
    """Where a page lies in the hierarchy, by the paper's indices (None: not that deep).

    A page's index extends its parent's by the part its kind adds: an agent page adds j,
    a subsystem page v, a behaviour page omega, a partial function page psi (`action`),
    an arrangement page snd/rcv (`action`), a mode page the buffer's index k (rho or kappa);
    a device net starts at (j, v); the transition function page P^f adds nothing."""

    j: str | None = None            # agent a_j (its designator)
    v: str | None = None            # subsystem or device of the agent
    omega: str | None = None        # behaviour
    action: Part | None = None      # psi (partial function) or "snd" / "rcv"
    k: int | None = None            # buffer index of a mode page: rho (snd) / kappa (rcv)
    parts: tuple[Part, ...] = field(init=False, repr=False, compare=False)
    # the indices that are set, in the order they are printed

    def __post_init__(self) -> None:
        object.__setattr__(self, "parts", tuple(
            x for x in (self.j, self.v, self.omega, self.action, self.k) if x is not None))

    @property
    def psi(self) -> int | None:
        return self.action if isinstance(self.action, int) else None

    @property
    def verb(self) -> str | None:
        """"snd" or "rcv" on communication pages, else None."""
        return self.action if isinstance(self.action, str) else None

    def below(self, kind: PageKind, added: tuple[Part, ...]) -> Scope:
        """The scope of a page of ``kind`` whose index extends this one by ``added``."""
        match kind, added:
            case (PageKind.SYSTEM | PageKind.FUNCTION), ():
                return self
            case PageKind.AGENT, (str() as j,):
                return Scope(j)
            case PageKind.SUBSYSTEM, (str() as v,):
                return Scope(self.j, v)
            case PageKind.DEVICE, (str() as j, str() as v):
                return Scope(j, v)
            case PageKind.BEHAVIOUR, (str() as omega,):
                return Scope(self.j, self.v, omega)
            case PageKind.PARTIAL, (int() as psi,):
                return Scope(self.j, self.v, self.omega, psi)
            case (PageKind.SEND | PageKind.RECEIVE), (str() as verb,):
                return Scope(self.j, self.v, self.omega, verb)
            case (PageKind.SEND_BUFFER | PageKind.RECEIVE_BUFFER), (int() as k,):
                return Scope(self.j, self.v, self.omega, self.action, k)
        raise ValueError(f"a {kind.value} page cannot extend {self.parts} by {added}")


SYSTEM_SCOPE = Scope()


class Name(NamedTuple):
    """The name of a page, place or transition in the paper's notation, by its parts.

    ``parts`` are the indices as printed; ``scope`` is the page the element lies on (for a
    page: the page itself) and reads the leading parts by meaning; ``local`` are the rest,
    the element's own indices on its page. So `p[1,lwr,move,rcv,2,in]` lies in scope
    j=1, v=lwr, omega=move, action=rcv, k=2 with local ("in",), and `t[1,c,cw,4]` in
    j=1, v=c, omega=cw with local (4,). ``text`` is the printed id (also ``str(name)``):
    symbol, superscript, then the indices in brackets; the system page is just `H`.

    Make names with :meth:`of` (which prints them); the functions of
    :mod:`rssm_dsl.hpn.names` make them at system scope (every index local), and the
    builder gives a name its page's scope (:meth:`within`) when it makes the element."""

    symbol: str                         # "p" place, "t" transition, "P" page, "H" system page
    sup: str                            # superscript: "", "^B", "^f", "^E", "^R"
    parts: tuple[Part, ...]
    scope: Scope
    text: str

    @staticmethod
    def of(symbol: str, sup: str = "", parts: tuple[Part, ...] = (),
           scope: Scope = SYSTEM_SCOPE) -> Name:
        lead = scope.parts
        if lead and parts[:len(lead)] != lead:
            raise ValueError(f"{parts} does not lie within {lead}")
        text = "H" if symbol == "H" else f"{symbol}{sup}[{','.join(map(str, parts))}]"
        return Name(symbol, sup, parts, scope, text)

    def __str__(self) -> str:
        return self.text

    @property
    def local(self) -> tuple[Part, ...]:
        """The indices after the scope's: the element's own on its page."""
        return self.parts[len(self.scope.parts):]

    def within(self, scope: Scope) -> Name:
        """This name read in ``scope``, whose indices must be its leading parts."""
        if self.scope is scope:
            return self
        lead = scope.parts
        if self.parts[:len(lead)] != lead:
            raise ValueError(f"{self.text} does not lie within {lead}")
        return tuple.__new__(Name, (self.symbol, self.sup, self.parts, scope, self.text))


@dataclass(frozen=True, slots=True)
class FusionName:
    """The fused place of a channel, p^fusion[(j,j'),(v,h),(snd,rcv),(rho,kappa),which]:
    producer and consumer agent, subsystem (or `E.h` / `R.l` for a device), buffer index,
    and which of the channel's two places it is (1 full: data not yet taken; 2 empty)."""

    FULL: ClassVar[int] = 1
    EMPTY: ClassVar[int] = 2

    agents: tuple[str, str]
    subsystems: tuple[str, str]
    indices: tuple[int, int]
    which: int
    text: str = field(init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        a, s, i = self.agents, self.subsystems, self.indices
        object.__setattr__(self, "text", f"p^fusion[({a[0]},{a[1]}),({s[0]},{s[1]}),"
                                         f"(snd,rcv),({i[0]},{i[1]}),{self.which}]")

    def __str__(self) -> str:
        return self.text

    @property
    def full(self) -> bool:
        return self.which == FusionName.FULL


# ---------------------------------------------------------------------- elements

class OpKind(str, Enum):
    INCREMENT = "increment"    # O_{j,v,omega,2}: i := i + 1
    CASE = "case"              # a data-availability case of a partial function
    SEND = "send"              # copy an output buffer into the channel
    RECEIVE = "receive"        # copy the channel into an input buffer
    DEVICE = "device"          # one step of a device
    NONE = "none"


@dataclass(frozen=True, slots=True)
class Operation:
    kind: OpKind
    subsystem: str                     # qualified id of the owner ("a1.e.lwr", "a1.E.lwr")
    text: str                          # what it does, in the DSL's words
    behaviour: str | None = None
    target: str | None = None          # partial function target / buffer name
    case: int | None = None            # varpi for CASE
    channel: str | None = None
    void: bool = False


class CondKind(str, Enum):
    CASE = "case"              # new(x) combination of a data-availability case
    CONTINUE = "continue"      # t_4: not f^tau and not f^eps
    STOP = "stop"              # t_out: f^tau or f^eps
    SWITCH = "switch"          # f^sigma of a behaviour switch


@dataclass(frozen=True, slots=True)
class Condition:
    kind: CondKind
    subsystem: str
    text: str
    behaviour: str | None = None
    new: tuple[bool | None, ...] | None = None  # CASE: new(x) per input buffer (None: not
                                               # split, rssm_dsl/semantics/cases.py)
    switch: int | None = None              # SWITCH: alpha
    constant: bool | None = None           # known without data (e.g. `terminal never when
                                           # false` makes t_out's condition constant false)


@dataclass(frozen=True, slots=True)
class Page:
    id: str
    kind: PageKind
    parent: str | None
    in_place: str
    out_place: str
    span: Span
    label: str
    owner: str                         # system / agent / subsystem id the page belongs to
    behaviour: str | None = None
    key: Name | None = None            # the id by its parts (None only in hand-made nets)

    @property
    def layer(self) -> int:
        return LAYER[self.kind][0]

    @property
    def sublayer(self) -> int:
        return LAYER[self.kind][1]


@dataclass(frozen=True, slots=True)
class Place:
    id: str
    page: str
    span: Span
    label: str
    operation: Operation | None = None
    fusion: str | None = None          # id of the fusion set it belongs to
    initial: bool = False
    key: Name | None = None            # the id by its parts (None only in hand-made nets)


@dataclass(frozen=True, slots=True)
class Transition:
    id: str
    page: str
    span: Span
    label: str
    role: Role = Role.STRUCTURE
    condition: Condition | None = None
    key: Name | None = None            # the id by its parts (None only in hand-made nets)


@dataclass(frozen=True, slots=True)
class Arc:
    page: str
    source: str                        # place, transition or page id
    target: str


@dataclass(frozen=True, slots=True)
class FusionSet:
    """Places shown in several nets that are one place (paper II, Fig. 5)."""

    id: str                            # the fused place's name, p^fusion[...]
    label: str
    channel: str
    places: tuple[str, ...]
    initial: bool
    span: Span
    key: FusionName | None = None      # the id by its parts (None only in hand-made nets)


Element = Page | Place | Transition | FusionSet


# ---------------------------------------------------------------------- tables that count changes

_V = TypeVar("_V")
_T = TypeVar("_T")


class Table(dict[str, _V]):
    """A dict of IR elements by id that counts its changes, so that :meth:`HPN.index` knows
    when its cached index is out of date. Reading is a plain dict's."""

    changes: int = 0

    def __setitem__(self, key: str, value: _V) -> None:
        self.changes += 1
        dict.__setitem__(self, key, value)

    def __delitem__(self, key: str) -> None:
        self.changes += 1
        super().__delitem__(key)

    def __ior__(self, other: Any) -> Table[_V]:  # type: ignore[override,misc]
        self.changes += 1
        super().__ior__(other)
        return self

    def clear(self) -> None:
        self.changes += 1
        super().clear()

    def pop(self, *args: Any) -> Any:  # type: ignore[override]
        self.changes += 1
        return super().pop(*args)

    def popitem(self) -> tuple[str, _V]:
        self.changes += 1
        return super().popitem()

    def setdefault(self, key: str, default: Any = None) -> Any:  # type: ignore[override]
        self.changes += 1
        return super().setdefault(key, default)

    def update(self, *args: Any, **kwargs: Any) -> None:  # type: ignore[override]
        self.changes += 1
        super().update(*args, **kwargs)


class TrackedList(list[_T]):
    """A list that counts its changes (see :class:`Table`)."""

    changes: int = 0

    def __setitem__(self, index: Any, value: Any) -> None:  # type: ignore[override]
        self.changes += 1
        super().__setitem__(index, value)

    def __delitem__(self, index: SupportsIndex | slice) -> None:
        self.changes += 1
        super().__delitem__(index)

    def __iadd__(self, other: Iterable[_T]) -> TrackedList[_T]:  # type: ignore[override,misc]
        self.changes += 1
        super().__iadd__(other)
        return self

    def __imul__(self, n: SupportsIndex) -> TrackedList[_T]:  # type: ignore[override,misc]
        self.changes += 1
        super().__imul__(n)
        return self

    def append(self, value: _T) -> None:
        self.changes += 1
        list.append(self, value)

    def extend(self, values: Iterable[_T]) -> None:
        self.changes += 1
        super().extend(values)

    def insert(self, index: SupportsIndex, value: _T) -> None:
        self.changes += 1
        super().insert(index, value)

    def remove(self, value: _T) -> None:
        self.changes += 1
        super().remove(value)

    def pop(self, index: SupportsIndex = -1) -> _T:
        self.changes += 1
        return super().pop(index)

    def clear(self) -> None:
        self.changes += 1
        super().clear()

    def sort(self, *args: Any, **kwargs: Any) -> None:
        self.changes += 1
        super().sort(*args, **kwargs)

    def reverse(self) -> None:
        self.changes += 1
        super().reverse()


# ---------------------------------------------------------------------- the index

@dataclass(frozen=True, slots=True)
class PageNet:
    """The net of one page: its places, transitions, sub-pages (as nodes) and arcs, each in
    the order of the IR's tables."""

    places: tuple[Place, ...] = ()
    transitions: tuple[Transition, ...] = ()
    children: tuple[Page, ...] = ()
    arcs: tuple[Arc, ...] = ()


_EMPTY_NET = PageNet()


@dataclass(frozen=True, slots=True)
class HpnIndex:
    """Lookups over one state of an HPN's tables, built in one pass (see :meth:`HPN.index`);
    the arcs by node on first use (the writers of the outputs read the nets of the pages
    only: on 5,000 agents the arcs by node were half the index's time)."""

    nets: dict[str, PageNet]                    # page id -> its net
    roots: tuple[Page, ...]                     # pages without a parent, in table order
    elements: dict[str, Element]                # id -> page, place, transition or fusion set
    arcs: tuple[Arc, ...] = ()                  # the arcs of that state
    _by_node: list[dict[str, tuple[Arc, ...]]] = field(default_factory=list)
    # [arcs into each node, arcs out of it], made on first use

    def net(self, page: str) -> PageNet:
        """The net of a page (empty for an unknown page)."""
        return self.nets.get(page, _EMPTY_NET)

    def children(self, page: str) -> tuple[Page, ...]:
        return self.nets.get(page, _EMPTY_NET).children

    @property
    def arcs_in(self) -> dict[str, tuple[Arc, ...]]:
        """Node id -> arcs into it."""
        return self._links()[0]

    @property
    def arcs_out(self) -> dict[str, tuple[Arc, ...]]:
        """Node id -> arcs out of it."""
        return self._links()[1]

    def _links(self) -> list[dict[str, tuple[Arc, ...]]]:
        if not self._by_node:
            arcs_in: dict[str, list[Arc]] = {}
            arcs_out: dict[str, list[Arc]] = {}
            for a in self.arcs:
                arcs_out.setdefault(a.source, []).append(a)
                arcs_in.setdefault(a.target, []).append(a)
            self._by_node[:] = [{n: tuple(v) for n, v in arcs_in.items()},
                                {n: tuple(v) for n, v in arcs_out.items()}]
        return self._by_node

    def into(self, node: str) -> tuple[Arc, ...]:
        """Arcs into a place, transition or page node."""
        return self._links()[0].get(node, ())

    def out_of(self, node: str) -> tuple[Arc, ...]:
        """Arcs out of a place, transition or page node."""
        return self._links()[1].get(node, ())

    def element(self, id: str) -> Element | None:
        return self.elements.get(id)

    @staticmethod
    def build(hpn: HPN) -> HpnIndex:
        places: dict[str, list[Place]] = {}
        transitions: dict[str, list[Transition]] = {}
        children: dict[str, list[Page]] = {}
        arcs: dict[str, list[Arc]] = {}
        roots: list[Page] = []
        for pg in hpn.pages.values():
            if pg.parent is None:
                roots.append(pg)
            else:
                children.setdefault(pg.parent, []).append(pg)
        for pl in hpn.places.values():
            places.setdefault(pl.page, []).append(pl)
        for tr in hpn.transitions.values():
            transitions.setdefault(tr.page, []).append(tr)
        for a in hpn.arcs:
            arcs.setdefault(a.page, []).append(a)
        nets = {pid: PageNet(tuple(places.get(pid, ())), tuple(transitions.get(pid, ())),
                             tuple(children.get(pid, ())), tuple(arcs.get(pid, ())))
                for pid in {*hpn.pages, *places, *transitions, *children, *arcs}}
        elements: dict[str, Element] = {}
        for table in (hpn.fusions, hpn.pages, hpn.transitions, hpn.places):
            elements.update(table)
        return HpnIndex(nets, tuple(roots), elements, tuple(hpn.arcs))


# ---------------------------------------------------------------------- the HPN

_TABLES = frozenset({"pages", "places", "transitions", "fusions"})
_LISTS = frozenset({"arcs", "devices"})


@dataclass
class HPN:
    system: str
    root: str                                       # id of the system page H
    pages: dict[str, Page] = field(default_factory=Table)
    places: dict[str, Place] = field(default_factory=Table)
    transitions: dict[str, Transition] = field(default_factory=Table)
    arcs: list[Arc] = field(default_factory=TrackedList)
    fusions: dict[str, FusionSet] = field(default_factory=Table)
    devices: list[str] = field(default_factory=TrackedList)  # ids of device pages (no parent)
    _index: tuple[tuple[int, ...], HpnIndex] | None = field(
        default=None, init=False, repr=False, compare=False)

    def __setattr__(self, name: str, value: Any) -> None:
        # tables assigned whole (also by __init__) become tables that count their changes,
        # and make the index out of date, as a new root does
        if name in _TABLES and not isinstance(value, Table):
            value = Table(value)
        elif name in _LISTS and not isinstance(value, TrackedList):
            value = TrackedList(value)
        object.__setattr__(self, name, value)
        if name in _TABLES or name in _LISTS or name == "root":
            object.__setattr__(self, "_index", None)

    def _stamp(self) -> tuple[int, ...]:
        tables = (self.pages, self.places, self.transitions, self.arcs, self.fusions)
        return tuple(getattr(t, "changes", -1) for t in tables)

    def index(self) -> HpnIndex:
        """The lookups of the net as it is now: built on first use, kept until a table
        changes (an element added, replaced or removed) or is replaced, or the root changes."""
        stamp = self._stamp()
        if self._index is None or self._index[0] != stamp:
            self._index = (stamp, HpnIndex.build(self))
        return self._index[1]

    def element(self, id: str) -> Element | None:
        """The page, place, transition or fusion set with this id."""
        return self.index().element(id)

    def children(self, page: str) -> list[Page]:
        return list(self.index().children(page))

    def contents(self, page: str) -> tuple[list[Place], list[Transition], list[Page], list[Arc]]:
        """The net of one page: its places, transitions, sub-pages (as nodes) and arcs."""
        net = self.index().net(page)
        return list(net.places), list(net.transitions), list(net.children), list(net.arcs)

    def node_page(self, node: str) -> str | None:
        """The page whose net contains a node (place, transition, or sub-page)."""
        if node in self.places:
            return self.places[node].page
        if node in self.transitions:
            return self.transitions[node].page
        if node in self.pages:
            return self.pages[node].parent
        return None
