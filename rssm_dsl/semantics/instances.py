"""Agents defined once and instantiated (docs/language.md, "Agent definitions"): the
system's `agent NAME: DEFINITION(ARGS)` lines made into the agents they declare, before the
structure pass sees the system.

An instance is its definition's agent under the instance's name: the same subsystems,
devices and behaviours (their spans are the definition's, so a diagnostic found in one
instance points at the definition and names the instance's subsystems, `r3.c`), with

* every peer whose first part is a parameter of type `agent` renamed to the agent the
  instance gives it (`from boss.c` becomes `from coord.c`);
* every other parameter a `param` of each subsystem of the definition whose expressions
  read it, with the instance's value (or the default): a name the definition's subsystems
  read like their own parameters, one value per instance.

`agent r[1..8]: Robot(...)` declares r1, ..., r8, all with the same arguments.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping
from typing import Any

from rssm_dsl.diagnostics import DiagnosticBag, Related
from rssm_dsl.semantics.checks.usage import names_read
from rssm_dsl.semantics.typecheck import did_you_mean
from rssm_dsl.source import Span
from rssm_dsl.syntax import ast


def expand(system: ast.SystemDecl, definitions: Mapping[str, ast.AgentDef],
           bag: DiagnosticBag) -> tuple[ast.SystemDecl, frozenset[str]]:
    """``system`` with its instance lines made into agents, in the order of the text, and
    the names of the agents of the lines that declare none: each problem with an instance
    line goes to ``bag``, and what names those agents is not reported again (no "there is
    no agent r3" after the error on r3's line)."""
    if not system.instances:
        return system, frozenset()
    agent_names = {a.name for a in system.agents}
    for inst in system.instances:
        agent_names.update(inst.names())
    placed: list[tuple[int, ast.AgentDecl]] = [(a.span.offset, a) for a in system.agents]
    reads: dict[int, frozenset[str]] = {}       # by id of a definition's subsystem
    failed: set[str] = set()
    for inst in system.instances:
        made = _instantiate(inst, definitions, agent_names, reads, bag)
        placed += [(inst.span.offset, a) for a in made]
        if not made:
            failed.update(_meant(inst))
    placed.sort(key=lambda x: x[0])             # stable: r1, ..., r8 of one line in order
    return dataclasses.replace(system, agents=tuple(a for _, a in placed)), frozenset(failed)


def _instantiate(inst: ast.AgentInstance, definitions: Mapping[str, ast.AgentDef],
                 agent_names: set[str], reads: dict[int, frozenset[str]],
                 bag: DiagnosticBag) -> list[ast.AgentDecl]:
    d = definitions.get(inst.definition)
    if d is None:
        guess = did_you_mean(inst.definition, definitions)
        bag.error("E311", f"no agent definition '{inst.definition}'", inst.definition_span,
                  f"did you mean '{guess}'?" if guess else
                  "define it outside the system: `agent NAME(PARAM: TYPE, ...) { control "
                  "{ ... } }`" + (f"; defined: {', '.join(sorted(definitions))}"
                                  if definitions else ""))
        return []
    if inst.lo is not None and inst.hi is not None and not inst.range_ok():
        what = (f"names agents with a negative index ({inst.name}{inst.lo})" if inst.lo < 0
                else f"declares {max(inst.hi - inst.lo + 1, 0):,} agents")
        bag.error("E313", f"'{inst.name}[{inst.lo}..{inst.hi}]' {what}", inst.name_span,
                  f"write LOW..HIGH with 0 <= LOW <= HIGH and at most {ast.MAX_INSTANCES:,} "
                  "agents")
        return []
    values = _arguments(inst, d, agent_names, bag)
    if values is None:
        return []
    peers = {p.name: values[p.name] for p in d.params if p.type is None}
    given = {p.name: (p, values[p.name]) for p in d.params if p.type is not None}
    subsystems = []
    for s in d.subsystems:
        if id(s) not in reads:
            reads[id(s)] = frozenset(names_read(s))
        subsystems.append(_subsystem(s, peers, given, reads[id(s)], d.name, bag))
    return [ast.AgentDecl(inst.span, name, inst.name_span, tuple(subsystems), d.devices,
                          instance_of=d.name) for name in inst.names()]


def definition_agent(d: ast.AgentDef) -> ast.AgentDecl:
    """The definition as an agent under its own name, its value parameters the ``param``s
    of the subsystems that read them (with their defaults; a parameter without one stands
    for itself): what the language server indexes of the definition's text."""
    given = {p.name: (p, p.default if p.default is not None else ast.Name(p.name_span, p.name))
             for p in d.params if p.type is not None}
    subsystems = tuple(_subsystem(s, {}, given, frozenset(names_read(s)), d.name,
                                  DiagnosticBag()) for s in d.subsystems)
    return ast.AgentDecl(d.span, d.name, d.name_span, subsystems, d.devices)


def _arguments(inst: ast.AgentInstance, d: ast.AgentDef, agent_names: set[str],
               bag: DiagnosticBag) -> dict[str, Any] | None:
    """Each parameter's value (an agent's name, or the expression of a value), None when
    one is missing or wrong (reported)."""
    params = {p.name: p for p in d.params}
    out: dict[str, Any] = {}
    ok = True
    for arg in inst.args:
        p = params.get(arg.name)
        if p is None:
            guess = did_you_mean(arg.name, params)
            bag.error("E312", f"agent definition '{d.name}' has no parameter '{arg.name}'",
                      arg.name_span, f"did you mean '{guess}'?" if guess else
                      ("its parameters: " + ", ".join(params) if params else
                       f"'{d.name}' takes no arguments"),
                      related=(Related(d.name_span, "defined here"),))
            ok = False
        elif arg.name in out:
            bag.error("E312", f"parameter '{arg.name}' is given twice", arg.name_span)
            ok = False
        elif p.type is None:
            if not isinstance(arg.value, ast.Name) or arg.value.name not in agent_names:
                _not_an_agent(arg, d, agent_names, bag)
                ok = False
            else:
                out[arg.name] = arg.value.name
        else:
            out[arg.name] = arg.value
    for p in d.params:
        if p.name in out or any(a.name == p.name for a in inst.args):
            continue
        if p.default is not None:
            out[p.name] = p.default
            continue
        bag.error("E312", f"'{inst.definition}' needs a value for its parameter '{p.name}'",
                  inst.span, f"write `{p.name} = ...` in the parentheses after "
                  f"'{inst.definition}'", related=(Related(p.span, "declared here"),))
        ok = False
    return out if ok else None


def _meant(inst: ast.AgentInstance) -> tuple[str, ...]:
    """The agents a line meant to declare (a range written high to low: those between)."""
    lo, hi = inst.lo, inst.hi
    if lo is None or hi is None or inst.range_ok():
        return inst.names()
    lo, hi = max(min(lo, hi), 0), max(lo, hi)     # (a negative index names no agent)
    if hi < lo or hi - lo >= ast.MAX_INSTANCES:
        return ()
    return tuple(f"{inst.name}{k}" for k in range(lo, hi + 1))


def _not_an_agent(arg: ast.DeviceArg, d: ast.AgentDef, agent_names: set[str],
                  bag: DiagnosticBag) -> None:
    """E312: an `agent` parameter given something that is not an agent's name."""
    v = arg.value
    if isinstance(v, ast.FieldAccess) and isinstance(v.value, ast.Name) and \
            v.value.name in agent_names:
        said, hint = f"{v.value.name}.{v.field}", f"give the agent alone: `{arg.name} = " \
            f"{v.value.name}` (the definition names its subsystems, `{arg.name}.c`)"
    elif isinstance(v, ast.Name):
        guess = did_you_mean(v.name, agent_names)
        said = v.name
        hint = (f"did you mean '{guess}'?" if guess else "give the name of an agent of this "
                "system" + (f": {', '.join(sorted(agent_names)[:6])}" if agent_names else ""))
    else:
        said, hint = "this value", "give the name of an agent of this system"
    bag.error("E312", f"parameter '{arg.name}' of '{d.name}' is an agent, and '{said}' is "
              "no agent of the system", v.span, hint)


def _subsystem(s: ast.SubsystemDecl, peers: Mapping[str, str],
               given: Mapping[str, tuple[ast.AgentParam, Any]], reads: frozenset[str],
               definition: str, bag: DiagnosticBag) -> ast.SubsystemDecl:
    buffers = tuple(
        dataclasses.replace(b, peer=dataclasses.replace(
            b.peer, parts=(peers[b.peer.parts[0]], *b.peer.parts[1:])))
        if b.peer is not None and b.peer.parts and b.peer.parts[0] in peers else b
        for b in s.buffers)
    own: dict[str, Span] = {x.name: x.name_span for x in s.memory}
    own.update({x.name: x.name_span for x in s.buffers})
    own.update({x.name: x.name_span for x in s.params})
    params = list(s.params)
    for name, (p, value) in given.items():
        if name not in reads:
            continue
        if name in own:
            bag.error("E312", f"'{name}' of {s.name} hides the parameter '{name}' of agent "
                      f"definition '{definition}'", own[name],
                      "rename one of them", related=(Related(p.name_span, "the parameter"),))
            continue
        assert p.type is not None
        params.append(ast.ParamDecl(p.span, name, p.name_span, p.type, value))
    return dataclasses.replace(s, buffers=buffers, params=tuple(params))
