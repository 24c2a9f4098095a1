"""Random valid multi-agent RSSM specs for the soundness harness (tests/soundness/,
bench/soundness.py).

``generate(seed)`` returns a :class:`GeneratedSpec`: the spec's text and the set of features
it exercises (``FEATURES`` lists them all). The same seed gives the same text. Every spec is
meant to pass ``rssmc check`` without errors (warnings are fine); the checker treats an error
as a bug of this generator.

What a spec holds:

* 2-6 agents; each has a control subsystem ``c`` with 1-3 behaviours over small finite
  memories (a range counter ``k``, sometimes a ``bool`` flag and an enum ``ph``);
* c–c channels between agents (a ring, sometimes with a chord), each with a producer and a
  consumer mode drawn from the four pairings, carrying a ``bool``, an enum or a range;
* some agents get a virtual effector (c–e, e–E to an echo device) or a virtual receptor
  (c–r, r–R from a constant device);
* behaviours write their outputs from memory and inputs, update memory with data cases
  (``case new(x)``) over inputs of each finite type, end on terminal and error conditions,
  and send and receive in sequential, parallel or mixed arrangements;
* switches read the ending behaviour's terminal and error condition names, some go to
  ``end`` (a subsystem that ends);
* ``property`` declarations: ``always`` over behaviours and values, ``whenever ...
  eventually``.

The sizes are kept small (counters up to 2, few behaviours, few devices, fewer features as
agents are added) so that the full exploration decides a spec in about a second.
"""

from __future__ import annotations

import random
from dataclasses import dataclass, field

MODES = ("bb", "bn", "nb", "nn")            # producer mode, consumer mode: b(locking)/n(on-)
TYPES = ("bool", "enum", "range")
ENUM = "Tok"
ENUM_MEMBERS = ("lo", "mid", "hi")
RANGE = "0..2"

FEATURES: frozenset[str] = frozenset({
    *(f"mode:{m}" for m in MODES),
    *(f"agents:{n}" for n in range(2, 7)),
    "arrangement:sequential", "arrangement:parallel", "arrangement:mixed",
    *(f"case:{t}" for t in TYPES),
    *(f"memory:{t}" for t in TYPES),
    *(f"channel:{t}" for t in TYPES),
    "property:always", "property:response",
    "switch:terminal", "switch:error", "switch:otherwise", "ends", "behaviours:several",
    "effector", "receptor", "device:effector", "device:receptor", "switch:param",
})


@dataclass(frozen=True)
class GeneratedSpec:
    seed: int
    text: str
    features: frozenset[str]


@dataclass(frozen=True)
class Channel:
    name: str
    producer: str          # agent
    consumer: str          # agent
    type: str              # one of TYPES
    producer_blocking: bool
    consumer_blocking: bool

    @property
    def mode(self) -> str:
        return ("b" if self.producer_blocking else "n") + ("b" if self.consumer_blocking else "n")


@dataclass(frozen=True)
class Port:
    """A buffer of a control subsystem, with the text of its declaration."""

    name: str
    type: str
    decl: str


@dataclass
class Control:
    agent: str
    outputs: list[Port] = field(default_factory=list)
    inputs: list[Port] = field(default_factory=list)
    has_flag: bool = False
    has_phase: bool = False
    behaviours: list[str] = field(default_factory=list)
    quick: bool | None = None       # a bool parameter some switches read (None: none)


def type_name(t: str) -> str:
    return {"bool": "bool", "enum": ENUM, "range": RANGE}[t]


