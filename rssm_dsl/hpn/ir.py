"""The hierarchical Petri net IR: flat tables of pages, places, transitions and arcs.

Hierarchy is held as indices: every place, transition and arc belongs to the page whose net
contains it, every page names its parent page (the net it appears in as a node) and its
own input and output places. Element ids are their names in the paper's notation, e.g.
`p[1,lwr,move,rcv,2,in]`, `t[1,c,cw,4]`, `P^B[1,c,cw]`, so they are unique and readable.

Layers (paper II-IV): 1 system H, 2 agent H_j, 3 subsystem sH_{j,v}, 4 behaviour
sH^B_{j,v,omega}, 5 action (sublayer 1: canonical decomposition / arrangement; sublayer 2:
data availability / communication mode). Device nets close the net for verification and
simulation; they are not part of H.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from enum import Enum

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
    new: tuple[bool, ...] | None = None    # CASE: new(x) per input buffer
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


@dataclass(frozen=True, slots=True)
class Transition:
    id: str
    page: str
    span: Span
    label: str
    role: Role = Role.STRUCTURE
    condition: Condition | None = None


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


@dataclass
class HPN:
    system: str
    root: str                                       # id of the system page H
    pages: dict[str, Page] = field(default_factory=dict)
    places: dict[str, Place] = field(default_factory=dict)
    transitions: dict[str, Transition] = field(default_factory=dict)
    arcs: list[Arc] = field(default_factory=list)
    fusions: dict[str, FusionSet] = field(default_factory=dict)
    devices: list[str] = field(default_factory=list)  # ids of device pages (no parent)

    def children(self, page: str) -> list[Page]:
        return [p for p in self.pages.values() if p.parent == page]

    def contents(self, page: str) -> tuple[list[Place], list[Transition], list[Page], list[Arc]]:
        """The net of one page: its places, transitions, sub-pages (as nodes) and arcs."""
        return (
            [p for p in self.places.values() if p.page == page],
            [t for t in self.transitions.values() if t.page == page],
            self.children(page),
            [a for a in self.arcs if a.page == page],
        )

    def node_page(self, node: str) -> str | None:
        """The page whose net contains a node (place, transition, or sub-page)."""
        if node in self.places:
            return self.places[node].page
        if node in self.transitions:
            return self.transitions[node].page
        if node in self.pages:
            return self.pages[node].parent
        return None
