"""Hover: what a name is (its kind and type) and where it sits in the HPN, in the paper's
notation (pages P[j], P[j,v], P^B[j,v,omega], P^f[j,v,omega,psi], transitions, fused
places)."""

from __future__ import annotations

from collections.abc import Callable

from rssm_dsl.hpn import names as N
from rssm_dsl.lsp.index import Definition
from rssm_dsl.lsp.scope import Env
from rssm_dsl.semantics.behaviours import combination_text
from rssm_dsl.semantics.model import Agent, Buffer, Channel, Device, Subsystem, System
from rssm_dsl.semantics.types import EnumT, RecordT, Type
from rssm_dsl.syntax import ast

_LETTER_TEXT = {"c": "control subsystem", "e": "virtual effector", "r": "virtual receptor",
                "E": "real effector", "R": "real receptor"}


def _code(text: str) -> str:
    return f"```rssm\n{text}\n```"


def _type(t: Type) -> str:
    """A type, written out: a record with its fields, an enum with its members."""
    if isinstance(t, RecordT):
        fields = ", ".join(f"{n}: {ft}" for n, ft in t.fields)
        return f"`{t.name}` = record {{{fields}}}"
    if isinstance(t, EnumT):
        return f"`{t.name}` = enum {{{', '.join(t.members)}}}"
    return f"`{t}`"


def _split(base: str) -> tuple[str, list[str]]:
    """'a1.e.lwr.torque' -> ('a1.e.lwr', ['torque']); 'a1.c.cw.x' -> ('a1.c', ['cw', 'x'])."""
    parts = base.split(".")
    n = 2 if len(parts) > 1 and parts[1] == "c" else 3
    return ".".join(parts[:n]), parts[n:]


class _Model:
    def __init__(self, system: System) -> None:
        self.system = system
        self.agents: dict[str, Agent] = {a.name: a for a in system.agents}
        self.subs: dict[str, Subsystem] = {s.id: s for s in system.subsystems()}
        self.devices: dict[str, Device] = {d.id: d for d in system.devices()}
        self.j: dict[str, str] = {s.id: a.designator for a in system.agents
                                  for s in a.subsystems}
        self.j.update({d.id: a.designator for a in system.agents for d in a.devices})

    def owner(self, sid: str) -> Subsystem | Device | None:
        return self.subs.get(sid) or self.devices.get(sid)


def _v(x: Subsystem | Device) -> str:
    return x.name if isinstance(x, Subsystem) else f"{x.letter}.{x.name}"


def _subsystem_symbol(s: Subsystem, j: str) -> str:
    return "c_" + j if s.letter == "c" else f"{s.letter}_{{{j},{s.name}}}"


def _channel_text(m: _Model, ch: Channel) -> str:
    prod, cons = m.owner(ch.producer.owner), m.owner(ch.consumer.owner)
    if prod is None or cons is None:
        return f"channel `{ch.id}`"
    rho = [b.name for b in prod.outputs].index(ch.producer.name) + 1
    kappa = [b.name for b in cons.inputs].index(ch.consumer.name) + 1
    fused = [N.fusion((m.j[prod.id], m.j[cons.id]), (_v(prod), _v(cons)), (rho, kappa), w)
             for w in (1, 2)]
    return (f"channel `{ch.producer.qualified} -> {ch.consumer.qualified}` ({ch.modes}); "
            f"fused places `{fused[0]}` (full) and `{fused[1]}` (empty)")


def _buffer(m: _Model, owner: Subsystem | Device, name: str) -> list[str]:
    buf: Buffer | None = next((b for b in (*owner.inputs, *owner.outputs) if b.name == name),
                              None)
    if buf is None:
        return []
    j = m.j[owner.id]
    out = [f"type {_type(buf.type)}, mode `{buf.mode.value}`"]
    output = buf.direction is ast.Direction.OUTPUT
    k = [b.name for b in (owner.outputs if output else owner.inputs)].index(name) + 1
    verb = "snd" if output else "rcv"
    if isinstance(owner, Subsystem):
        pages = [f"`{N.page(j, owner.name, b.name, verb, k, sup='^B')}`"
                 for b in owner.behaviours]
        sym = "rho" if output else "kappa"
        out.append(f"{'send' if output else 'receive'} pages ({sym} = {k}): "
                   + ", ".join(pages))
    else:
        out.append(f"{'send' if output else 'receive'} page "
                   f"`{N.page(j, owner.name, verb, k, sup='^' + owner.letter)}` of the device net")
    ch = m.system.channel_of(buf)
    out.append(_channel_text(m, ch) if ch is not None else "not connected to a channel")
    return out


