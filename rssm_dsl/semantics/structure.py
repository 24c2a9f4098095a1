"""The structure of the system (paper III-A): agents, subsystems, devices and their buffers."""

from __future__ import annotations

from dataclasses import field, replace

from rssm_core.modes import Mode
from rssm_core.records import dataclass
from rssm_dsl.diagnostics import DiagnosticBag, Related
from rssm_dsl.semantics.declarations import DeclarationPass, Globals
from rssm_dsl.semantics.model import DEVICE_LETTER, KIND_LETTER, Buffer, Variable
from rssm_dsl.semantics.typecheck import ExprChecker, Scope, Symbol, did_you_mean, mismatch_hint
from rssm_dsl.semantics.types import Type, assignable
from rssm_dsl.source import Span
from rssm_dsl.syntax import ast

# The highest frequency a subsystem or device may be given: above the fastest loops of robot
# hardware (drives' current loops, 10-40 kHz); 1 s of a 1 GHz subsystem would be 10^9
# iterations for the interpreter (E209).
MAX_HERTZ = 100_000.0


@dataclass
class Shell:
    """A subsystem or device whose buffers are known but not yet paired."""

    agent: str
    kind: str                 # control/effector/receptor, or E/R device kind
    name: str
    device: bool
    span: Span
    frequency: float | None
    params: list[Variable] = field(default_factory=list)
    memory: list[Variable] = field(default_factory=list)
    buffers: list[Buffer] = field(default_factory=list)
    peers: dict[str, ast.PeerRef | None] = field(default_factory=dict)  # buffer name -> peer
    decl: ast.SubsystemDecl | None = None
    device_type: str = ""
    binding: str | None = None
    binding_span: Span | None = None
    # params, memory and buffers whose type could not be resolved (an error was reported):
    # later passes know the names but say nothing more about them
    unresolved: list[ast.ParamDecl | ast.MemoryDecl | ast.BufferDecl] = field(
        default_factory=list)

    @property
    def letter(self) -> str:
        return DEVICE_LETTER[self.kind] if self.device else KIND_LETTER[self.kind]

    id: str = ""              # qualified id, e.g. "a1.c", "a1.e.lwr", "a1.E.lwr"

    def __post_init__(self) -> None:
        control = not self.device and self.kind == "control"
        self.id = f"{self.agent}.c" if control else f"{self.agent}.{self.letter}.{self.name}"

    def inputs(self) -> list[Buffer]:
        return [b for b in self.buffers if b.direction is ast.Direction.INPUT]

    def outputs(self) -> list[Buffer]:
        return [b for b in self.buffers if b.direction is ast.Direction.OUTPUT]


@dataclass
class AgentShell:
    name: str
    span: Span
    shells: list[Shell]
    broken: set[str] = field(default_factory=set)  # ids of device instances already reported


