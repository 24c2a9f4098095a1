"""The flattened HPN: a plain safe place/transition net, with its bindings kept.

This is the interface between the compiler and its consumers (verifier, interpreter,
exports). Pages are gone (arcs into a page go to its input place, arcs out of it leave
from its output place) and every fusion set is one place. Each element remembers the IR
elements it came from, its name in the paper's notation and the span of the user's text.
"""

from __future__ import annotations

from dataclasses import field
from enum import Enum
from functools import cached_property

from rssm_core.firing import Net
from rssm_core.records import dataclass
from rssm_dsl.source import Span


class Role(str, Enum):
    """What a flat transition means for the system, used to word counterexamples and progress."""

    STRUCTURE = "structure"        # layer plumbing: t_in, t_out, forks, joins
    ITERATION = "iteration"        # t_4 / t_out of a behaviour page: one iteration completed
    SWITCH = "switch"              # subsystem layer: initial condition f^sigma, behaviour switch
    CASE = "case"                  # data-availability case of a partial transition function
    SEND = "send"                  # mode sublayer, producer side
    RECEIVE = "receive"            # mode sublayer, consumer side
    DEVICE = "device"              # device loop


@dataclass(frozen=True, slots=True)
class FlatPlace:
    index: int
    name: str                      # paper notation; for a fusion set, the fused place's name
    label: str                     # in the user's words, e.g. "channel a1.c.cmd -> a1.lwr.cmd: full"
    span: Span
    origin: tuple[str, ...]        # ids of the IR places merged into this one
    operation: str | None = None   # id of the operation bound to the place, if any
    subsystem: str | None = None   # qualified subsystem ("a1.c") owning the place; None if shared
    behaviour: str | None = None   # behaviour owning the place, if any
    channel: str | None = None     # channel id for fusion places of a channel
    page: str | None = None        # the IR page it lies on (a fusion set: its consumer's page)


@dataclass(frozen=True, slots=True)
class FlatPage:
    """A page of the HPN the flat net came from: the hierarchy its places lie in."""

    id: str
    parent: str | None
    kind: str                      # ir.PageKind value: system, agent, subsystem, device, ...
    owner: str                     # the system, agent, subsystem or device it belongs to
    agent: str | None = None       # the agent it belongs to (a device net: its device's agent)


@dataclass(frozen=True, slots=True)
class FlatTransition:
    index: int
    name: str
    label: str
    span: Span
    pre: tuple[int, ...]           # input places (sorted, no duplicates)
    post: tuple[int, ...]          # output places (sorted, no duplicates)
    role: Role = Role.STRUCTURE
    condition: str | None = None   # id of the condition bound to the transition; None = true
    subsystem: str | None = None
    behaviour: str | None = None
    channel: str | None = None


@dataclass(frozen=True, slots=True)
class FlatCondition:
    """The condition of a flat transition that is not known without data (ir.Condition):
    ``kind`` is its ir.CondKind value (``case``: a data-availability case, ``continue`` /
    ``stop``: t_4 / t_out of a behaviour, ``switch``: f^sigma), ``text`` its words; a data
    case's ``new`` gives new(x) per input buffer of its subsystem (bit k: input k; None: an
    input the case does not split, rssm_dsl/semantics/cases.py)."""

    transition: int
    kind: str
    text: str
    new: tuple[bool | None, ...] | None = None


@dataclass(frozen=True, slots=True)
class NewSites:
    """Where the flat net decides new(x) of a subsystem's inputs (rssm_core/iteration.py):
    the receive that takes fresh data into input k (the step RECEIVED of its mode page, in
    every behaviour), the fork of the transition function P^f (new(x) frozen for its data
    cases) and its join (the data used: every new(x) false again). The verifier tracks new(x)
    from these (rssm_dsl/verify/datanet.py)."""

    inputs: tuple[tuple[str, tuple[str, ...]], ...] = ()  # (subsystem, input buffers by k)
    receives: tuple[tuple[int, str, int], ...] = ()       # (transition, subsystem, k)
    forks: tuple[tuple[int, str], ...] = ()               # (transition, subsystem)
    joins: tuple[tuple[int, str], ...] = ()               # (transition, subsystem)
    # inputs whose new(x) the verifier leaves a free choice (fed by a slice's environment,
    # rssm_dsl/verify/slicing.py): (subsystem, k)
    free: tuple[tuple[str, int], ...] = ()


@dataclass(frozen=True)
class FlatNet:
    """A safe P/T net. Markings are sets of place indices (at most one token per place)."""

    system: str
    places: tuple[FlatPlace, ...]
    transitions: tuple[FlatTransition, ...]
    initial: frozenset[int]
    final: frozenset[int]          # places whose marking means the system finished
    subsystems: tuple[str, ...] = field(default=())  # qualified names, for progress checks
    pages: tuple[FlatPage, ...] = field(default=())   # the page hierarchy, parents first
    conditions: tuple[FlatCondition, ...] = field(default=())  # those not known without data
    new_sites: NewSites = field(default=NewSites())

    # lookups, each built on first use (the net is immutable)
    @cached_property
    def place_index(self) -> dict[str, int]:
        """Place name -> index."""
        return {p.name: p.index for p in self.places}

    @cached_property
    def transition_index(self) -> dict[str, int]:
        """Transition name -> index."""
        return {t.name: t.index for t in self.transitions}

    @cached_property
    def rule(self) -> Net:
        """The net's structure for the firing rule (rssm_core.firing): pre- and post-sets,
        and per place its consumers and producers."""
        return Net.of(self.transitions, len(self.places))

    def place(self, name: str) -> FlatPlace:
        return self.places[self.place_index[name]]

    def transition(self, name: str) -> FlatTransition:
        return self.transitions[self.transition_index[name]]
