"""The semantic model: the system with every name resolved and every type known.

It mirrors the paper's structure (III-A): agents a_j with one control subsystem c_j, virtual
effectors e_{j,n}, virtual receptors r_{j,k} and devices E_{j,h} / R_{j,l}; buffers paired
into channels; behaviours made of partial transition functions (canonical decomposition),
each split into data-availability cases (the rule: rssm_dsl/semantics/cases.py).
"""

from __future__ import annotations

from dataclasses import field

from rssm_core.modes import Mode, pairing
from rssm_core.records import dataclass
from rssm_dsl.semantics.cases import Combination
from rssm_dsl.semantics.types import Type
from rssm_dsl.source import Span
from rssm_dsl.syntax import ast

# Kind letters of the paper: c, e, r (designed subsystems), E, R (devices).
KIND_LETTER = {"control": "c", "effector": "e", "receptor": "r"}
DEVICE_LETTER = {"effector": "E", "receptor": "R"}


@dataclass(frozen=True)
class Extern:
    name: str
    params: tuple[tuple[str, Type], ...]
    result: Type
    binding: str  # "module:function"
    span: Span


@dataclass(frozen=True)
class Const:
    name: str
    type: Type
    value: ast.Expr
    span: Span


@dataclass(frozen=True)
class Variable:
    """A memory variable or a parameter of a subsystem or device."""

    name: str
    type: Type
    init: ast.Expr | None
    span: Span


@dataclass(frozen=True)
class Buffer:
    owner: str            # qualified id of the subsystem or device, e.g. "a1.e.lwr"
    name: str
    direction: ast.Direction
    type: Type
    mode: Mode
    init: ast.Expr | None
    span: Span
    peer: str | None = None   # qualified id of the peer, once paired

    @property
    def qualified(self) -> str:
        return f"{self.owner}.{self.name}"


@dataclass(frozen=True)
class Channel:
    """A producer's output buffer joined to a consumer's input buffer (fused places)."""

    index: int
    producer: Buffer
    consumer: Buffer

    @property
    def id(self) -> str:
        return f"{self.producer.qualified}->{self.consumer.qualified}"

    @property
    def modes(self) -> str:
        return pairing(self.producer.mode, self.consumer.mode).text


@dataclass(frozen=True)
class DataCase:
    """One data-availability case of a partial function (index varpi, from 1): the
    combination of new(x) of the inputs its behaviour's case clauses read (rssm_dsl/semantics/cases.py).
    """

    index: int
    new: Combination                  # new(x) per input buffer, in declaration order; None:
                                      # not split (the case stands for new and not new)
    body: tuple[ast.Stmt, ...]        # empty: a void operation
    span: Span                        # the user's case (or the update) it comes from
    source_case: int | None           # index of the user's case in the update, if any

    @property
    def void(self) -> bool:
        return all(isinstance(s, ast.Skip) for s in self.body)


@dataclass(frozen=True)
class PartialFunction:
    """A partial transition function f_{j,v,omega,psi}: writes one output buffer or memory."""

    index: int                        # psi, from 1; memory comes last (mu + 1)
    target: str                       # output buffer name, or "memory"
    cases: tuple[DataCase, ...]
    span: Span


@dataclass(frozen=True)
class Condition:
    kind: str                         # "terminal" (f^tau) | "error" (f^epsilon)
    name: str
    expr: ast.Expr
    span: Span

    @property
    def never(self) -> bool:
        return isinstance(self.expr, ast.Literal) and self.expr.value is False


@dataclass(frozen=True)
class ArrLeaf:
    buffer: str
    span: Span


@dataclass(frozen=True)
class ArrSeq:
    items: tuple[Arrangement, ...]
    span: Span


@dataclass(frozen=True)
class ArrPar:
    items: tuple[Arrangement, ...]
    span: Span


Arrangement = ArrLeaf | ArrSeq | ArrPar


@dataclass(frozen=True)
class Behaviour:
    name: str
    span: Span
    functions: tuple[PartialFunction, ...]   # mu + 1: outputs in order, then memory
    conditions: tuple[Condition, ...]
    send: Arrangement | None                  # None when the subsystem has no outputs
    receive: Arrangement | None               # None when it has no inputs

    @property
    def terminals(self) -> tuple[Condition, ...]:
        return tuple(c for c in self.conditions if c.kind == "terminal")

    @property
    def errors(self) -> tuple[Condition, ...]:
        return tuple(c for c in self.conditions if c.kind == "error")


