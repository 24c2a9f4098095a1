"""The abstract syntax tree: immutable, slotted nodes, each with the span of its text."""

from __future__ import annotations

from enum import Enum

from rssm_core.modes import Mode
from rssm_core.records import dataclass
from rssm_dsl.source import Span

# ---------------------------------------------------------------- types


@dataclass(frozen=True, slots=True)
class NamedType:
    span: Span
    name: str


@dataclass(frozen=True, slots=True)
class ArrayType:
    span: Span
    element: TypeExpr
    size: int


@dataclass(frozen=True, slots=True)
class RangeType:
    """A bounded int, written as its range: `0..3`, `-5..5`."""

    span: Span
    lo: int
    hi: int


TypeExpr = NamedType | ArrayType | RangeType

# ---------------------------------------------------------------- expressions


@dataclass(frozen=True, slots=True)
class Literal:
    span: Span
    value: bool | int | float


@dataclass(frozen=True, slots=True)
class Name:
    span: Span
    name: str


@dataclass(frozen=True, slots=True)
class FieldAccess:
    span: Span
    value: Expr
    field: str


@dataclass(frozen=True, slots=True)
class Index:
    span: Span
    value: Expr
    index: Expr


@dataclass(frozen=True, slots=True)
class Call:
    span: Span
    function: str
    function_span: Span
    args: tuple[Expr, ...]


@dataclass(frozen=True, slots=True)
class Unary:
    span: Span
    op: str  # "-" | "not"
    operand: Expr


@dataclass(frozen=True, slots=True)
class Binary:
    span: Span
    op: str  # + - * / % == != < <= > >= and or
    left: Expr
    right: Expr


@dataclass(frozen=True, slots=True)
class IfExpr:
    span: Span
    condition: Expr
    then: Expr
    otherwise: Expr


@dataclass(frozen=True, slots=True)
class ArrayLit:
    span: Span
    items: tuple[Expr, ...]


@dataclass(frozen=True, slots=True)
class RecordLit:
    span: Span
    fields: tuple[tuple[str, Expr], ...]


@dataclass(frozen=True, slots=True)
class InBehaviour:
    """`SUBJECT in BEHAVIOUR` (properties only): the subsystem `subject` (written
    `agent.subsystem`) is in its behaviour `behaviour`."""

    span: Span
    subject: Expr
    behaviour: str
    behaviour_span: Span


Expr = (Literal | Name | FieldAccess | Index | Call | Unary | Binary | IfExpr | ArrayLit
        | RecordLit | InBehaviour)

# ---------------------------------------------------------------- statements


@dataclass(frozen=True, slots=True)
class Assign:
    span: Span
    target: Expr  # Name, FieldAccess or Index rooted at a Name
    value: Expr


@dataclass(frozen=True, slots=True)
class Let:
    span: Span
    name: str
    value: Expr


@dataclass(frozen=True, slots=True)
class Skip:
    span: Span


Stmt = Assign | Let | Skip

# ---------------------------------------------------------------- declarations


class Direction(str, Enum):
    INPUT = "input"
    OUTPUT = "output"


class SubsystemKind(str, Enum):
    CONTROL = "control"      # c
    EFFECTOR = "effector"    # e (virtual effector)
    RECEPTOR = "receptor"    # r (virtual receptor)


class DeviceKind(str, Enum):
    EFFECTOR = "effector"    # E (real effector)
    RECEPTOR = "receptor"    # R (real receptor)


@dataclass(frozen=True, slots=True)
class Import:
    span: Span
    path: str          # dotted module path or a quoted file path
    quoted: bool


@dataclass(frozen=True, slots=True)
class RecordDecl:
    span: Span
    name: str
    name_span: Span
    fields: tuple[FieldDecl, ...]


@dataclass(frozen=True, slots=True)
class FieldDecl:
    span: Span
    name: str
    type: TypeExpr


@dataclass(frozen=True, slots=True)
class EnumMember:
    span: Span
    name: str


@dataclass(frozen=True, slots=True)
class EnumDecl:
    span: Span
    name: str
    name_span: Span
    members: tuple[EnumMember, ...]