class _Gen:
    """One spec being generated: the random source and the features used so far."""

    def __init__(self, seed: int) -> None:
        self.seed = seed
        self.rng = random.Random(seed)
        # the parameters' own stream: a spec without them is the one generated before
        # they were added (the same seed, the same text)
        self.params = random.Random(seed * 7919 + 17)
        self.features: set[str] = set()

    def chance(self, p: float) -> bool:
        return self.rng.random() < p

    # ---------------------------------------------------------------- values of each type

    def literal(self, t: str) -> str:
        if t == "bool":
            return self.rng.choice(("true", "false"))
        if t == "enum":
            return f"{ENUM}.{self.rng.choice(ENUM_MEMBERS)}"
        return str(self.rng.randint(0, 2))

    def value(self, t: str, c: Control) -> str:
        """An expression of type ``t`` over c's memory and same-typed inputs."""
        inputs = [p.name for p in c.inputs if p.type == t]
        r = self.rng.random()
        if inputs and r < 0.35:
            return self.rng.choice(inputs)
        if t == "bool":
            opts = [f"k >= {self.rng.randint(1, 2)}", f"k == {self.rng.randint(0, 2)}"]
            if c.has_flag:
                opts += ["not flag", "flag"]
            if c.has_phase:
                opts.append(f"ph == {ENUM}.{self.rng.choice(ENUM_MEMBERS)}")
            return self.rng.choice(opts)
        if t == "enum":
            if c.has_phase and r < 0.6:
                return "ph"
            a, b = self.rng.sample(ENUM_MEMBERS, 2)
            return f"if k >= 1 then {ENUM}.{a} else {ENUM}.{b}"
        return self.rng.choice(("k", "if k >= 2 then 0 else k + 1", "2 - k"))

    def condition(self, c: Control) -> str:
        """A bool condition over c's memory (and, sometimes, its bool inputs)."""
        return self.value("bool", c)

    # --------------------------------------------------------------------- structure

    def channels(self, agents: list[str]) -> list[Channel]:
        n = len(agents)
        pairs = [(i, (i + 1) % n) for i in range(n)] if n > 2 or self.chance(0.5) else [(0, 1)]
        if n == 2 and len(pairs) == 2 and self.chance(0.3):
            pairs = [(0, 1), (1, 0)]
        if n == 2 and self.chance(0.35):
            pairs.append((0, 1))        # a second channel the same way
        if 3 <= n <= 4 and self.chance(0.3):
            i, j = self.rng.sample(range(n), 2)
            if (i, j) not in pairs:
                pairs.append((i, j))
        out = []
        for k, (i, j) in enumerate(pairs):
            t = self.rng.choice(TYPES)
            mode = self.rng.choice(MODES)
            self.features.add(f"mode:{mode}")
            self.features.add(f"channel:{t}")
            out.append(Channel(f"m{k}", agents[i], agents[j], t, mode[0] == "b", mode[1] == "b"))
        return out

    def arrangement(self, names: list[str]) -> str:
        """A send or receive arrangement of ``names``: sequential, parallel or mixed."""
        names = names[:]
        self.rng.shuffle(names)
        if len(names) == 1:
            return names[0]
        kind = self.rng.choice(("sequential", "parallel", "mixed") if len(names) >= 3
                               else ("sequential", "parallel"))
        self.features.add(f"arrangement:{kind}")
        if kind == "sequential":
            return "; ".join(names)
        if kind == "parallel":
            return " | ".join(names)
        cut = self.rng.randint(1, len(names) - 1)
        head, tail = names[:cut], names[cut:]
        left = head[0] if len(head) == 1 else "(" + " | ".join(head) + ")"
        right = tail[0] if len(tail) == 1 else " | ".join(tail)
        return f"{left}; {right}" if self.chance(0.5) else f"{right}; {left}"

    def memory_update(self, c: Control) -> list[str]:
        """The lines of an ``update memory`` block: the counter's step, the flag and the
        phase, sometimes split by a data case over one input."""
        step = self.rng.choice(("if k >= 2 then 0 else k + 1", "if k >= 2 then 2 else k + 1"))
        body = [f"k := {step}"]
        if c.has_flag and self.chance(0.6):
            body.append(f"flag := {self.value('bool', c)}")
        if c.has_phase and self.chance(0.6):
            body.append(f"ph := {self.value('enum', c)}")
        if c.inputs and self.chance(0.6):
            x = self.rng.choice(c.inputs)
            self.features.add(f"case:{x.type}")
            fresh = [f"k := {step}"]
            if x.type == "bool" and c.has_flag:
                fresh.append(f"flag := {x.name}")
            elif x.type == "enum" and c.has_phase:
                fresh.append(f"ph := {x.name}")
            elif x.type == "range":
                fresh = [f"k := {x.name}"]
            stale = self.rng.choice((["skip"], body))
            lines = [f"case new({x.name}):", *(f"  {s}" for s in fresh),
                     "otherwise:", *(f"  {s}" for s in stale)]
            return lines
        return body

    def behaviour(self, c: Control, name: str) -> tuple[list[str], list[str], list[str]]:
        """The lines of behaviour ``name``, its terminal and its error condition names."""
        lines = [f"behaviour {name} {{"]
        for p in c.outputs:
            if self.chance(0.85):
                lines.append(f"  update {p.name} {{ {p.name} := {self.value(p.type, c)} }}")
        mem = self.memory_update(c)
        lines.append("  update memory {")
        lines += [f"    {s}" for s in mem]
        lines.append("  }")
        terminals: list[str] = []
        errors: list[str] = []
        if len(c.behaviours) > 1 or self.chance(0.7):
            terminals.append(f"t_{name}")
            lines.append(f"  terminal t_{name} when {self.condition(c)}")
        else:
            lines.append("  terminal never when false")
        if terminals and self.chance(0.35):
            errors.append(f"x_{name}")
            lines.append(f"  error x_{name} when {self.condition(c)}")
        if len(c.outputs) > 1 or (c.outputs and self.chance(0.3)):
            lines.append(f"  send {self.arrangement([p.name for p in c.outputs])}")
        if len(c.inputs) > 1 or (c.inputs and self.chance(0.3)):
            lines.append(f"  receive {self.arrangement([p.name for p in c.inputs])}")
        lines.append("}")
        return lines, terminals, errors

    def switches(self, c: Control, name: str, terminals: list[str],
                 errors: list[str]) -> list[str]:
        if not terminals:
            return []
        targets = [*c.behaviours, "end"]
        weights = [*([1.0] * len(c.behaviours)), 0.5]

        def target() -> str:
            return self.rng.choices(targets, weights)[0]
        out = []
        if errors:
            self.features.add("switch:error")
            out.append(f"switch {name} -> {target()} when {errors[0]}")
        self.features.add("switch:terminal")
        first = target()
        if self.chance(0.5):
            cond = terminals[0] if not c.has_flag or self.chance(0.5) \
                else f"{terminals[0]} and flag"
            if c.quick is not None and self.params.random() < 0.7:
                # a guard a parameter decides: never a free choice in any pass
                self.features.add("switch:param")
                cond += " and quick" if self.params.random() < 0.5 else " and not quick"
            out.append(f"switch {name} -> {first} when {cond}")
            self.features.add("switch:otherwise")
            out.append(f"switch {name} -> {target()} otherwise")
        else:
            self.features.add("switch:otherwise")
            out.append(f"switch {name} -> {first} otherwise")
        if any(s.endswith(("-> end otherwise",)) or " -> end when " in s for s in out):
            self.features.add("ends")
        return out

    def control(self, c: Control, size: int) -> list[str]:
        lines = ["control {", "  memory k: 0..2 = 0"]
        self.features.add("memory:range")
        if c.has_flag:
            self.features.add("memory:bool")
            lines.append(f"  memory flag: bool = {self.literal('bool')}")
        if c.has_phase:
            self.features.add("memory:enum")
            lines.append(f"  memory ph: {ENUM} = {self.literal('enum')}")
        if self.params.random() < 0.3:
            c.quick = self.params.random() < 0.5
            lines.append(f"  param quick: bool = {'true' if c.quick else 'false'}")
        lines += [f"  {p.decl}" for p in (*c.outputs, *c.inputs)]
        nb = self.rng.choice((1, 1, 2, 2, 3) if size <= 2 else (1, 1, 2))
        c.behaviours = [f"b{i}" for i in range(nb)]
        if nb > 1:
            self.features.add("behaviours:several")
        switch_lines: list[str] = []
        for b in c.behaviours:
            body, terminals, errors = self.behaviour(c, b)
            lines += [f"  {s}" for s in body]
            switch_lines += self.switches(c, b, terminals, errors)
        lines.append("  initial b0")
        lines += [f"  {s}" for s in switch_lines]
        lines.append("}")
        return lines

    def effector(self, t: str, device_blocking: bool) -> list[str]:
        """A virtual effector between c and an echo device; mostly in lock step with both
        (blocking), which keeps the state space small."""
        self.features.update(("effector", "device:effector"))
        tn = type_name(t)
        case = self.chance(0.5)
        if case:
            self.features.add(f"case:{t}")
        status = (["    update st {", "      case new(meas):", "        st := meas",
                   "      otherwise:", "        skip", "    }"] if case
                  else ["    update st { st := meas }"])
        recv = self.rng.choice(("", "    receive cmd; meas", "    receive cmd | meas",
                                "    receive meas; cmd"))
        cmd_mode = " blocking" if self.chance(0.7) else ""
        meas_mode = " blocking" if self.chance(0.5) else ""
        return ["effector eff {",
                f"  input cmd: {tn} from c{cmd_mode}",
                f"  input meas: {tn} from E.act{meas_mode}",
                f"  output drive: {tn} to E.act",
                f"  output st: {tn} to c",
                "  behaviour follow {",
                "    update drive { drive := cmd }",
                *status,
                "    terminal never when false",
                *([recv] if recv else []),
                "  }",
                "  initial follow",
                "}",
                f"real effector act: {_act(t, device_blocking)}"]

    def receptor(self, t: str) -> list[str]:
        self.features.update(("receptor", "device:receptor", f"case:{t}"))
        tn = type_name(t)
        return ["receptor sense {",
                f"  input reading: {tn} from R.sen{' blocking' if self.chance(0.6) else ''}",
                f"  output obs: {tn} to c",
                "  behaviour watch {",
                "    update obs {",
                "      case new(reading):",
                "        obs := reading",
                "      otherwise:",
                "        skip",
                "    }",
                "    terminal never when false",
                "  }",
                "  initial watch",
                "}",
                f"real receptor sen: Sen_{t}"]

    def properties(self, controls: list[Control]) -> list[str]:
        out = []
        for i in range(self.rng.choice((0, 1, 1, 2, 2))):
            a, b = self.rng.choice(controls), self.rng.choice(controls)
            ba, bb = self.rng.choice(a.behaviours), self.rng.choice(b.behaviours)
            if self.chance(0.55):
                self.features.add("property:always")
                expr = self.rng.choice((
                    f"not ({a.agent}.c in {ba} and {b.agent}.c in {bb})",
                    f"{a.agent}.c.k <= {self.rng.randint(1, 2)}",
                    f"{a.agent}.c.k != 2 or {b.agent}.c in {bb}",
                    *([f"{a.agent}.c.flag or not {a.agent}.c in {ba}"] if a.has_flag else []),
                    *([f"{a.agent}.c.ph != {ENUM}.hi"] if a.has_phase else []),
                ))
                out.append(f"property p{i}: always {expr}")
            else:
                self.features.add("property:response")
                goal = self.rng.choice((f"{b.agent}.c in {bb}", f"{b.agent}.c.k == 0",
                                        f"{a.agent}.c.k >= 1"))
                out.append(f"property p{i}: whenever {a.agent}.c in {ba} eventually {goal}")
        return out


