"""The questions `rssmc verify` answers, as input for the Model Checking Contest's tools
(`rssmc compile --emit mcc`): a folder laid out as the contest lays out a model instance
(`mcc/model.pnml` beside one XML file per examination), for nets beyond one machine's reach
with our own verifier.

The property files follow the contest's property language (XML, namespace
``http://mcc.lip6.fr/``): a ``property-set`` of ``property`` elements, each with an ``id``
(the model's name, the examination, a number: ``handshake-ReachabilityDeadlock-00``), a
``description`` and one ``formula``.

- ``model.pnml`` is the flat PNML (:func:`rssm_dsl.emit.pnml.flat_pnml`, the same place and
  transition ids) with one transition added, ``t_final`` (id ``t<number of transitions>``),
  which takes and puts back the tokens of the final places (the root page's output place: the
  system finished). It is enabled exactly in the final marking, so the final marking is not
  dead in ``model.pnml``, and a dead marking of ``model.pnml`` is exactly what `rssmc verify`
  calls a deadlock (a dead marking that is not final). No other marking changes: ``t_final``
  changes no marking when it fires.
- ``ReachabilityDeadlock.xml``: the contest's ReachabilityDeadlock examination, ``EF
  deadlock``. TRUE: a deadlock is reachable; FALSE: the system is deadlock-free.
- ``ReachabilityCardinality.xml``: each `property NAME: always P` whose atoms are all
  ``SUB in BEH``, as ``AG P'``, P' a Boolean combination of ``integer-le`` over
  ``tokens-count`` of places: ``SUB in BEH`` is ``1 <= tokens-count(the places of BEH's page
  of SUB)``, as the verifier reads it (rssm_dsl/verify/userprops.py). P' is computed from P's
  truth table, evaluated by the code the verifier and the interpreter run
  (:class:`rssm_dsl.semantics.properties.Formula`), so it means what P means.
- ``CTLCardinality.xml``: each `whenever P eventually Q` over behaviours, as ``AG (not P' or
  not E (not Q' U not EF Q'))``: the verifier's reading (a reachable state where P holds,
  from which a path that never meets Q leads to a state that can never reach Q again, is a
  violation).
- ``README.txt``: what each file holds, and the properties not written, with the reason. A
  property that reads a value (``SUB.NAME``) is not expressible: the values the verifier
  tracks beside the net (new(x), finite values) are not places of the PNML, where every
  condition on data is a free choice.

What the answers mean for the system: the PNML is the net with every condition on data a free
choice (the verifier's first pass, docs/verify.md, "Conditions on data"): it can do all the
system can do. A deadlock-freedom or an invariant proved on it holds for the system; a
deadlock or a violation found on it may be one the data rules out (`rssmc verify` tells).
"""

from __future__ import annotations

import copy
import itertools
import xml.etree.ElementTree as ET
from collections.abc import Sequence
from dataclasses import replace
from functools import partial

from rssm_dsl.emit.pnml import flat_pnml
from rssm_dsl.hpn.flat import FlatNet, FlatTransition, Role
from rssm_dsl.hpn.flatten import flatten
from rssm_dsl.hpn.ir import HPN
from rssm_dsl.semantics.model import Property, System

MCC_NS = "http://mcc.lip6.fr/"
HEADER = '<?xml version="1.0" encoding="UTF-8"?>'
FOLDER = "mcc"
FINAL_LOOP = "t_final"
MAX_ATOMS = 8          # a truth table of 2^8 rows at most per expression

# A cube: a conjunction of literals, one per atom: True (in), False (not in), None (either).
Cube = tuple[bool | None, ...]


def emit_mcc(hpn: HPN, system: System | None = None) -> dict[str, str]:
    """The files of `--emit mcc` (the module docstring), by path relative to the output
    folder."""
    net = flatten(hpn)
    model = hpn.system
    files = {f"{FOLDER}/model.pnml": flat_pnml(closed_net(net)),
             f"{FOLDER}/ReachabilityDeadlock.xml": deadlock_xml(model)}
    always: list[tuple[Property, ET.Element]] = []
    response: list[tuple[Property, ET.Element]] = []
    skipped: list[tuple[Property, str]] = []
    for prop in (system.properties if system is not None else ()):
        assert system is not None
        formula = property_formula(net, system, prop)
        if isinstance(formula, Skip):
            skipped.append((prop, formula.why))
        elif prop.kind == "always":
            always.append((prop, formula))
        else:
            response.append((prop, formula))
    if always:
        files[f"{FOLDER}/ReachabilityCardinality.xml"] = property_set(
            model, "ReachabilityCardinality", always)
    if response:
        files[f"{FOLDER}/CTLCardinality.xml"] = property_set(model, "CTLCardinality", response)
    files[f"{FOLDER}/README.txt"] = _readme(model, net, always, response, skipped)
    return files