def _behaviour(m: _Model, s: Subsystem, name: str) -> list[str]:
    b = next((x for x in s.behaviours if x.name == name), None)
    if b is None:
        return []
    j, v = m.j[s.id], s.name
    out = [f"page `{N.page(j, v, name, sup='^B')}` (behaviour layer sH^B_{{{j},{v},{name}}}) "
           f"in `{N.page(j, v)}`"]
    parts = ", ".join(f"`{N.page(j, v, name, f.index, sup='^f')}` ({f.target})"
                      for f in b.functions)
    out.append(f"transition function `{N.page(j, v, name, sup='^f')}`: mu + 1 = "
               f"{len(b.functions)} partial functions {parts}")
    switches = [sw for sw in s.switches if sw.source == name]
    if switches:
        out.append("switches: " + ", ".join(
            f"`{N.transition(j, v, sw.index)}` -> {sw.target or 'end'}" for sw in switches))
    if any(sw.source is None and sw.target == name for sw in s.switches):
        out.append(f"initial: entered by `{N.transition(j, v, 'in')}`")
    return out


def _condition(m: _Model, s: Subsystem, behaviour: str, name: str) -> list[str]:
    b = next((x for x in s.behaviours if x.name == behaviour), None)
    if b is None:
        return []
    c = next((x for x in b.conditions if x.name == name), None)
    if c is None:
        return []
    j, v = m.j[s.id], s.name
    sym = "f^tau" if c.kind == "terminal" else "f^epsilon"
    return [f"{sym} of behaviour {behaviour}: ends it through "
            f"`{N.transition(j, v, behaviour, 'out')}` (and blocks "
            f"`{N.transition(j, v, behaviour, 4)}`)"]


def _update(m: _Model, s: Subsystem, behaviour: str, target: str) -> list[str]:
    b = next((x for x in s.behaviours if x.name == behaviour), None)
    if b is None:
        return []
    f = next((x for x in b.functions if x.target == target), None)
    if f is None:
        return []
    j, v = m.j[s.id], s.name
    inputs = tuple(x.name for x in s.inputs)
    lines = [f"partial function f_{{{j},{v},{behaviour},{f.index}}} (psi = {f.index}) "
             f"for `{target}`: page `{N.page(j, v, behaviour, f.index, sup='^f')}`, "
             f"{len(f.cases)} data-availability cases"]
    for case in f.cases:
        place = N.place(j, v, behaviour, f.index, case.index)
        what = "void" if case.void else "operation"
        lines.append(f"- varpi = {case.index}: {combination_text(inputs, case.new)} -> "
                     f"`{place}` ({what})")
    return [lines[0], "\n".join(lines[1:])]


def hover_text(d: Definition, system: System | None,
               update: tuple[str, str] | None = None, env: Env | None = None,
               local: Type | None = None) -> str:
    """Markdown for a definition; `update` = (behaviour, target) when the cursor is on the
    target of an `update`. The program-wide declarations (types, constants, external
    operations, fields) get their types from `env` (the declaration pass of the program the
    cursor is in: a library module has no system), or from the system; `local` is the type
    of a `let` value."""
    head = f"**{d.kind}** `{d.name}`"
    body = [head, _code(d.detail)]
    prefix, _, rest = d.key.partition(":")
    if prefix in _GLOBAL:
        return "\n\n".join(body + _GLOBAL[prefix](d, system, env or Env()))
    if prefix == "local" and local is not None:
        return "\n\n".join([*body, f"type {_type(local)}"])
    if system is None:
        return "\n\n".join(body)
    _file, _, scoped = rest.partition("|")
    sysname, _, base = scoped.partition("/")
    if prefix not in _IN_SYSTEM or sysname != system.name:
        return "\n\n".join(body)
    return "\n\n".join(body + _IN_SYSTEM[prefix](_Model(system), prefix, base, update))


