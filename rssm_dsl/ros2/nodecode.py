"""The Python of one node: a subsystem (the behaviour pattern, partial functions, conditions,
switches) or a bound device, as the pieces node.py.j2 / device.py.j2 lay out.

Every piece is built by :mod:`rssm_dsl.ros2.pycode` from the semantic model; names of the
specification reach the code only mangled or inside ``repr`` string literals.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from typing import Any

import numpy as np

from rssm_core.modes import pairing
from rssm_core.records import dataclass
from rssm_dsl.hpn.ir import HPN, PageKind
from rssm_dsl.hpn.pattern import Compute, Increment, Receive, Send, iteration
from rssm_dsl.pycode import (
    PyGen,
    TypeTable,
    comment,
    cond,
    const,
    extern,
    number,
    tuple_source,
    var,
)
from rssm_dsl.ros2.msgtypes import MessageTypes
from rssm_dsl.ros2.stdtypes import PACKAGES as STD_PACKAGES
from rssm_dsl.ros2.stdtypes import RosType, default_name, resolve
from rssm_dsl.semantics import cases as case_rule
from rssm_dsl.semantics.behaviours import combination_text
from rssm_dsl.semantics.model import (
    Arrangement,
    ArrLeaf,
    ArrPar,
    Behaviour,
    Buffer,
    Channel,
    DataCase,
    Device,
    Extern,
    PartialFunction,
    Subsystem,
    System,
    Variable,
)
from rssm_dsl.semantics.typecheck import Symbol, enum_symbols, owner_symbols
from rssm_dsl.semantics.types import BOOL, Type
from rssm_dsl.syntax.printer import expr_text

INDENT = "    "


@dataclass(frozen=True)
class ChannelView:
    buffer: str
    channel: str
    topic: str
    msg: str              # Python source of the data message class (_std_msgs.Float64, ...)
    ros_type: str         # its ROS name, std_msgs/msg/Float64 or <system>_interfaces/msg/X
    package: str          # the package of the message (std_msgs, ..., <system>_interfaces)
    stamped: bool         # a std_msgs/Header the producer stamps
    desc: str
    pairing: str          # the member of rssm_core.modes.Pairing
    modes: str


@dataclass(frozen=True)
class ExternView:
    var: str
    module: str
    attribute: str
    name: str


@dataclass(frozen=True)
class ParamView:
    name: str
    desc: str
    default: str          # Python source of the specification's value


@dataclass(frozen=True)
class BehaviourView:
    name: str
    page: str             # its page in the paper's notation, P^B[j,v,w]
    tables: tuple[str, ...]
    iterate: tuple[str, ...]
    switch: tuple[str, ...]
    spec: str


@dataclass(frozen=True)
class NodeView:
    """What node.py.j2 needs for one subsystem node."""

    id: str
    kind: str
    module: str
    executable: str
    node: str
    namespace: str
    frequency: str
    types: tuple[str, ...]
    converters: tuple[str, ...]
    msgdescs: tuple[str, ...]
    externs: tuple[ExternView, ...]
    consts: tuple[str, ...]
    slots: tuple[str, ...]
    initial: tuple[str, ...]
    functions: tuple[tuple[str, ...], ...]
    behaviours: tuple[BehaviourView, ...]
    initial_behaviour: str
    params: tuple[ParamView, ...]
    inputs: tuple[ChannelView, ...]
    outputs: tuple[ChannelView, ...]
    ros_imports: tuple[str, ...]      # standard message packages the channels use


@dataclass(frozen=True)
class DeviceView:
    """What device.py.j2 needs for one device node."""

    id: str
    name: str
    device_type: str
    kind: str
    module: str
    executable: str
    node: str
    namespace: str
    frequency: str
    binding_module: str
    binding_attribute: str
    types: tuple[str, ...]
    msgdescs: tuple[str, ...]
    inputs: tuple[tuple[str, str], ...]         # (buffer, descriptor name)
    outputs: tuple[tuple[str, str], ...]
    channels_in: tuple[ChannelView, ...]
    channels_out: tuple[ChannelView, ...]
    initial: tuple[tuple[str, str], ...]        # (buffer, Python literal)
    params: tuple[ParamView, ...]
    package: str                                # the agent's package (share/<package>/data)
    ros_imports: tuple[str, ...]


def node_name(kind_letter: str, name: str) -> str:
    """The ROS node of a subsystem or device: c, e_<name>, r_<name>, E_<name>, R_<name>."""
    return "c" if kind_letter == "c" else f"{kind_letter}_{name}"


def literal(value: Any) -> str:
    """Python source of a value of the interpreter's representation (arrays as lists)."""
    if isinstance(value, bool | int | float):
        return number(value)
    if isinstance(value, str):
        return repr(value)              # an enum member
    if isinstance(value, np.ndarray):
        return literal(tuple(float(x) for x in value.tolist()))
    if isinstance(value, tuple | list):
        return "[" + ", ".join(literal(x) for x in value) + "]"
    assert isinstance(value, dict)
    return "{" + ", ".join(f"{k!r}: {literal(v)}" for k, v in value.items()) + "}"