class StructurePass:
    def __init__(self, bag: DiagnosticBag, g: Globals, decls: DeclarationPass) -> None:
        self.bag = bag
        self.g = g
        self.decls = decls
        self.checker = ExprChecker(bag)

    def unique_agents(self, system: ast.SystemDecl) -> list[ast.AgentDecl]:
        """The system's agents, but the second of two with one name (reported)."""
        agents: list[ast.AgentDecl] = []
        seen: dict[str, Span] = {}
        for a in system.agents:
            if a.name in seen:
                self.bag.error("E101", f"agent '{a.name}' is declared twice", a.name_span,
                               related=(Related(seen[a.name], "first declared here"),))
                continue
            seen[a.name] = a.name_span
            agents.append(a)
        return agents

    def agent(self, a: ast.AgentDecl) -> AgentShell:
        shells: list[Shell] = []
        broken: set[str] = set()
        controls = [s for s in a.subsystems if s.kind is ast.SubsystemKind.CONTROL]
        if len(controls) != 1:
            self.bag.error(
                "E301", f"agent '{a.name}' has {len(controls)} control subsystems; it needs exactly one",
                controls[1].span if len(controls) > 1 else a.name_span,
                "an agent a_j has one control subsystem c_j (paper III-A)",
            )
        names: dict[tuple[bool, str], Span] = {}
        for s in sorted(a.subsystems, key=lambda s: s.kind is not ast.SubsystemKind.CONTROL):
            if s.kind is ast.SubsystemKind.CONTROL and s is not controls[0]:
                continue  # E301 above; the extra control subsystems are not analysed
            key = (False, s.name)
            if key in names:
                self.bag.error("E101", f"subsystem '{s.name}' is declared twice in agent "
                               f"'{a.name}'", s.name_span,
                               related=(Related(names[key], "first declared here"),))
                continue
            names[key] = s.name_span
            shells.append(self._subsystem(a.name, s))
        for d in a.devices:
            key = (True, d.name)
            if key in names:
                self.bag.error("E101", f"device '{d.name}' is declared twice in agent '{a.name}'",
                               d.name_span, related=(Related(names[key], "first declared here"),))
                continue
            names[key] = d.name_span
            shell = self._device(a.name, d)
            if shell is not None:
                shells.append(shell)
            else:
                broken.add(f"{a.name}.{DEVICE_LETTER[d.kind.value]}.{d.name}")
        return AgentShell(a.name, a.span, shells, broken)

    # ------------------------------------------------------------------ variables
    def _variable(self, name: str, span: Span, t: ast.TypeExpr, init: ast.Expr | None,
                  scope: Scope, what: str) -> Variable | None:
        vt = self.decls.resolve_type(t)
        if vt is None:
            return None
        if init is not None:
            self._initial(init, scope, vt, f"{what} '{name}'")
        return Variable(name, vt, init, span)

    def _initial(self, init: ast.Expr, scope: Scope, t: Type, what: str) -> None:
        """Check the initial value of a variable or buffer (``what``: "memory 'x'")."""
        got = self.checker.check(init, scope, t)
        if got is not None and not assignable(got, t):
            self.bag.error("E201", f"{what} is {t} but its initial value is {got}", init.span,
                           hint=mismatch_hint(got, t))
        elif got is not None:
            self.checker.fits(init, t, what)

    def _frequency(self, f: ast.Frequency | None) -> float | None:
        if f is None:
            return None
        if f.hertz <= 0:
            self.bag.error("E209", f"a frequency must be positive, not {f.hertz:g} Hz", f.span,
                           "leave the frequency out to run as fast as communication allows")
            return None
        if f.hertz > MAX_HERTZ:
            self.bag.error("E209", f"a frequency must be at most {MAX_HERTZ / 1000:g} kHz, not "
                           f"{f.hertz:g} Hz", f.span,
                           "a controller's loop runs at most at tens of kHz; leave the "
                           "frequency out to run as fast as communication allows")
            return None
        return f.hertz

    def _fill(self, shell: Shell, params: tuple[ast.ParamDecl, ...],
              memory: tuple[ast.MemoryDecl, ...], buffers: tuple[ast.BufferDecl, ...]) -> None:
        local: dict[str, Span] = {}

        def declare(name: str, span: Span) -> bool:
            if name in local:
                self.bag.error("E101", f"'{name}' is declared twice in {shell.id}", span,
                               related=(Related(local[name], "first declared here"),))
                return False
            if name == "memory":
                self.bag.error("E101", "'memory' names the memory target of `update`; "
                               "choose another name", span)
                return False
            local[name] = span
            return True

        init_scope = Scope(self.g.symbols(), self.g.externs, no_calls="an initial value")
        for p in params:
            if declare(p.name, p.name_span):
                v = self._variable(p.name, p.span, p.type, p.value, init_scope, "param")
                if v is not None:
                    shell.params.append(v)
                else:
                    shell.unresolved.append(p)
                init_scope.symbols[p.name] = Symbol("param", v.type if v else None, p.span)
        for m in memory:
            if declare(m.name, m.name_span):
                v = self._variable(m.name, m.span, m.type, m.init, init_scope, "memory")
                if v is not None:
                    shell.memory.append(v)
                else:
                    shell.unresolved.append(m)
        for b in buffers:
            if not declare(b.name, b.name_span):
                continue
            bt = self.decls.resolve_type(b.type)
            if bt is None:
                shell.unresolved.append(b)
                continue
            if b.init is not None:
                self._initial(b.init, init_scope, bt, f"buffer '{b.name}'")
            mode = b.mode or Mode.NONBLOCKING
            shell.buffers.append(Buffer(shell.id, b.name, b.direction, bt, mode, b.init, b.span))
            shell.peers[b.name] = b.peer

    def _subsystem(self, agent: str, s: ast.SubsystemDecl) -> Shell:
        shell = Shell(agent, s.kind.value, s.name, False, s.span, self._frequency(s.frequency),
                      decl=s)
        self._fill(shell, s.params, s.memory, s.buffers)
        for b in s.buffers:
            want = "to" if b.direction is ast.Direction.OUTPUT else "from"
            if b.arrow is not None and b.arrow[0] != want:
                self.bag.error("E309", f"{b.direction.value} '{b.name}' names its peer with "
                               f"`{b.arrow[0]}`", b.arrow[1],
                               f"an {b.direction.value} {'sends to' if want == 'to' else 'receives from'}"
                               f" its peer: write `{want}`, or change the direction")
            if b.peer is None:
                self.bag.error("E307", f"buffer '{b.name}' of {shell.id} does not say which "
                               "subsystem it talks to", b.name_span,
                               f"e.g. `{b.direction.value} {b.name}: ... "
                               f"{'to' if b.direction is ast.Direction.OUTPUT else 'from'} "
                               f"{_usual_peer(s.kind, b.direction)}`")
        return shell

    def _device(self, agent: str, d: ast.DeviceInstance) -> Shell | None:
        decl = self.g.devices.get(d.device)
        if decl is None:
            known = ", ".join(sorted(self.g.devices)) or "none"
            guess = did_you_mean(d.device, self.g.devices)
            if d.device in self.g.spans:
                self.bag.error("E103", f"'{d.device}' is not a device type", d.device_span,
                               f"device types declared or imported: {known}")
            else:
                self.bag.error("E102", f"unknown device type '{d.device}'", d.device_span,
                               f"did you mean '{guess}'?" if guess else
                               "declare it with `device effector NAME { ... }` or import it")
            return None
        if decl.kind is not d.kind:
            self.bag.error("E308", f"'{d.device}' is a real {decl.kind.value}, declared here as a "
                           f"real {d.kind.value}", d.span,
                           related=(Related(decl.name_span, "device type declared here"),))
        shell = Shell(agent, decl.kind.value, d.name, True, d.span,
                      self._frequency(d.frequency or decl.frequency), device_type=decl.name,
                      binding=decl.binding.binding if decl.binding else None,
                      binding_span=decl.binding.span if decl.binding else None)
        self._fill(shell, self._instance_params(d, decl), (), decl.buffers)
        for b in decl.buffers:
            if b.peer is not None:
                self.bag.error("E302", "a device buffer does not name its peer; the virtual "
                               "subsystem names the device", b.peer.span)
        return shell


    def _instance_params(self, d: ast.DeviceInstance,
                         decl: ast.DeviceDecl) -> tuple[ast.ParamDecl, ...]:
        """The device type's parameters, with the values this instance gives
        (``real effector big: Heater(watts = 2000.0)``) in place of the type's."""
        declared = {p.name: p for p in decl.params}
        given: dict[str, ast.DeviceArg] = {}
        for a in d.args:
            if a.name not in declared:
                guess = did_you_mean(a.name, declared)
                names = ", ".join(declared) or "none"
                self.bag.error("E310", f"device type {decl.name} has no parameter '{a.name}'",
                               a.name_span,
                               f"did you mean '{guess}'?" if guess else
                               f"its parameters: {names}",
                               related=(Related(decl.name_span, "device type declared here"),))
            elif a.name in given:
                self.bag.error("E101", f"parameter '{a.name}' of {d.name} is given twice",
                               a.name_span,
                               related=(Related(given[a.name].name_span, "first given here"),))
            else:
                given[a.name] = a
        return tuple(replace(p, value=given[p.name].value) if p.name in given else p
                     for p in decl.params)


def _usual_peer(kind: ast.SubsystemKind, direction: ast.Direction) -> str:
    """The peer a buffer of this subsystem kind and direction usually names."""
    if kind is ast.SubsystemKind.CONTROL:
        return "e.NAME" if direction is ast.Direction.OUTPUT else "r.NAME"
    device = "E.NAME" if kind is ast.SubsystemKind.EFFECTOR else "R.NAME"
    to_c = (direction is ast.Direction.INPUT) == (kind is ast.SubsystemKind.EFFECTOR)
    return "c" if to_c else device