@dataclass(frozen=True, slots=True)
class AliasDecl:
    span: Span
    name: str
    name_span: Span
    type: TypeExpr


@dataclass(frozen=True, slots=True)
class ConstDecl:
    span: Span
    name: str
    name_span: Span
    type: TypeExpr | None
    value: Expr


@dataclass(frozen=True, slots=True)
class Param:
    span: Span
    name: str
    type: TypeExpr


@dataclass(frozen=True, slots=True)
class ExternDecl:
    span: Span
    name: str
    name_span: Span
    params: tuple[Param, ...]
    result: TypeExpr
    binding: str
    binding_span: Span


@dataclass(frozen=True, slots=True)
class Frequency:
    span: Span
    hertz: float


@dataclass(frozen=True, slots=True)
class PeerRef:
    span: Span
    parts: tuple[str, ...]

    def __str__(self) -> str:
        return ".".join(self.parts)


@dataclass(frozen=True, slots=True)
class BufferDecl:
    span: Span
    direction: Direction
    name: str
    name_span: Span
    type: TypeExpr
    peer: PeerRef | None
    mode: Mode | None
    mode_span: Span | None
    init: Expr | None
    arrow: tuple[str, Span] | None = None  # the `from` / `to` word as written


@dataclass(frozen=True, slots=True)
class MemoryDecl:
    span: Span
    name: str
    name_span: Span
    type: TypeExpr
    init: Expr | None


@dataclass(frozen=True, slots=True)
class ParamDecl:
    span: Span
    name: str
    name_span: Span
    type: TypeExpr
    value: Expr


@dataclass(frozen=True, slots=True)
class BindingDecl:
    span: Span
    binding: str


@dataclass(frozen=True, slots=True)
class DeviceDecl:
    span: Span
    kind: DeviceKind
    name: str
    name_span: Span
    frequency: Frequency | None
    buffers: tuple[BufferDecl, ...]
    params: tuple[ParamDecl, ...]
    binding: BindingDecl | None


@dataclass(frozen=True, slots=True)
class Case:
    span: Span
    condition: Expr | None  # None: otherwise
    body: tuple[Stmt, ...]


@dataclass(frozen=True, slots=True)
class UpdateDecl:
    """A partial transition function: its target is an output buffer or `memory`."""

    span: Span
    target: str
    target_span: Span
    cases: tuple[Case, ...]
    plain: bool  # written without cases: one case for every data combination


@dataclass(frozen=True, slots=True)
class ConditionDecl:
    span: Span
    kind: str  # "terminal" | "error"
    name: str
    name_span: Span
    expr: Expr


@dataclass(frozen=True, slots=True)
class ArrBuffer:
    span: Span
    name: str


@dataclass(frozen=True, slots=True)
class ArrSeq:
    span: Span
    items: tuple[Arrangement, ...]


@dataclass(frozen=True, slots=True)
class ArrPar:
    span: Span
    items: tuple[Arrangement, ...]


Arrangement = ArrBuffer | ArrSeq | ArrPar


@dataclass(frozen=True, slots=True)
class BehaviourDecl:
    span: Span
    name: str
    name_span: Span
    updates: tuple[UpdateDecl, ...]
    conditions: tuple[ConditionDecl, ...]
    send: tuple[Arrangement, ...]      # at most one; more is reported
    receive: tuple[Arrangement, ...]


@dataclass(frozen=True, slots=True)
class InitialDecl:
    span: Span
    behaviour: str
    behaviour_span: Span


@dataclass(frozen=True, slots=True)
class SwitchDecl:
    span: Span
    source: str
    source_span: Span
    target: str          # a behaviour name or "end"
    target_span: Span
    condition: Expr | None  # None: otherwise


@dataclass(frozen=True, slots=True)
class SubsystemDecl:
    span: Span
    kind: SubsystemKind
    name: str            # "c" for an unnamed control subsystem
    name_span: Span
    frequency: Frequency | None
    memory: tuple[MemoryDecl, ...]
    buffers: tuple[BufferDecl, ...]
    params: tuple[ParamDecl, ...]
    behaviours: tuple[BehaviourDecl, ...]
    initial: tuple[InitialDecl, ...]
    switches: tuple[SwitchDecl, ...]