def arrangement(arr: Arrangement) -> str:
    if isinstance(arr, ArrLeaf):
        return f"('buf', {arr.buffer!r})"
    kind = "par" if isinstance(arr, ArrPar) else "seq"
    return f"({kind!r}, {tuple_source([arrangement(a) for a in arr.items])})"


def mask_of(case: DataCase) -> int:
    """The row of a case in its table: new(x) of the split inputs as bits, bit i for the
    i-th split input (rssm_dsl.semantics.cases.bits of any run-time mask the case stands for)."""
    return sum(1 << i for i, v in enumerate(x for x in case.new if x is not None) if v)


def row_source(split: tuple[int, ...], inputs: int) -> str:
    """Python source of rssm_dsl.semantics.cases.bits(mask, split): the row of the case that the
    run-time new(x) ``mask`` selects (``mask`` itself when every input is split)."""
    if split == tuple(range(inputs)):
        return "mask"
    if not split:
        return "0"
    return " | ".join(f"(mask >> {k} & 1)" + (f" << {i}" if i else "")
                      for i, k in enumerate(split))


@dataclass(frozen=True)
class Wire:
    """What a channel's data topic carries (see :mod:`rssm_dsl.ros2.stdtypes`)."""

    msg: str              # Python source of the message class
    ros_type: str
    package: str
    desc: str             # Python source of its message descriptor
    stamped: bool


def ros_imports(channels: tuple[ChannelView, ...]) -> tuple[str, ...]:
    return tuple(sorted({c.package for c in channels if c.package in STD_PACKAGES}))


class Context:
    """What every node of the system shares: constants, externs, message types, owners."""

    def __init__(self, system: System, hpn: HPN, msgs: MessageTypes,
                 values: Callable[[str, Variable], Any], interfaces: str = "",
                 explicit: Mapping[str, RosType] | None = None) -> None:
        self.system = system
        self.interfaces = interfaces
        self.explicit = dict(explicit or {})     # channel id -> the ROS type named for it
        self.wires: dict[str, Wire] = {}
        self.hpn = hpn
        self.behaviour_pages = {(p.owner, p.behaviour): p for p in hpn.pages.values()
                                if p.kind is PageKind.BEHAVIOUR}
        self.msgs = msgs
        self.values = values            # (owner id, variable) -> its value (params, inits)
        self.externs: dict[str, Extern] = {e.name: e for e in system.externs}
        self.owner_node: dict[str, tuple[str, str]] = {}    # owner id -> (agent, node)
        for a in system.agents:
            for s in a.subsystems:
                self.owner_node[s.id] = (a.name, node_name(s.letter, s.name))
            for d in a.devices:
                self.owner_node[d.id] = (a.name, node_name(d.letter, d.name))

    def topic(self, ch: Channel) -> str:
        agent, node = self.owner_node[ch.producer.owner]
        return f"/{agent}/{node}/{ch.producer.name}"

    def wire(self, ch: Channel) -> Wire:
        """The data message of a channel: the ROS type named for it, else the default
        standard type of its buffer type, else the generated message."""
        if ch.id not in self.wires:
            t = ch.producer.type
            std = self.explicit.get(ch.id)
            if std is None:
                name = default_name(t)
                found = resolve(name, t, self.msgs.descriptor) if name is not None else None
                std = found if isinstance(found, RosType) else None
            if std is not None:
                wire = Wire(std.cls, std.full, std.package, std.desc, std.stamped)
            else:
                cls, desc = self.msgs.data_message(t)
                name = cls.split(".", 1)[1]
                wire = Wire(cls, f"{self.interfaces}/msg/{name}", self.interfaces, desc, False)
            self.wires[ch.id] = wire
        return self.wires[ch.id]

    def channel_view(self, buf: Buffer, types: TypeTable, descs: dict[str, str]) -> ChannelView:
        ch = self.system.channel_of(buf)
        assert ch is not None
        wire = self.wire(ch)
        if wire.desc not in descs:
            descs[wire.desc] = f"M{len(descs)}"
        return ChannelView(buf.name, ch.id, self.topic(ch), wire.msg, wire.ros_type,
                           wire.package, wire.stamped, descs[wire.desc],
                           pairing(ch.producer.mode, ch.consumer.mode).name, ch.modes)


