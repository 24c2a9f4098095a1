"""Subsystem layer (paper IV-C): after a behaviour ends, at least one switch condition must
hold (E603); warn when two can hold at once (W604) and when a behaviour is unreachable (W605).

Switch conditions are abstracted to propositional formulas: the names of the source
behaviour's terminal/error conditions are atoms (at least one is true when it ends), every
other comparison or boolean value is an atom. A comparison is one atom whatever its form
(`x > 1`, `1 < x` and `not (x <= 1)` are the negation of `x <= 1`), and two conditions whose
comparisons are one atom are one atom too, so `terminal pos when x > 0` and `terminal nonpos
when x <= 0` never hold together. Atoms are independent except that comparisons of one value
with members of its enum (`phase == Phase.grasp`, `phase != Phase.idle`) exclude each other,
and cover every case when they name all the members, and that `<`, `<=` and `==` of the same
two operands agree as in a total order. The check enumerates the assignments, so it is exact
for that abstraction.
"""

from __future__ import annotations

import itertools
import re
from collections.abc import Mapping

from rssm_core.records import dataclass
from rssm_dsl.diagnostics import Related
from rssm_dsl.semantics.checks.context import CheckContext
from rssm_dsl.semantics.model import Behaviour, Subsystem, Switch
from rssm_dsl.semantics.types import EnumT
from rssm_dsl.syntax import ast
from rssm_dsl.syntax.printer import expr_text

MAX_ATOMS = 14
_FLIP = {">": "<=", ">=": "<", "!=": "=="}
# the comparisons met in one behaviour's switches: atom text -> (left operand, operator,
# right operand)
Parts = dict[str, tuple[str, str, str]]
_MIRROR = {"<": ">", "<=": ">=", ">": "<", ">=": "<=", "==": "==", "!=": "!="}


@dataclass(frozen=True)
class F:
    """A propositional formula: op in const/atom/not/and/or."""

    op: str
    args: tuple[object, ...]


def _abstract(e: ast.Expr, conds: dict[str, tuple[str, bool]], parts: Parts) -> F:
    """`conds` maps a condition name, or the canonical text of a condition's comparison, to
    (the condition whose atom it is, negated)."""
    match e:
        case ast.Literal(value=bool() as v):
            return F("const", (v,))
        case ast.Name(name=n) if n in conds:
            name, negated = conds[n]
            atom = F("atom", (f"cond:{name}",))
            return F("not", (atom,)) if negated else atom
        case ast.Unary(op="not", operand=x):
            return F("not", (_abstract(x, conds, parts),))
        case ast.Binary(op="and" | "or", left=a, right=b):
            return F(e.op, (_abstract(a, conds, parts), _abstract(b, conds, parts)))
        case ast.Binary(op=op, left=a, right=b) if op in _MIRROR:
            key, flipped = _key(op, a, b, parts)
            atom = F("atom", (key,))
            if key in conds:
                name, negated = conds[key]
                atom = F("atom", (f"cond:{name}",))
                atom = F("not", (atom,)) if negated else atom
            return F("not", (atom,)) if flipped else atom
    return F("atom", (expr_text(e),))


def _key(op: str, a: ast.Expr, b: ast.Expr, parts: Parts) -> tuple[str, bool]:
    """The atom of the comparison `a op b`, and whether the comparison is its negation: the
    operands in one order (a literal on the right, else by their text; `1 < x` is `x > 1`),
    the operator one of ==, <, <= (`x > 1` is the negation of `x <= 1`)."""
    left, right = expr_text(a), expr_text(b)
    literal_left = isinstance(a, ast.Literal) and not isinstance(b, ast.Literal)
    if literal_left or (not isinstance(b, ast.Literal) and left > right):
        left, right, op = right, left, _MIRROR[op]
    key = f"{left} {_FLIP.get(op, op)} {right}"
    parts[key] = (left, _FLIP.get(op, op), right)
    return key, op in _FLIP



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


def _order_groups(atoms: set[str], parts: Parts
                  ) -> list[tuple[str | None, str | None, str | None]]:
    """The atoms `A < B`, `A <= B`, `A == B` of one pair of operands, as (lt, le, eq): in a
    total order `A <= B` is `A < B or A == B`, and `A < B` excludes `A == B`."""
    pairs: dict[tuple[str, str], dict[str, str]] = {}
    for atom in atoms:
        if atom in parts:
            left, op, right = parts[atom]
            pairs.setdefault((left, right), {})[op] = atom
    return [(g.get("<"), g.get("<="), g.get("=="))
            for g in pairs.values() if len(g) > 1]


def _possible(env: dict[str, bool], groups: list[tuple[list[str], bool]],
              orders: list[tuple[str | None, str | None, str | None]]) -> bool:
    for atoms, total in groups:
        true = sum(env[a] for a in atoms)
        if true > 1 or (total and true == 0):
            return False
    for lt, le, eq in orders:
        less = env[lt] if lt is not None else None
        equal = env[eq] if eq is not None else None
        if less and equal:
            return False
        if le is not None and (less or equal) and not env[le]:
            return False
        if le is not None and env[le] and less is False and equal is False:
            return False
    return True