def _act(t: str, blocking: bool) -> str:
    return f"Act_{t}_{'b' if blocking else 'n'}"


def _device_types(effectors: set[tuple[str, bool]], receptors: set[str]) -> list[str]:
    lines = []
    for t, blocking in sorted(effectors):
        tn = type_name(t)
        lines += [f"device effector {_act(t, blocking)} {{",
                  f"  input drive: {tn} {'blocking' if blocking else 'nonblocking'}",
                  f"  output meas: {tn} nonblocking",
                  '  binding "rssm_stdlib.devices.echo:EchoDevice"',
                  "}", ""]
    for t in sorted(receptors):
        tn = type_name(t)
        lines += [f"device receptor Sen_{t} {{",
                  f"  output reading: {tn} nonblocking",
                  '  binding "rssm_stdlib.devices.constant:ConstantDevice"',
                  "}", ""]
    return lines


def _indent(lines: list[str], by: int) -> list[str]:
    return [(" " * by + s) if s else s for s in lines]


def generate(seed: int) -> GeneratedSpec:
    """The spec of ``seed`` (deterministic)."""
    g = _Gen(seed)
    n = g.rng.choices((2, 3, 4, 5, 6), (10, 4, 2, 1, 1))[0]
    g.features.add(f"agents:{n}")
    agents = [f"a{i}" for i in range(n)]
    rich = 0.3 if n <= 3 else 0.1
    controls = {a: Control(a, has_flag=g.chance(rich), has_phase=g.chance(rich * 0.7))
                for a in agents}
    for ch in g.channels(agents):
        tn = type_name(ch.type)
        pm = "blocking" if ch.producer_blocking else "nonblocking"
        cm = "blocking" if ch.consumer_blocking else "nonblocking"
        controls[ch.producer].outputs.append(
            Port(ch.name, ch.type, f"output {ch.name}: {tn} to {ch.consumer}.c {pm}"))
        controls[ch.consumer].inputs.append(
            Port(ch.name, ch.type, f"input {ch.name}: {tn} from {ch.producer}.c {cm}"))
    # virtual subsystems with devices: few of them, fewer in larger systems
    devices = (1 + g.chance(0.25)) if n == 2 and g.chance(0.45) else 0
    effectors: dict[str, tuple[str, bool]] = {}
    receptors: dict[str, str] = {}
    for _ in range(devices):
        a = g.rng.choice(agents)
        t = g.rng.choice(TYPES)
        if g.chance(0.5) and a not in effectors:
            effectors[a] = (t, g.chance(0.7))
            c = controls[a]
            mode = " blocking" if g.chance(0.7) else ""
            c.outputs.append(Port("cmd", t, f"output cmd: {type_name(t)} to e.eff{mode}"))
            c.inputs.append(Port("st", t, f"input st: {type_name(t)} from e.eff"))
        elif a not in receptors:
            receptors[a] = t
            controls[a].inputs.append(Port("obs", t, f"input obs: {type_name(t)} from r.sense"))
    body: list[str] = []
    for a in agents:
        part = g.control(controls[a], n)
        if a in effectors:
            part += g.effector(*effectors[a])
        if a in receptors:
            part += g.receptor(receptors[a])
        body += [f"agent {a} {{", *_indent(part, 2), "}"]
    body += g.properties(list(controls.values()))
    lines = [f"// generated by tests/soundness/generator.py, seed {seed}",
             f"enum {ENUM} {{ {', '.join(ENUM_MEMBERS)} }}", "",
             *_device_types(set(effectors.values()), set(receptors.values())),
             f"system s{seed} {{", *_indent(body, 2), "}", ""]
    return GeneratedSpec(seed, "\n".join(lines), frozenset(g.features))