@dataclass(frozen=True)
class Switch:
    index: int                        # alpha, from 1 within the subsystem
    source: str | None                # None: the entry from p_{j,v,in} (initial behaviour)
    target: str | None                # None: the subsystem ends (p_{j,v,out})
    condition: ast.Expr | None        # None: true / otherwise
    otherwise: bool
    span: Span


@dataclass(frozen=True)
class Subsystem:
    agent: str
    kind: str                         # "control" | "effector" | "receptor"
    name: str                         # designator v: "c" for the control subsystem
    span: Span
    frequency: float | None
    params: tuple[Variable, ...]
    memory: tuple[Variable, ...]
    inputs: tuple[Buffer, ...]
    outputs: tuple[Buffer, ...]
    behaviours: tuple[Behaviour, ...]
    switches: tuple[Switch, ...]      # the entry switch first

    @property
    def letter(self) -> str:
        return KIND_LETTER[self.kind]

    @property
    def id(self) -> str:
        return f"{self.agent}.c" if self.kind == "control" else f"{self.agent}.{self.letter}.{self.name}"

    def behaviour(self, name: str) -> Behaviour:
        return next(b for b in self.behaviours if b.name == name)

    def switches_from(self, behaviour: str) -> tuple[Switch, ...]:
        """The switches leaving ``behaviour`` in the order they are tried when it ends: the
        `when` switches as declared, `otherwise` last. The first whose condition holds is
        taken (the rule of every backend; the compiler warns, W604, when two can hold)."""
        return tuple(sorted((s for s in self.switches if s.source == behaviour),
                            key=lambda s: (s.otherwise or s.condition is None, s.index)))


@dataclass(frozen=True)
class Device:
    agent: str
    kind: str                         # "effector" (E) | "receptor" (R)
    name: str
    device_type: str
    span: Span
    frequency: float | None
    params: tuple[Variable, ...]
    inputs: tuple[Buffer, ...]
    outputs: tuple[Buffer, ...]
    binding: str | None
    binding_span: Span | None = None  # where the device type declares its binding

    @property
    def letter(self) -> str:
        return DEVICE_LETTER[self.kind]

    @property
    def id(self) -> str:
        return f"{self.agent}.{self.letter}.{self.name}"


@dataclass(frozen=True)
class Agent:
    name: str
    span: Span
    subsystems: tuple[Subsystem, ...]  # the control subsystem first
    devices: tuple[Device, ...]

    @property
    def designator(self) -> str:
        """j in the paper's notation: `a1` and `a_1` give `1`; other names are kept."""
        n = self.name
        for prefix in ("a_", "a"):
            rest = n[len(prefix):]
            if n.startswith(prefix) and rest.isdigit():
                return rest
        return n


@dataclass(frozen=True)
class Property:
    """A user-stated property the verifier checks (docs/language.md, Properties).

    ``kind`` "always": ``condition`` holds in every reachable state (a state invariant);
    "response" (`whenever trigger eventually goal`): every reachable state where ``trigger``
    holds is followed, now or later, by one where ``goal`` holds, on every run but those that
    keep a way to ``goal`` open for ever (docs/verify.md). The expressions are as
    written; rssm_dsl.semantics.properties resolves their atoms (``atoms``) and evaluates
    them (``Formula``, ``evaluate``)."""

    name: str
    kind: str                          # "always" | "response"
    span: Span                         # the declaration
    name_span: Span
    condition: ast.Expr | None = None  # always
    trigger: ast.Expr | None = None    # response
    goal: ast.Expr | None = None       # response

    @property
    def expressions(self) -> tuple[ast.Expr, ...]:
        """The condition, or the trigger and the goal."""
        return tuple(e for e in (self.condition, self.trigger, self.goal) if e is not None)


@dataclass(frozen=True)
class System:
    name: str
    span: Span
    agents: tuple[Agent, ...]
    channels: tuple[Channel, ...]
    consts: tuple[Const, ...]
    externs: tuple[Extern, ...]
    types: tuple[tuple[str, Type], ...] = field(default=())
    properties: tuple[Property, ...] = field(default=())

    def subsystems(self) -> list[Subsystem]:
        return [s for a in self.agents for s in a.subsystems]

    def devices(self) -> list[Device]:
        return [d for a in self.agents for d in a.devices]

    def channel_of(self, buffer: Buffer) -> Channel | None:
        for ch in self.channels:
            if ch.producer.qualified == buffer.qualified or ch.consumer.qualified == buffer.qualified:
                return ch
        return None