def _describe(env: dict[str, bool], ended: list[str]) -> str:
    data = [f"{k} is {'true' if v else 'false'}" for k, v in sorted(env.items())
            if not k.startswith("cond:")]
    text = "when " + " and ".join(f"'{c}'" for c in ended) + " ended it"
    return text + (" and " + " and ".join(data) if data else "")


def _condition_keys(b: Behaviour, parts: Parts) -> dict[str, tuple[str, bool]]:
    """So that a switch repeating a condition's comparison is recognised as that condition,
    and a condition whose comparison is another's (or its negation) as that one's atom."""
    keys: dict[str, tuple[str, bool]] = {}
    for c in b.conditions:
        e, negated_expr = c.expr, False
        while isinstance(e, ast.Unary) and e.op == "not":
            e, negated_expr = e.operand, not negated_expr
        if isinstance(e, ast.Binary) and e.op in _MIRROR:
            key, flipped = _key(e.op, e.left, e.right, parts)
            flipped = flipped != negated_expr
            if key in keys:                      # the atom of an earlier condition
                name, negated = keys[key]
                keys[c.name] = (name, negated != flipped)
                continue
            keys[key] = (c.name, flipped)
        keys[c.name] = (c.name, False)
    return keys


def _holds(name: str, env: dict[str, bool], conds: dict[str, tuple[str, bool]]) -> bool:
    """Whether the condition ``name`` holds in ``env``."""
    atom, negated = conds[name]
    return env[f"cond:{atom}"] != negated


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
    parts: Parts = {}
    conds = _condition_keys(b, parts)
    formulas: list[tuple[Switch, F | None]] = [
        (sw, None if sw.condition is None else _abstract(sw.condition, conds, parts))
        for sw in outgoing
    ]
    atoms: set[str] = {f"cond:{conds[c.name][0]}" for c in b.conditions}
    for _, f in formulas:
        if f is not None:
            _atoms(f, atoms)
    if len(atoms) > MAX_ATOMS:
        return
    order = sorted(atoms)
    enums = {n: t for n, t in ctx.system.types if isinstance(t, EnumT)}
    groups = _enum_groups(atoms, enums)
    orders = _order_groups(atoms, parts)
    missing: list[str] = []
    overlaps: dict[tuple[int, int], str] = {}
    for values in itertools.product((False, True), repeat=len(order)):
        env = dict(zip(order, values, strict=True))
        if any(_holds(c.name, env, conds) for c in b.conditions if c.never):
            continue
        ended = [c.name for c in b.conditions if _holds(c.name, env, conds)]
        if not any(_holds(c.name, env, conds) for c in live):
            continue
        if not _possible(env, groups, orders):
            continue
        explicit = [i for i, (_, f) in enumerate(formulas) if f is not None and _eval(f, env)]
        holding = explicit or [i for i, (_, f) in enumerate(formulas) if f is None]
        if not holding:
            missing.append(_describe(env, ended))
        for i, j in itertools.combinations(explicit, 2):
            overlaps.setdefault((i, j), _describe(env, ended))
    if missing:
        shown = "; ".join(missing[:3]) + (f"; and {len(missing) - 3} more" if len(missing) > 3 else "")
        ctx.bag.error("E603", f"after behaviour '{b.name}' of {s.id} ends, no switch condition "
                      f"holds {shown}", b.span,
                      f"add `switch {b.name} -> NEXT otherwise` or cover these cases")
    for (i, j), when in sorted(overlaps.items()):
        ctx.bag.warn("W604", f"switches from '{b.name}' overlap {when}: both hold, and the "
                     "one declared first is taken", formulas[j][0].span,
                     "make the conditions disjoint, or put the switch meant to win first",
                     related=(Related(formulas[i][0].span, "this switch also holds, and is "
                                      "declared first: it is taken"),))


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


def _check_subsystem(ctx: CheckContext, s: Subsystem, unchecked: set[str]) -> None:
    for b in s.behaviours:
        if b.name not in unchecked:
            _check_behaviour(ctx, s, b)
    if not unchecked:  # a switch with errors: reachability is unknown
        _check_reachability(ctx, s)


def check_switching(ctx: CheckContext) -> None:
    for s in ctx.system.subsystems():
        unchecked = ctx.unchecked.get(s.id, set())

        def check(c: CheckContext, s: Subsystem = s, unchecked: set[str] = unchecked) -> None:
            _check_subsystem(c, s, unchecked)

        # what it reads: its behaviours and switches (the same objects while its agent is
        # unchanged), the enum types (the same while the declarations outside are)
        ctx.reuse(("switching", s.id, s.behaviours, s.switches, unchecked), check)
