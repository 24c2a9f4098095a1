"""From the parsed program to the semantic model: the passes of the front end, in order."""

from __future__ import annotations

import threading
from bisect import bisect_right
from collections.abc import Mapping
from dataclasses import field, replace

from rssm_core.records import dataclass
from rssm_dsl.diagnostics import Diagnostic, DiagnosticBag, Related
from rssm_dsl.semantics.behaviours import BehaviourPass
from rssm_dsl.semantics.channels import ChannelPass
from rssm_dsl.semantics.checks import CHECKS, CheckContext
from rssm_dsl.semantics.checks.context import CheckCache
from rssm_dsl.semantics.checks.usage import names_read
from rssm_dsl.semantics.declarations import DeclarationPass, Globals
from rssm_dsl.semantics.instances import expand
from rssm_dsl.semantics.loader import Program
from rssm_dsl.semantics.model import Agent, Behaviour, Buffer, Device, Subsystem, Switch, System
from rssm_dsl.semantics.properties import check_properties
from rssm_dsl.semantics.structure import AgentShell, Shell, StructurePass
from rssm_dsl.semantics.typecheck import new_suggestions
from rssm_dsl.syntax import ast
from rssm_dsl.syntax.walk import names


def _paired(shell: Shell, paired: dict[str, Buffer]) -> tuple[list[Buffer], list[Buffer]]:
    """The shell's buffers, replaced by their paired versions (with the peer set)."""
    buffers = [paired.get(b.qualified, b) for b in shell.buffers]
    return ([b for b in buffers if b.direction is ast.Direction.INPUT],
            [b for b in buffers if b.direction is ast.Direction.OUTPUT])


@dataclass(frozen=True)
class Behaviours:
    """What the behaviour pass made of one subsystem."""

    behaviours: tuple[Behaviour, ...]
    switches: tuple[Switch, ...]
    written: set[str]
    unchecked: set[str]
    read: set[str]                  # the names its expressions read (checks/usage.py)


@dataclass(frozen=True)
class AgentWork:
    """What the structure and behaviour passes made of one agent declaration, and what they
    reported. It depends on nothing but that declaration and the declarations outside
    systems (types, constants, externs, devices)."""

    decl: ast.AgentDecl
    shell: AgentShell
    subsystems: dict[str, Behaviours]       # by the shell's id
    diagnostics: tuple[Diagnostic, ...]


@dataclass
class AgentMemo:
    """The work of each agent of the last analysis, reused by the next one for every agent
    whose declaration is the same AST object while the declarations outside systems are
    the same objects too. The language server keeps one per document: an edit inside one
    agent reparses that agent alone (lsp/incremental.py), so every other agent is reused.
    Analyses in several threads may share one: each reads a snapshot and stores a whole
    new one."""

    outside: tuple[ast.Decl, ...] = ()
    agents: dict[int, AgentWork] = field(default_factory=dict)   # by id(decl)
    checks: CheckCache = field(default_factory=CheckCache)      # what the checks found
    lock: threading.Lock = field(default_factory=threading.Lock, repr=False)

    def reusable(self, outside: tuple[ast.Decl, ...]) -> dict[int, AgentWork]:
        with self.lock:
            same = len(outside) == len(self.outside) and all(
                a is b for a, b in zip(outside, self.outside, strict=True))
            return self.agents if same else {}

    def keep(self, outside: tuple[ast.Decl, ...], works: list[AgentWork]) -> None:
        with self.lock:
            self.outside = outside
            self.agents = {id(w.decl): w for w in works}


def _outside_systems(program: Program) -> tuple[ast.Decl, ...]:
    return tuple(d for m in program.modules for d in m.decls
                 if not isinstance(d, ast.SystemDecl))


def _agent_work(a: ast.AgentDecl, g: Globals, decls: DeclarationPass) -> AgentWork:
    bag = DiagnosticBag()
    with decls.reporting_to(bag):
        shell = StructurePass(bag, g, decls).agent(a)
    subsystems: dict[str, Behaviours] = {}
    for s in shell.shells:
        if not s.device:
            assert s.decl is not None
            bp = BehaviourPass(bag, g, s)
            behaviours, switches = bp.run(s.decl)
            subsystems[s.id] = Behaviours(behaviours, switches, bp.usage.written, bp.unchecked,
                                          names_read(s.decl))
    return AgentWork(a, shell, subsystems, tuple(bag.items))


