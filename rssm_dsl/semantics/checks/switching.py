"""Subsystem layer (paper IV-C): after a behaviour ends, at least one switch condition must
hold (E603); warn when two can hold at once (W604) and when a behaviour is unreachable (W605).

Switch conditions are abstracted to propositional formulas: the names of the source
behaviour's terminal/error conditions are atoms (at least one is true when it ends), every
other comparison or boolean value is an independent atom (`x > 1` and `x <= 1` are one atom,
negated), except that comparisons of one value with members of its enum (`phase ==
Phase.grasp`, `phase != Phase.idle`) exclude each other, and cover every case when they name
all the members. The check enumerates the assignments, so it is exact for that abstraction.
"""

from __future__ import annotations

import itertools
import re
from collections.abc import Mapping
from dataclasses import dataclass

from rssm_dsl.diagnostics import Related
from rssm_dsl.semantics.checks.context import CheckContext
from rssm_dsl.semantics.model import Behaviour, Subsystem, Switch
from rssm_dsl.semantics.types import EnumT
from rssm_dsl.syntax import ast
from rssm_dsl.syntax.printer import expr_text

MAX_ATOMS = 14
_FLIP = {">": "<=", ">=": "<", "!=": "=="}


@dataclass(frozen=True)
class F:
    """A propositional formula: op in const/atom/not/and/or."""

    op: str
    args: tuple[object, ...]


def _abstract(e: ast.Expr, conds: dict[str, tuple[str, bool]]) -> F:
    """`conds` maps a condition name, or the canonical text of a condition's comparison, to
    (condition name, negated)."""
    match e:
        case ast.Literal(value=bool() as v):
            return F("const", (v,))
        case ast.Name(name=n) if n in conds:
            return F("atom", (f"cond:{conds[n][0]}",))
        case ast.Unary(op="not", operand=x):
            return F("not", (_abstract(x, conds),))
        case ast.Binary(op="and" | "or", left=a, right=b):
            return F(e.op, (_abstract(a, conds), _abstract(b, conds)))
        case ast.Binary(op=op, left=a, right=b) if op in ("==", "!=", "<", "<=", ">", ">="):
            key = _key(op, a, b)
            atom = F("atom", (key,))
            if key in conds:
                name, negated = conds[key]
                atom = F("atom", (f"cond:{name}",))
                atom = F("not", (atom,)) if negated else atom
            return F("not", (atom,)) if op in _FLIP else atom
    return F("atom", (expr_text(e),))


def _key(op: str, a: ast.Expr, b: ast.Expr) -> str:
    return f"{expr_text(a)} {_FLIP.get(op, op)} {expr_text(b)}"


def _atoms(f: F, out: set[str]) -> None:
    if f.op == "atom":
        out.add(str(f.args[0]))
    elif f.op != "const":
        for a in f.args:
            assert isinstance(a, F)
            _atoms(a, out)


def _eval(f: F, env: dict[str, bool]) -> bool:
    match f.op:
        case "const":
            return bool(f.args[0])
        case "atom":
            return env[str(f.args[0])]
        case "not":
            return not _eval(f.args[0], env)  # type: ignore[arg-type]
        case "and":
            return _eval(f.args[0], env) and _eval(f.args[1], env)  # type: ignore[arg-type]
        case _:
            return _eval(f.args[0], env) or _eval(f.args[1], env)  # type: ignore[arg-type]


_MEMBER = r"([A-Za-z_][A-Za-z0-9_]*)\.([A-Za-z_][A-Za-z0-9_]*)"
_VALUE_IS_MEMBER = (re.compile(rf"(.+) == {_MEMBER}\Z"), re.compile(rf"{_MEMBER} == (.+)\Z"))


def _enum_groups(atoms: set[str], enums: Mapping[str, EnumT]
                 ) -> list[tuple[list[str], bool]]:
    """The atoms `VALUE == E.member` grouped by VALUE and E: at most one of a group holds,
    and exactly one when the group names every member of E (the bool)."""
    groups: dict[tuple[str, str], dict[str, str]] = {}
    for atom in atoms:
        m = _VALUE_IS_MEMBER[0].match(atom)
        if m is not None:
            value, enum, member = m.group(1), m.group(2), m.group(3)
        elif (m := _VALUE_IS_MEMBER[1].match(atom)) is not None:
            value, enum, member = m.group(3), m.group(1), m.group(2)
        else:
            continue
        if enum in enums and member in enums[enum].members:
            groups.setdefault((value, enum), {})[member] = atom
    return [(list(g.values()), len(g) == len(enums[enum].members))
            for (_, enum), g in groups.items()]