def const_lines(system: System, types: TypeTable) -> list[str]:
    lines: list[str] = []
    symbols: dict[str, Symbol] = enum_symbols(system.types, system.span)
    for c in system.consts:
        gen = PyGen(symbols, {}, types)
        lines.append(f"{const(c.name)} = {gen.expr(c.value, c.type, c.name)}")
        symbols[c.name] = Symbol("const", c.type, c.span)
    return lines


class SubsystemCode:
    """Builds the :class:`NodeView` of one subsystem."""

    def __init__(self, ctx: Context, sub: Subsystem, agent: str, j: str) -> None:
        self.ctx, self.sub, self.agent, self.j = ctx, sub, agent, j
        self.types = TypeTable()
        self.descs: dict[str, str] = {}
        self.externs: set[str] = set()
        self.functions: list[tuple[str, ...]] = []
        self.function_names: set[str] = set()
        consts = enum_symbols(ctx.system.types, ctx.system.span)
        consts.update({c.name: Symbol("const", c.type, c.span) for c in ctx.system.consts})
        self.symbols = owner_symbols(consts, sub.params, sub.memory, (*sub.inputs, *sub.outputs))

    def gen(self, special: frozenset[str] = frozenset()) -> PyGen:
        return PyGen(self.symbols, self.ctx.externs, self.types, special)

    def _loads(self, gen: PyGen) -> list[str]:
        return [f"{INDENT}{var(n)} = st.{var(n)}" for n in sorted(gen.reads)]

    def _note(self, gen: PyGen) -> None:
        self.externs |= gen.externs_used

    # ------------------------------------------------------------------ pieces
    def _initial(self) -> list[str]:
        sub = self.sub
        lines = [f"{INDENT}st = State()"]
        scope = enum_symbols(self.ctx.system.types, self.ctx.system.span)
        scope.update({c.name: Symbol("const", c.type, c.span) for c in self.ctx.system.consts})
        for p in sub.params:
            lines.append(f"{INDENT}{var(p.name)} = st.{var(p.name)} = p[{p.name!r}]")
            scope[p.name] = Symbol("param", p.type, p.span)
        gen = PyGen(scope, self.ctx.externs, self.types)
        named: list[tuple[str, Type, Any]] = [(m.name, m.type, m.init) for m in sub.memory]
        named += [(b.name, b.type, b.init) for b in (*sub.inputs, *sub.outputs)]
        for name, t, init in named:
            value = gen.expr(init, t, name) if init is not None else \
                f"_rt.default({self.types.desc(t)})"
            lines.append(f"{INDENT}st.{var(name)} = {value}")
        self._note(gen)
        lines.append(f"{INDENT}return st")
        return lines

    def _case_function(self, b: int, beh: Behaviour, pf: PartialFunction,
                       case: DataCase) -> str:
        which = (str(case.source_case + 1) if case.source_case is not None
                 else f"c{case.index}")
        name = f"f_{b}_{pf.index}_{which}"
        if name in self.function_names:
            return name
        self.function_names.add(name)
        gen = self.gen()
        body, written = gen.body(case.body)
        self._note(gen)
        where = f"{case.span.file}:{case.span.line}"
        lines = [f"def {name}(st: State, stage: dict[str, Any]) -> None:",
                 f"{INDENT}# {comment(f'{beh.name}: update {pf.target}, {where}')}",
                 *self._loads(gen), *(INDENT + x for x in body),
                 *(f"{INDENT}stage[{var(n)!r}] = {var(n)}" for n in written)]
        self.functions.append(tuple(lines))
        return name

    def _tables(self, b: int, beh: Behaviour) -> tuple[list[str], list[str]]:
        """The case tables of the partial functions and the lines of P^f that use them."""
        inputs = tuple(x.name for x in self.sub.inputs)
        tables: list[str] = []
        calls: list[str] = []
        for pf in beh.functions:
            by_mask: dict[int, tuple[DataCase, str]] = {}
            for case in pf.cases:
                fn = "None" if case.void else self._case_function(b, beh, pf, case)
                by_mask[mask_of(case)] = (case, fn)
            table = f"CASES_{b}_{pf.index}"
            split = case_rule.split_of(pf.cases[0].new)
            tables.append(f"{table} = (  # {comment(f'{beh.name}: update {pf.target}')}")
            if case_rule.uniform([c.new for c in pf.cases]):
                for mask in range(1 << len(split)):
                    case, fn = by_mask[mask]
                    tables.append(f"{INDENT}({case.index}, {fn}),  # "
                                  + comment(combination_text(inputs, case.new)))
                pick = f"{table}[{row_source(split, len(inputs))}]"
            else:   # cubes (rssm_dsl/semantics/cases.py): the case whose fixed inputs match
                for case in pf.cases:
                    fn = "None" if case.void else self._case_function(b, beh, pf, case)
                    care, want = case_rule.care_want(case.new)
                    tables.append(f"{INDENT}({care:#x}, {want:#x}, ({case.index}, {fn})),  # "
                                  + comment(combination_text(inputs, case.new)))
                pick = f"next(c for m, w, c in {table} if mask & m == w)"
            tables.append(")")
            calls.append(f"{INDENT}r.partial({pick}, st, stage)  # "
                         + comment(f"f[{self.j},{self.sub.name},{beh.name},{pf.index}]: "
                                   f"update {pf.target}"))
        return tables, calls

    def _conditions(self, b: int, beh: Behaviour) -> list[str]:
        entries: list[str] = []
        for k, c in enumerate(beh.conditions, start=1):
            gen = self.gen()
            code = gen.expr(c.expr)
            self._note(gen)
            name = f"cond_{b}_{k}"
            self.functions.append((
                f"def {name}(st: State) -> bool:",
                f"{INDENT}# {comment(f'{c.kind} {c.name} when {expr_text(c.expr)}')}",
                *self._loads(gen), f"{INDENT}return {code}"))
            entries.append(f"({c.name!r}, {c.kind!r}, {name})")
        return [f"CONDITIONS_{b} = {tuple_source(entries)}"]

    def _switch(self, b: int, beh: Behaviour) -> list[str]:
        names = frozenset(c.name for c in beh.conditions)
        switches = self.sub.switches_from(beh.name)
        body: list[str] = []
        gens: list[PyGen] = []
        for sw in switches:
            target = "None" if sw.target is None else repr(sw.target)
            what = comment(f"switch {beh.name} -> {sw.target or 'end'}, "
                           f"{sw.span.file}:{sw.span.line}")
            if sw.condition is None:
                body += [f"{INDENT}return {target}  # otherwise: {what}"]
                break
            gen = self.gen(names)
            gen.extra_symbols = {c.name: Symbol("condition", BOOL, c.span)
                                 for c in beh.conditions}
            code = gen.expr(sw.condition)
            self._note(gen)
            gens.append(gen)
            body += [f"{INDENT}if {code}:  # {what}", f"{INDENT * 2}return {target}"]
        else:
            body.append(f"{INDENT}raise _NoSwitch({beh.name!r})")
        specials = sorted(set().union(*(g.specials_read for g in gens)) if gens else set())
        reads = sorted(set().union(*(g.reads for g in gens)) if gens else set())
        return [f"def switch_{b}(st: State, conds: Mapping[str, bool]) -> str | None:",
                f"{INDENT}# {comment(f'after {beh.name}: the first switch whose condition holds')}",
                *(f"{INDENT}{cond(n)} = conds.get({n!r}, False)" for n in specials),
                *(f"{INDENT}{var(n)} = st.{var(n)}" for n in reads), *body]

    def _behaviour(self, b: int, beh: Behaviour) -> BehaviourView:
        page = f"P^B[{self.j},{self.sub.name},{beh.name}]"
        tables, calls = self._tables(b, beh)
        tables += self._conditions(b, beh)
        iterate = [
            f"def iterate_{b}(r: _Runner) -> _Iteration:",
            f"{INDENT}# {comment(f'one iteration of behaviour {beh.name}, {page}')}",
            f"{INDENT}st = r.state",
            *self._steps(beh, calls),
            f"{INDENT}return r.conditions(CONDITIONS_{b})",
        ]
        targets = tuple_source([repr(pf.target) for pf in beh.functions])
        conds = tuple_source([repr(c.name) for c in beh.conditions])
        spec = (f"_Behaviour({beh.name!r}, iterate_{b}, switch_{b}, {targets}, {conds}, "
                f"{bool(beh.errors)})")
        return BehaviourView(beh.name, page, tuple(tables), tuple(iterate),
                             tuple(self._switch(b, beh)), spec)

    def _steps(self, beh: Behaviour, calls: list[str]) -> list[str]:
        """The lines of one iteration, in the order the behaviour page's net runs its steps
        (rssm_dsl.hpn.pattern)."""
        lines: list[str] = []
        for step in iteration(self.ctx.hpn, self.ctx.behaviour_pages[self.sub.id, beh.name]):
            match step:
                case Compute():
                    lines += [f"{INDENT}mask = r.begin()  # new(x) of the inputs, frozen for "
                              "the transition function",
                              f"{INDENT}stage: dict[str, Any] = {{}}", *calls,
                              f"{INDENT}r.commit(stage)  # memory and outputs of i + 1; "
                              "new(x) cleared"]
                case Send():
                    lines.append(f"{INDENT}yield from r.send({arrangement(step.arrangement)})")
                case Increment():
                    lines.append(f"{INDENT}r.increment()  # i := i + 1")
                case Receive():
                    lines.append(f"{INDENT}yield from r.receive({arrangement(step.arrangement)})")
        if not any("yield from" in line for line in lines):
            # no communication: nothing waits, but the runner drives every iteration as one
            lines.append(f"{INDENT}yield from ()  # no send or receive: nothing waits")
        return lines

    def _params(self, owner: str, params: tuple[Variable, ...]) -> tuple[ParamView, ...]:
        return tuple(ParamView(p.name, self.types.desc(p.type),
                               literal(self.ctx.values(owner, p))) for p in params)

    def build(self, package: str) -> NodeView:
        sub = self.sub
        initial = self._initial()
        behaviours = tuple(self._behaviour(b, beh)
                           for b, beh in enumerate(sub.behaviours, start=1))
        params = self._params(sub.id, sub.params)
        inputs = tuple(self.ctx.channel_view(x, self.types, self.descs) for x in sub.inputs)
        outputs = tuple(self.ctx.channel_view(x, self.types, self.descs) for x in sub.outputs)
        consts = const_lines(self.ctx.system, self.types) if self._uses_consts() else []
        node = node_name(sub.letter, sub.name)
        slots = tuple(var(n) for n in (*(p.name for p in sub.params),
                                       *(m.name for m in sub.memory),
                                       *(b.name for b in (*sub.inputs, *sub.outputs))))
        externs = tuple(self._extern(n) for n in sorted(self.externs))
        start = next(s.target for s in sub.switches if s.source is None)
        assert start is not None
        return NodeView(
            sub.id, sub.kind, f"node_{node}", node, node, f"/{self.agent}",
            number(float(sub.frequency)) if sub.frequency else "None",
            tuple(self.types.desc_lines()), tuple(self.types.converter_lines()),
            tuple(f"{name} = {src}" for src, name in self.descs.items()), externs,
            tuple(consts), slots, tuple(initial), tuple(self.functions), behaviours, start,
            params, inputs, outputs, ros_imports((*inputs, *outputs)))

    def _uses_consts(self) -> bool:
        return bool(self.ctx.system.consts)

    def _extern(self, name: str) -> ExternView:
        ext = self.ctx.externs[name]
        module, _, attr = ext.binding.partition(":")
        return ExternView(extern(name), module, attr, name)