def _named_type(name: str, system: System | None, env: Env) -> Type | None:
    t = env.types.get(name)
    if t is None and system is not None:
        t = dict(system.types).get(name)
    return t


def _type_lines(d: Definition, system: System | None, env: Env) -> list[str]:
    t = _named_type(d.name, system, env)
    return [f"type {_type(t)}"] if t is not None else []


def _const_lines(d: Definition, system: System | None, env: Env) -> list[str]:
    t = env.const_type(d.name)
    if t is None and system is not None:
        t = next((c.type for c in system.consts if c.name == d.name), None)
    return [f"type {_type(t)}"] if t is not None else []


def _extern_lines(d: Definition, system: System | None, env: Env) -> list[str]:
    ext = env.externs.get(d.name)
    if ext is None and system is not None:
        ext = next((e for e in system.externs if e.name == d.name), None)
    if ext is None:
        return []
    params = ", ".join(f"{n}: {t}" for n, t in ext.params)
    return [f"({params}) -> {_type(ext.result)}", f"bound to `{ext.binding}`"]


def _field_lines(d: Definition, system: System | None, env: Env) -> list[str]:
    record, _, name = d.key.partition(":")[2].partition(".")
    t = _named_type(record, system, env)
    ft = t.field(name) if isinstance(t, RecordT) else None
    return [f"field of record `{record}`"] + ([f"type {_type(ft)}"] if ft is not None else [])


# the program-wide definitions (key prefix -> the lines about them)
_GLOBAL: dict[str, Callable[[Definition, System | None, Env], list[str]]] = {
    "type": _type_lines, "const": _const_lines, "extern": _extern_lines,
    "field": _field_lines,
}


def field_hover(d: Definition | None, record: RecordT, name: str) -> str:
    """Hover on the field name of `x.field`, x a record (as on the field's declaration)."""
    ft = record.field(name)
    lines = [f"**field** `{name}`"]
    if d is not None:
        lines.append(_code(d.detail))
    lines.append(f"field of record `{record.name}`")
    if ft is not None:
        lines.append(f"type {_type(ft)}")
    return "\n\n".join(lines)


_Update = tuple[str, str] | None


def _agent_lines(m: _Model, prefix: str, base: str, update: _Update) -> list[str]:
    a = m.agents.get(base)
    if a is None:
        return []
    return [f"agent a_{a.designator}: page `{N.page(a.designator)}` in H "
            f"(agent layer H_{a.designator}); subsystems "
            + ", ".join(f"`{s.id}`" for s in a.subsystems)]


def _subsystem_lines(m: _Model, prefix: str, base: str, update: _Update) -> list[str]:
    s = m.subs.get(base)
    if s is None:
        return []
    j = m.j[s.id]
    freq = f" @ {s.frequency:g} Hz" if s.frequency else ""
    return [f"{_LETTER_TEXT[s.letter]} {_subsystem_symbol(s, j)} (`{s.id}`){freq}: "
            f"page `{N.page(j, s.name)}` in `{N.page(j)}` (subsystem layer "
            f"sH_{{{j},{s.name}}})",
            f"inputs nu = {len(s.inputs)}, outputs mu = {len(s.outputs)}; "
            "behaviours " + ", ".join(b.name for b in s.behaviours)]


def _device_lines(m: _Model, prefix: str, base: str, update: _Update) -> list[str]:
    dev = m.devices.get(base)
    if dev is None:
        return []
    j = m.j[dev.id]
    return [f"{_LETTER_TEXT[dev.letter]} {dev.letter}_{{{j},{dev.name}}} "
            f"(`{dev.id}`, {dev.device_type}): device net "
            f"`{N.page(j, dev.name, sup='^' + dev.letter)}`"]