def _possible(env: dict[str, bool], groups: list[tuple[list[str], bool]]) -> bool:
    for atoms, total in groups:
        true = sum(env[a] for a in atoms)
        if true > 1 or (total and true == 0):
            return False
    return True


def _describe(env: dict[str, bool]) -> str:
    ended = [k[5:] for k, v in sorted(env.items()) if k.startswith("cond:") and v]
    data = [f"{k} is {'true' if v else 'false'}" for k, v in sorted(env.items())
            if not k.startswith("cond:")]
    text = "when " + " and ".join(f"'{c}'" for c in ended) + " ended it"
    return text + (" and " + " and ".join(data) if data else "")


def _condition_keys(b: Behaviour) -> dict[str, tuple[str, bool]]:
    """So that a switch repeating a condition's comparison is recognised as that condition."""
    keys: dict[str, tuple[str, bool]] = {c.name: (c.name, False) for c in b.conditions}
    for c in b.conditions:
        e = c.expr
        if isinstance(e, ast.Binary) and e.op in ("==", "!=", "<", "<=", ">", ">="):
            keys.setdefault(_key(e.op, e.left, e.right), (c.name, e.op in _FLIP))
    return keys


def _check_behaviour(ctx: CheckContext, s: Subsystem, b: Behaviour) -> None:
    live = [c for c in b.conditions if not c.never]
    if not live:
        return  # never ends: no switch is needed
    outgoing = [sw for sw in s.switches if sw.source == b.name]
    if not outgoing:
        ctx.bag.error("E603", f"behaviour '{b.name}' of {s.id} can end (when "
                      + " or ".join(f"'{c.name}'" for c in live) + ") but no switch leaves it",
                      b.span, f"add `switch {b.name} -> NEXT when ...` or `switch {b.name} -> "
                      "end otherwise`")
        return
    conds = _condition_keys(b)
    formulas: list[tuple[Switch, F | None]] = [
        (sw, None if sw.condition is None else _abstract(sw.condition, conds)) for sw in outgoing
    ]
    atoms: set[str] = {f"cond:{c.name}" for c in b.conditions}
    for _, f in formulas:
        if f is not None:
            _atoms(f, atoms)
    if len(atoms) > MAX_ATOMS:
        return
    order = sorted(atoms)
    enums = {n: t for n, t in ctx.system.types if isinstance(t, EnumT)}
    groups = _enum_groups(atoms, enums)
    missing: list[str] = []
    overlaps: dict[tuple[int, int], str] = {}
    for values in itertools.product((False, True), repeat=len(order)):
        env = dict(zip(order, values, strict=True))
        if any(env[f"cond:{c.name}"] for c in b.conditions if c.never):
            continue
        if not any(env[f"cond:{c.name}"] for c in live):
            continue
        if not _possible(env, groups):
            continue
        explicit = [i for i, (_, f) in enumerate(formulas) if f is not None and _eval(f, env)]
        holding = explicit or [i for i, (_, f) in enumerate(formulas) if f is None]
        if not holding:
            missing.append(_describe(env))
        for i, j in itertools.combinations(explicit, 2):
            overlaps.setdefault((i, j), _describe(env))
    if missing:
        shown = "; ".join(missing[:3]) + (f"; and {len(missing) - 3} more" if len(missing) > 3 else "")
        ctx.bag.error("E603", f"after behaviour '{b.name}' of {s.id} ends, no switch condition "
                      f"holds {shown}", b.span,
                      f"add `switch {b.name} -> NEXT otherwise` or cover these cases")
    for (i, j), when in sorted(overlaps.items()):
        ctx.bag.warn("W604", f"switches from '{b.name}' overlap {when}: both may fire",
                     formulas[j][0].span,
                     related=(Related(formulas[i][0].span, "this switch also holds"),))


def _check_reachability(ctx: CheckContext, s: Subsystem) -> None:
    entry = [sw.target for sw in s.switches if sw.source is None]
    seen: set[str] = set()
    stack = [t for t in entry if t is not None]
    while stack:
        b = stack.pop()
        if b in seen:
            continue
        seen.add(b)
        stack += [sw.target for sw in s.switches if sw.source == b and sw.target is not None]
    if not entry:
        return
    for behaviour in s.behaviours:
        if behaviour.name not in seen:
            ctx.bag.warn("W605", f"behaviour '{behaviour.name}' of {s.id} is never entered",
                         behaviour.span, "no switch chain from the initial behaviour leads to it")


def check_switching(ctx: CheckContext) -> None:
    for s in ctx.system.subsystems():
        for b in s.behaviours:
            if b.name not in ctx.unchecked.get(s.id, set()):
                _check_behaviour(ctx, s, b)
        if not ctx.unchecked.get(s.id):  # a switch with errors: reachability is unknown
            _check_reachability(ctx, s)