def _once_per_definition(bag: DiagnosticBag, start: int,
                         definitions: Mapping[str, ast.AgentDef]) -> None:
    """The diagnostics from ``start`` on that point into an agent definition's text, one per
    problem: each instance finds it again, so the first instance's is kept, saying how many
    others have it too."""
    if not definitions:
        return
    # per file, the definitions' (start, end, name) in the order of their starts (top-level
    # declarations do not overlap): each diagnostic's is found by bisection, not by a scan
    # of all the definitions (diagnostics times definitions)
    inside: dict[str, list[tuple[int, int, str]]] = {}
    for x in definitions.values():
        inside.setdefault(x.span.file, []).append((x.span.offset, x.span.end_offset, x.name))
    starts: dict[str, list[int]] = {}
    for f, spans in inside.items():
        spans.sort()
        starts[f] = [a for a, _, _ in spans]

    def definition_of(d: Diagnostic) -> str | None:
        spans = inside.get(d.span.file)
        if spans is None:
            return None
        at = bisect_right(starts[d.span.file], d.span.offset) - 1
        if at >= 0 and spans[at][0] <= d.span.offset < spans[at][1]:
            return spans[at][2]
        return None

    kept: list[Diagnostic] = []
    count: dict[tuple[str, str, int, int], int] = {}
    first: dict[tuple[str, str, int, int], int] = {}
    owner: dict[tuple[str, str, int, int], str] = {}
    for d in bag.items[start:]:
        name = definition_of(d)
        if name is None:
            kept.append(d)
            continue
        key = (d.code, d.span.file, d.span.offset, d.span.end_offset)
        if key in first:
            count[key] += 1
            continue
        first[key], count[key], owner[key] = len(kept), 0, name
        kept.append(d)
    for key, at in first.items():
        n = count[key]
        if n:
            kept[at] = replace(kept[at], message=f"{kept[at].message} (and in {n} more "
                               f"instance{'s' if n > 1 else ''} of {owner[key]})")
    bag.items[start:] = kept


def analyze(program: Program, bag: DiagnosticBag, memo: AgentMemo | None = None
            ) -> System | None:
    """The semantic model of the program (None when it has no single system); every
    problem goes to `bag`. With `memo`, agents unchanged since the last call are not
    analysed again."""
    new_suggestions()
    start = len(bag.items)
    try:
        return _analyze(program, bag, memo)
    finally:
        _once_per_definition(bag, start, _definitions(program))


def _definitions(program: Program) -> dict[str, ast.AgentDef]:
    return {d.name: d for m in program.modules for d in m.decls if isinstance(d, ast.AgentDef)}


def _analyze(program: Program, bag: DiagnosticBag, memo: AgentMemo | None) -> System | None:
    decls = DeclarationPass(bag)
    g = decls.run(program.modules, program.root)
    root = program.root
    if root is None:
        return None
    if len(g.systems) != 1:
        if not g.systems:
            bag.error("E104", "this file declares no system", root.span,
                      "write `system NAME { agent a1 { control { ... } } }`; library modules "
                      "are imported, not compiled")
        else:
            bag.error("E104", f"this file declares {len(g.systems)} systems; compile one at a "
                      "time", g.systems[1].name_span,
                      related=(Related(g.systems[0].name_span, "the first system"),))
        return None
    sysdecl, failed = expand(g.systems[0], g.agent_defs, bag)
    outside = _outside_systems(program) if memo is not None else ()
    reusable = memo.reusable(outside) if memo is not None else {}
    works: list[AgentWork] = []
    for decl in StructurePass(bag, g, decls).unique_agents(sysdecl):
        work = reusable.get(id(decl))
        if work is None or work.decl is not decl:
            work = _agent_work(decl, g, decls)
        for d in work.diagnostics:
            bag.add(d)
        works.append(work)
    checks = CheckCache(memo.checks) if memo is not None and reusable else CheckCache()
    if memo is not None:
        memo.keep(outside, works)
    agent_shells = [w.shell for w in works]
    done = {sid: b for w in works for sid, b in w.subsystems.items()}
    channels = ChannelPass(bag, agent_shells, failed).run()
    paired = {b.qualified: b for ch in channels for b in (ch.producer, ch.consumer)}

    agents: list[Agent] = []
    sub_decls: dict[str, ast.SubsystemDecl] = {}
    written: dict[str, set[str]] = {}
    read: dict[str, set[str]] = {}
    unchecked: dict[str, set[str]] = {}
    for a in agent_shells:
        subsystems: list[Subsystem] = []
        devices: list[Device] = []
        for shell in a.shells:
            inputs, outputs = _paired(shell, paired)
            if shell.device:
                devices.append(Device(a.name, shell.kind, shell.name, shell.device_type,
                                      shell.span, shell.frequency, tuple(shell.params),
                                      tuple(inputs), tuple(outputs), shell.binding,
                                      shell.binding_span))
                continue
            assert shell.decl is not None
            b = done[shell.id]
            sub = Subsystem(a.name, shell.kind, shell.name, shell.span, shell.frequency,
                            tuple(shell.params), tuple(shell.memory), tuple(inputs),
                            tuple(outputs), b.behaviours, b.switches)
            subsystems.append(sub)
            sub_decls[sub.id] = shell.decl
            written[sub.id] = b.written
            read[sub.id] = b.read
            unchecked[sub.id] = b.unchecked
        agents.append(Agent(a.name, a.span, tuple(subsystems), tuple(devices)))

    system = System(sysdecl.name, sysdecl.span, tuple(agents), tuple(channels),
                    tuple(g.consts.values()), tuple(g.externs.values()),
                    tuple(sorted(g.types.items())))
    property_reads: dict[str, set[str]] = {}
    # (a property of an agent whose instance line failed is not checked: it was reported)
    properties = check_properties(bag, system, tuple(
        p for p in sysdecl.properties if not failed.intersection(
            n.name for e in p.expressions for n in names(e))), g.symbols(), sub_decls,
        property_reads)
    ctx = CheckContext(bag, system, sub_decls, written, read, unchecked, property_reads,
                       root_file=root.span.file, cache=checks if memo is not None else None)
    for check in CHECKS:
        check(ctx)
    if memo is not None:
        memo.checks = checks
    return replace(system, properties=properties)