class DeviceCode:
    """Builds the :class:`DeviceView` of one device with a binding."""

    def __init__(self, ctx: Context, dev: Device, agent: str, binding: str) -> None:
        self.ctx, self.dev, self.agent, self.binding = ctx, dev, agent, binding
        self.types = TypeTable()
        self.descs: dict[str, str] = {}

    def build(self, initial: Mapping[str, Any], package: str = "") -> DeviceView:
        d = self.dev
        ctx = self.ctx
        connected = [b for b in (*d.inputs, *d.outputs) if ctx.system.channel_of(b) is not None]
        chans = {b.name: ctx.channel_view(b, self.types, self.descs) for b in connected}
        node = node_name(d.letter, d.name)
        module, _, attr = self.binding.partition(":")
        params = tuple(ParamView(p.name, self.types.desc(p.type),
                                 literal(ctx.values(d.id, p))) for p in d.params)
        inputs = tuple((b.name, self.types.desc(b.type)) for b in d.inputs)
        outputs = tuple((b.name, self.types.desc(b.type)) for b in d.outputs)
        return DeviceView(
            d.id, d.name, d.device_type, d.kind, f"device_{node}", node, node, f"/{self.agent}",
            number(float(d.frequency)) if d.frequency else "None", module, attr,
            tuple(self.types.desc_lines()),
            tuple(f"{name} = {src}" for src, name in self.descs.items()), inputs, outputs,
            tuple(chans[b.name] for b in d.inputs if b.name in chans),
            tuple(chans[b.name] for b in d.outputs if b.name in chans),
            tuple((n, literal(v)) for n, v in initial.items()), params, package,
            ros_imports(tuple(chans.values())))
