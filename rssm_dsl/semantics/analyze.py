"""From the parsed program to the semantic model: the passes of the front end, in order."""

from __future__ import annotations

from dataclasses import replace

from rssm_dsl.diagnostics import DiagnosticBag, Related
from rssm_dsl.semantics.behaviours import BehaviourPass
from rssm_dsl.semantics.channels import ChannelPass
from rssm_dsl.semantics.checks import CHECKS, CheckContext
from rssm_dsl.semantics.declarations import DeclarationPass
from rssm_dsl.semantics.loader import Program
from rssm_dsl.semantics.model import Agent, Buffer, Device, Subsystem, System
from rssm_dsl.semantics.properties import check_properties
from rssm_dsl.semantics.structure import Shell, StructurePass
from rssm_dsl.syntax import ast


def _paired(shell: Shell, paired: dict[str, Buffer]) -> tuple[list[Buffer], list[Buffer]]:
    """The shell's buffers, replaced by their paired versions (with the peer set)."""
    buffers = [paired.get(b.qualified, b) for b in shell.buffers]
    return ([b for b in buffers if b.direction is ast.Direction.INPUT],
            [b for b in buffers if b.direction is ast.Direction.OUTPUT])


def analyze(program: Program, bag: DiagnosticBag) -> System | None:
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
    sysdecl = g.systems[0]
    agent_shells = StructurePass(bag, g, decls).run(sysdecl)
    channels = ChannelPass(bag, agent_shells).run()
    paired = {b.qualified: b for ch in channels for b in (ch.producer, ch.consumer)}

    agents: list[Agent] = []
    sub_decls: dict[str, ast.SubsystemDecl] = {}
    written: dict[str, set[str]] = {}
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
            bp = BehaviourPass(bag, g, shell)
            behaviours, switches = bp.run(shell.decl)
            sub = Subsystem(a.name, shell.kind, shell.name, shell.span, shell.frequency,
                            tuple(shell.params), tuple(shell.memory), tuple(inputs),
                            tuple(outputs), behaviours, switches)
            subsystems.append(sub)
            sub_decls[sub.id] = shell.decl
            written[sub.id] = bp.usage.written
            unchecked[sub.id] = bp.unchecked
        agents.append(Agent(a.name, a.span, tuple(subsystems), tuple(devices)))

    system = System(sysdecl.name, sysdecl.span, tuple(agents), tuple(channels),
                    tuple(g.consts.values()), tuple(g.externs.values()),
                    tuple(sorted(g.types.items())))
    property_reads: dict[str, set[str]] = {}
    properties = check_properties(bag, system, sysdecl.properties, g.symbols(), sub_decls,
                                  property_reads)
    ctx = CheckContext(bag, system, sub_decls, written, unchecked, property_reads,
                       root_file=root.span.file)
    for check in CHECKS:
        check(ctx)
    return replace(system, properties=properties)