def closed_net(net: FlatNet) -> FlatNet:
    """The flat net with ``t_final``, a loop on the final places (the module docstring)."""
    if not net.final:
        return net
    final = tuple(sorted(net.final))
    loop = FlatTransition(
        len(net.transitions), FINAL_LOOP,
        "the system finished (a loop, so the final marking is not a deadlock)",
        net.places[final[0]].span, final, final, Role.STRUCTURE)
    return replace(net, transitions=(*net.transitions, loop))


def deadlock_xml(model: str) -> str:
    body = _quantified("exists-path", "finally", ET.Element("deadlock"))
    description = (f"rssmc: a deadlock of system {model} is reachable (a dead marking of "
                   f"model.pnml; the final marking is not one: {FINAL_LOOP} loops on it)")
    return _document([_property(f"{model}-ReachabilityDeadlock-00", description, body)])


class Skip:
    """A property not expressible over the places of the PNML, and why."""

    def __init__(self, why: str) -> None:
        self.why = why


def property_formula(net: FlatNet, system: System, prop: Property) -> ET.Element | Skip:
    """The formula element of one user property, or why there is none."""
    from rssm_dsl.semantics.properties import Formula, InBehaviour

    try:
        formulas = [Formula(system, e) for e in prop.expressions]
    except Exception as e:  # a property the verifier could not run either
        return Skip(f"it cannot be evaluated ({e})")
    atoms: list[tuple[str, str]] = []
    for f in formulas:
        for a in f.atoms:
            if not isinstance(a, InBehaviour):
                return Skip(f"it reads the value {a.subsystem_id}.{a.variable_name}, which "
                            "is not a place of the PNML (the verifier tracks values beside "
                            "the net; in the PNML every condition on data is a free choice)")
            if (a.subsystem_id, a.behaviour) not in atoms:
                atoms.append((a.subsystem_id, a.behaviour))
    if len(atoms) > MAX_ATOMS:
        return Skip(f"it has {len(atoms)} atoms (at most {MAX_ATOMS} are written, from a "
                    "truth table)")
    places = [tuple(p.index for p in net.places if p.subsystem == s and p.behaviour == b)
              for s, b in atoms]
    exprs: list[ET.Element] = []
    for f in formulas:
        rows: list[tuple[bool, ...]] = []
        for row in itertools.product((False, True), repeat=len(atoms)):
            if any(v and not ps for v, ps in zip(row, places, strict=True)):
                continue      # a behaviour without places is never active (never happens)
            active = {a for a, v in zip(atoms, row, strict=True) if v}
            try:
                holds = f(partial(_in, frozenset(active)), _no_value)
            except Exception as e:  # e.g. a division by zero in P
                return Skip(f"it cannot be evaluated on the behaviours alone ({e})")
            if holds:
                rows.append(row)
        exprs.append(_dnf(prime_cubes(rows, len(atoms)), places))
    if prop.kind == "always":
        return _quantified("all-paths", "globally", exprs[0])
    # whenever P eventually Q: AG (not P or not E (not Q U not EF Q)), the verifier's
    # reading: no P-state from which a path that never meets Q leads to a state that can
    # never reach Q again
    p_expr, q_expr = exprs
    lost = _node("negation", _quantified("exists-path", "finally", q_expr))
    until = _node("until", _node("before", _node("negation", copy.deepcopy(q_expr))),
                  _node("reach", lost))
    return _quantified("all-paths", "globally", _node(
        "disjunction", _node("negation", p_expr),
        _node("negation", _node("exists-path", until))))


def _in(active: frozenset[tuple[str, str]], subsystem: str, behaviour: str) -> bool:
    return (subsystem, behaviour) in active


def _no_value(subsystem: str, name: str) -> object:
    raise LookupError(f"{subsystem}.{name} is not a place")


def prime_cubes(rows: Sequence[tuple[bool, ...]], n: int) -> list[Cube]:
    """The prime implicants of the Boolean function true exactly on ``rows`` (Quine and
    McCluskey's merging, without choosing a cover: their disjunction is the function)."""
    current: set[Cube] = {tuple(r) for r in rows}
    primes: set[Cube] = set()
    while current:
        merged: set[Cube] = set()
        used: set[Cube] = set()
        for c in current:
            for i in range(n):
                if c[i] is None:
                    continue
                other = (*c[:i], not c[i], *c[i + 1:])
                if other in current:
                    merged.add((*c[:i], None, *c[i + 1:]))
                    used.add(c)
                    used.add(other)
        primes |= current - used
        current = merged
    return sorted(primes, key=lambda c: tuple(2 if v is None else int(v) for v in c))