def _buffer_lines(m: _Model, prefix: str, base: str, update: _Update) -> list[str]:
    sid, tail = _split(base)
    owner = m.owner(sid)
    return _buffer(m, owner, tail[0]) if owner is not None and tail else []


def _variable_lines(m: _Model, prefix: str, base: str, update: _Update) -> list[str]:
    """A memory variable or a parameter."""
    sid, tail = _split(base)
    s = m.subs.get(sid)
    if s is None or not tail:
        return []
    var = next((x for x in (s.memory if prefix == "mem" else s.params) if x.name == tail[0]),
               None)
    if var is None:
        return []
    lines = [f"type {_type(var.type)}"]
    if prefix == "mem":
        mu1 = len(s.outputs) + 1
        j = m.j[s.id]
        lines.append(f"written by the memory partial function (psi = mu + 1 = "
                     f"{mu1}): pages " + ", ".join(
                         f"`{N.page(j, s.name, b.name, mu1, sup='^f')}`"
                         for b in s.behaviours))
    return lines


def _behaviour_lines(m: _Model, prefix: str, base: str, update: _Update) -> list[str]:
    sid, tail = _split(base)
    s = m.subs.get(sid)
    if s is None or not tail:
        return []
    return _update(m, s, tail[0], update[1]) if update is not None else _behaviour(m, s, tail[0])


def _condition_lines(m: _Model, prefix: str, base: str, update: _Update) -> list[str]:
    sid, tail = _split(base)
    s = m.subs.get(sid)
    return _condition(m, s, tail[0], tail[1]) if s is not None and len(tail) == 2 else []


def _property_lines(m: _Model, prefix: str, base: str, update: _Update) -> list[str]:
    from rssm_dsl.semantics.properties import InBehaviour, PropertyError, atoms, written
    from rssm_dsl.semantics.types import finite_domain

    p = next((x for x in m.system.properties if x.name == base), None)
    if p is None:
        return []
    if p.kind == "always":
        out = ["**always**: a state invariant; the verifier checks that the condition holds "
               "in every reachable state"]
    else:
        out = ["**whenever ... eventually ...**: a response property; every reachable state "
               "where the trigger holds is followed, now or later, by one where the goal holds"]
    items: list[str] = []
    abstracted: list[str] = []
    try:
        found = [a for e in p.expressions for a in atoms(m.system, e)]
    except PropertyError:
        found = []
    for a in found:
        sub = m.subs.get(a.subsystem_id)
        if sub is None:
            continue
        if isinstance(a, InBehaviour):
            page = N.page(m.j[sub.id], sub.name, a.behaviour, sup="^B")
            text = f"`{written(m.system, sub.id)} in {a.behaviour}` (page `{page}`)"
        else:
            text = f"`{written(m.system, sub.id)}.{a.variable_name}` ({a.kind}, {a.type})"
            if finite_domain(a.type) is None:
                abstracted.append(f"`{written(m.system, sub.id)}.{a.variable_name}`")
        if text not in items:
            items.append(text)
    if items:
        out.append("atoms: " + ", ".join(items))
    if abstracted:
        out.append("abstracted by the verifier (no finite domain): "
                   + ", ".join(dict.fromkeys(abstracted)))
    return out


# the definitions inside a system (key prefix -> the lines about them in the HPN)
_IN_SYSTEM: dict[str, Callable[[_Model, str, str, _Update], list[str]]] = {
    "agent": _agent_lines, "sub": _subsystem_lines, "inst": _device_lines,
    "buf": _buffer_lines, "mem": _variable_lines, "param": _variable_lines,
    "beh": _behaviour_lines, "cond": _condition_lines, "prop": _property_lines,
}


def update_hover(d: Definition, behaviour: str, target: str, system: System | None) -> str:
    """Hover on the target of `update`: the partial function and its cases."""
    text = hover_text(d, system, (behaviour, target))
    model = text.split("\n\n", 2)[2] if text.count("\n\n") >= 2 else ""
    new_head = f"**partial function** for `{target}` in behaviour `{behaviour}`"
    return "\n\n".join(x for x in (new_head, _code(f"update {target}"), model) if x)