@dataclass(frozen=True, slots=True)
class DeviceArg:
    """``NAME = VALUE`` in ``real effector big: Heater(watts = 2000.0)``: this instance's
    value of the device type's parameter NAME."""

    span: Span
    name: str
    name_span: Span
    value: Expr


@dataclass(frozen=True, slots=True)
class DeviceInstance:
    span: Span
    kind: DeviceKind
    name: str
    name_span: Span
    device: str
    device_span: Span
    frequency: Frequency | None
    args: tuple[DeviceArg, ...] = ()


@dataclass(frozen=True, slots=True)
class AgentDecl:
    span: Span
    name: str
    name_span: Span
    subsystems: tuple[SubsystemDecl, ...]
    devices: tuple[DeviceInstance, ...]
    # made by semantics/instances.py from `agent NAME: DEFINITION(...)`: the definition's
    # name (its body's spans are the definition's), None for an agent written out
    instance_of: str | None = None


@dataclass(frozen=True, slots=True)
class AgentParam:
    """``boss: agent`` (``type`` None: another agent's name, for the peers of buffers) or
    ``speed: float = 0.2`` (a value the definition's expressions read) in
    ``agent Robot(boss: agent, speed: float = 0.2) { ... }``."""

    span: Span
    name: str
    name_span: Span
    type: TypeExpr | None
    default: Expr | None


@dataclass(frozen=True, slots=True)
class AgentDef:
    """An agent defined once, outside the system, instantiated by :class:`AgentInstance`."""

    span: Span
    name: str
    name_span: Span
    params: tuple[AgentParam, ...]
    subsystems: tuple[SubsystemDecl, ...]
    devices: tuple[DeviceInstance, ...]


@dataclass(frozen=True, slots=True)
class AgentInstance:
    """``agent r1: Robot(boss = coord)``, or ``agent r[2..8]: Robot(...)`` (``lo``..``hi``:
    the agents r2, ..., r8; None for one agent)."""

    span: Span
    name: str
    name_span: Span
    definition: str
    definition_span: Span
    args: tuple[DeviceArg, ...] = ()
    lo: int | None = None
    hi: int | None = None

    def names(self) -> tuple[str, ...]:
        """The agents it declares: none when its range is wrong (:meth:`range_ok`)."""
        if self.lo is None or self.hi is None:
            return (self.name,)
        if not self.range_ok():
            return ()
        return tuple(f"{self.name}{k}" for k in range(self.lo, self.hi + 1))

    def range_ok(self) -> bool:
        """No range, or one from 0 or more that declares 1 to MAX_INSTANCES agents."""
        return self.lo is None or self.hi is None or (
            self.lo >= 0 and 0 <= self.hi - self.lo < MAX_INSTANCES)


MAX_INSTANCES = 10_000      # agents one indexed line `agent r[1..8]: ...` may declare


@dataclass(frozen=True, slots=True)
class PropertyDecl:
    """`property NAME: always CONDITION` or `property NAME: whenever TRIGGER eventually GOAL`."""

    span: Span
    name: str
    name_span: Span
    kind: str                  # "always" | "response"
    condition: Expr | None     # always
    trigger: Expr | None       # response
    goal: Expr | None          # response

    @property
    def expressions(self) -> tuple[Expr, ...]:
        return tuple(e for e in (self.condition, self.trigger, self.goal) if e is not None)


@dataclass(frozen=True, slots=True)
class SystemDecl:
    span: Span
    name: str
    name_span: Span
    agents: tuple[AgentDecl, ...]
    properties: tuple[PropertyDecl, ...] = ()
    # `agent NAME: DEFINITION(...)` lines, made into agents by semantics/instances.py
    instances: tuple[AgentInstance, ...] = ()


Decl = (RecordDecl | AliasDecl | EnumDecl | ConstDecl | ExternDecl | DeviceDecl | AgentDef
        | SystemDecl)


@dataclass(frozen=True, slots=True)
class Module:
    span: Span
    path: str
    imports: tuple[Import, ...]
    decls: tuple[Decl, ...]