def _node(tag: str, *children: ET.Element, text: str | None = None) -> ET.Element:
    e = ET.Element(tag)
    e.extend(children)
    e.text = text
    return e


def _dnf(cubes: list[Cube], places: Sequence[tuple[int, ...]]) -> ET.Element:
    """The disjunction of the cubes (a conjunction of literals each)."""
    if not cubes:
        return _node("false")
    terms = []
    for cube in cubes:
        lits = [_literal(places[i], v) for i, v in enumerate(cube) if v is not None]
        if not lits:
            return _node("true")
        terms.append(lits[0] if len(lits) == 1 else _node("conjunction", *lits))
    return terms[0] if len(terms) == 1 else _node("disjunction", *terms)


def _literal(places: tuple[int, ...], active: bool) -> ET.Element:
    """``1 <= tokens-count(places)`` (the behaviour is active), or ``tokens-count(places)
    <= 0``."""
    count = _node("tokens-count", *(_node("place", text=f"p{p}") for p in places))
    if active:
        return _node("integer-le", _node("integer-constant", text="1"), count)
    return _node("integer-le", count, _node("integer-constant", text="0"))


def _quantified(path: str, temporal: str, inner: ET.Element) -> ET.Element:
    return _node(path, _node(temporal, inner))


def property_set(model: str, examination: str,
                 props: list[tuple[Property, ET.Element]]) -> str:
    out = []
    for i, (prop, formula) in enumerate(props):
        description = f"rssmc property {prop.name} ({_where(prop)}): {_text(prop)}"
        out.append(_property(f"{model}-{examination}-{i:02d}", description, formula))
    return _document(out)


def _property(pid: str, description: str, formula: ET.Element) -> ET.Element:
    return _node("property", _node("id", text=pid), _node("description", text=description),
                 _node("formula", formula))


def _document(props: list[ET.Element]) -> str:
    """The property set, indented, every text escaped by ElementTree."""
    root = _node("property-set", *props)
    root.set("xmlns", MCC_NS)
    ET.indent(root)
    return f"{HEADER}\n{ET.tostring(root, encoding='unicode')}\n"


def _where(prop: Property) -> str:
    return f"{prop.span.file}:{prop.span.line}"


def _text(prop: Property) -> str:
    from rssm_dsl.syntax.printer import expr_text

    if prop.kind == "always" and prop.condition is not None:
        return f"always {expr_text(prop.condition)}"
    if prop.trigger is not None and prop.goal is not None:
        return f"whenever {expr_text(prop.trigger)} eventually {expr_text(prop.goal)}"
    return prop.kind


def _readme(model: str, net: FlatNet, always: list[tuple[Property, ET.Element]],
            response: list[tuple[Property, ET.Element]],
            skipped: list[tuple[Property, str]]) -> str:
    final = ", ".join(f"p{p} ({net.places[p].label})" for p in sorted(net.final))
    lines = [
        f"Model Checking Contest input for system {model}, written by `rssmc compile "
        "--emit mcc` (docs/verify.md, \"Model Checking Contest files\").",
        "",
        f"model.pnml: the flat PNML with one transition more, {FINAL_LOOP} "
        f"(t{len(net.transitions)}), a loop on the final place(s) {final or '(none)'}: the",
        "final marking (the system finished) is not dead, so a dead marking of model.pnml is",
        "what `rssmc verify` calls a deadlock. Place and transition ids are those of the flat",
        "PNML (--emit pnml).",
        f"ReachabilityDeadlock.xml: {model}-ReachabilityDeadlock-00, EF deadlock. TRUE: a",
        "deadlock is reachable; FALSE: the system is deadlock-free.",
    ]
    if always:
        lines.append("ReachabilityCardinality.xml: the `always` properties, as AG P:")
        lines += [f"  {model}-ReachabilityCardinality-{i:02d}: {p.name}"
                  for i, (p, _) in enumerate(always)]
    if response:
        lines.append("CTLCardinality.xml: the `whenever P eventually Q` properties, as "
                     "AG (not P or not E (not Q U not EF Q)):")
        lines += [f"  {model}-CTLCardinality-{i:02d}: {p.name}"
                  for i, (p, _) in enumerate(response)]
    if skipped:
        lines.append("Not written:")
        lines += [f"  {p.name} ({_where(p)}): {why}" for p, why in skipped]
    lines += [
        "",
        "The net has every condition on data as a free choice: it can do all the system can",
        "do. A deadlock-freedom or an invariant proved on it holds for the system; a deadlock",
        "or a violation found on it may be one the data rules out (`rssmc verify` tells).",
        "",
    ]
    return "\n".join(lines)
