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
two operands agree as in a total order. A terminal or error condition is the atom of its
own comparison or value (`terminal on when flag`, `terminal off when not flag` are one atom
and its negation), so conditions that test one value exclude each other as their comparisons
do (`terminal tx when s == St.x` and `terminal ty when s == St.y` never hold together). The
check considers every assignment of the atoms, so it is exact for that abstraction: each
formula is evaluated once, over all the assignments at once (a bit per assignment of an
integer), and the overlaps are reported once per switch (W604: the first switch declared
before it that may hold with it, and how many more do), so a behaviour left by thousands of
switches costs time linear in them, not in their pairs.
"""

from __future__ import annotations

import re
from collections.abc import Callable, Iterator, Mapping

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
_VALUE = "value:"   # the key of a condition's tested value (not a name: it has a colon)
# an atom, or its negation (True): one side of the constraints between atoms
Literal = tuple[str, bool]


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
    text = expr_text(e)
    if _VALUE + text in conds:       # the value a condition tests (`flag` of `when flag`)
        name, negated = conds[_VALUE + text]
        cond = F("atom", (f"cond:{name}",))
        return F("not", (cond,)) if negated else cond
    return F("atom", (text,))


def _fixed_params(s: Subsystem) -> dict[str, object]:
    """The parameters whose value is a literal (an instance's argument, or the default),
    by name."""
    out: dict[str, object] = {}
    for p in s.params:
        init, sign = p.init, 1
        if isinstance(init, ast.Unary) and init.op == "-":
            init, sign = init.operand, -1
        if isinstance(init, ast.Literal) and isinstance(init.value, bool | int | float):
            if isinstance(init.value, bool):
                if sign == 1:
                    out[p.name] = init.value
            else:
                out[p.name] = sign * init.value
    return out


def _by_params(space: _Space, atoms: set[str], parts: Parts,
               fixed: Mapping[str, object]) -> int:
    """The assignments that agree with the parameters' values: an atom that compares
    parameters and literals (`work_time == 1`), or is a bool parameter, has one value."""
    def value(text: str) -> object:
        if text in fixed:
            return fixed[text]
        if text in ("true", "false"):
            return text == "true"
        try:
            return int(text)
        except ValueError:
            pass
        try:
            return float(text)
        except ValueError:
            return None

    agree = space.full
    for atom in atoms:
        truth: object = None
        if atom in parts:
            left, op, right = parts[atom]
            a, b = value(left), value(right)
            if a is not None and b is not None and isinstance(a, bool) == isinstance(b, bool):
                truth = {"==": a == b, "<": a < b, "<=": a <= b}.get(op)  # type: ignore[operator]
        elif isinstance(fixed.get(atom), bool):
            truth = fixed[atom]
        if isinstance(truth, bool):
            agree &= space.literal((atom, not truth))
    return agree


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


_MEMBER = r"([A-Za-z_][A-Za-z0-9_]*)\.([A-Za-z_][A-Za-z0-9_]*)"
_VALUE_IS_MEMBER = (re.compile(rf"(.+) == {_MEMBER}\Z"), re.compile(rf"{_MEMBER} == (.+)\Z"))


def _enum_groups(atoms: Mapping[str, Literal], enums: Mapping[str, EnumT]
                 ) -> list[tuple[list[Literal], bool]]:
    """The atoms `VALUE == E.member` grouped by VALUE and E: at most one of a group holds,
    and exactly one when the group names every member of E (the bool). ``atoms`` maps the
    text of each comparison to the literal that stands for it (itself, or a condition's
    atom)."""
    groups: dict[tuple[str, str], dict[str, Literal]] = {}
    for atom, literal in atoms.items():
        m = _VALUE_IS_MEMBER[0].match(atom)
        if m is not None:
            value, enum, member = m.group(1), m.group(2), m.group(3)
        elif (m := _VALUE_IS_MEMBER[1].match(atom)) is not None:
            value, enum, member = m.group(3), m.group(1), m.group(2)
        else:
            continue
        if enum in enums and member in enums[enum].members:
            groups.setdefault((value, enum), {})[member] = literal
    return [(list(g.values()), len(g) == len(enums[enum].members))
            for (_, enum), g in groups.items()]


def _order_groups(atoms: Mapping[str, Literal], parts: Parts
                  ) -> list[tuple[Literal | None, Literal | None, Literal | None]]:
    """The atoms `A < B`, `A <= B`, `A == B` of one pair of operands, as (lt, le, eq): in a
    total order `A <= B` is `A < B or A == B`, and `A < B` excludes `A == B`."""
    pairs: dict[tuple[str, str], dict[str, Literal]] = {}
    for atom, literal in atoms.items():
        if atom in parts:
            left, op, right = parts[atom]
            pairs.setdefault((left, right), {})[op] = literal
    return [(g.get("<"), g.get("<="), g.get("=="))
            for g in pairs.values() if len(g) > 1]


class _Space:
    """Every assignment of the atoms ``order`` at once: assignment e (0 <= e < 2^k, in the
    order of itertools.product((False, True), repeat=k): the first atom varies slowest) is
    bit e of an integer, so a formula is one integer, the set of assignments it holds in."""

    def __init__(self, order: list[str]) -> None:
        self.order = order
        k = len(order)
        n = 1 << k
        self.full = (1 << n) - 1
        self.atom: dict[str, int] = {}
        for i, name in enumerate(order):
            half = 1 << (k - 1 - i)            # the atom's bit in e
            period = 2 * half
            self.atom[name] = (((1 << half) - 1) << half) * (self.full // ((1 << period) - 1))

    def literal(self, lit: Literal | None) -> int:
        if lit is None:
            return 0
        m = self.atom[lit[0]]
        return self.full ^ m if lit[1] else m

    def of(self, f: F) -> int:
        match f.op:
            case "const":
                return self.full if f.args[0] else 0
            case "atom":
                return self.atom[str(f.args[0])]
            case "not":
                return self.full ^ self.of(f.args[0])  # type: ignore[arg-type]
            case "and":
                return self.of(f.args[0]) & self.of(f.args[1])  # type: ignore[arg-type]
            case _:
                return self.of(f.args[0]) | self.of(f.args[1])  # type: ignore[arg-type]

    def env(self, e: int) -> dict[str, bool]:
        k = len(self.order)
        return {a: bool(e >> (k - 1 - i) & 1) for i, a in enumerate(self.order)}


def _bits(mask: int) -> Iterator[int]:
    """The set bits of ``mask``, lowest first."""
    while mask:
        low = mask & -mask
        yield low.bit_length() - 1
        mask ^= low


def _impossible(space: _Space, groups: list[tuple[list[Literal], bool]],
                orders: list[tuple[Literal | None, Literal | None, Literal | None]]) -> int:
    """The assignments that the enum groups and the orders exclude."""
    out = 0
    for literals, total in groups:
        once = twice = 0
        for lit in literals:
            m = space.literal(lit)
            twice |= once & m
            once |= m
        out |= twice | (space.full ^ once if total else 0)
    for lt, le, eq in orders:
        less, equal, at_most = space.literal(lt), space.literal(eq), space.literal(le)
        out |= less & equal                                  # A < B and A == B
        if le is not None:
            out |= (less | equal) & ~at_most                 # A < B or A == B, not A <= B
            if lt is not None and eq is not None:
                out |= at_most & ~less & ~equal              # A <= B, neither
    return out & space.full


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
        key: str | None = None
        if isinstance(e, ast.Binary) and e.op in _MIRROR:
            key, flipped = _key(e.op, e.left, e.right, parts)
            flipped = flipped != negated_expr
        elif not isinstance(e, ast.Literal | ast.Binary | ast.Unary):   # a value: `flag`
            key, flipped = _VALUE + expr_text(e), negated_expr
        if key is not None:
            if key in keys:                      # the atom of an earlier condition
                name, negated = keys[key]
                keys[c.name] = (name, negated != flipped)
                continue
            keys[key] = (c.name, flipped)
        keys[c.name] = (c.name, False)
    return keys


def _check_behaviour(ctx: CheckContext, s: Subsystem, b: Behaviour,
                     outgoing: list[Switch], enums: Mapping[str, EnumT]) -> None:
    live = [c for c in b.conditions if not c.never]
    if not live:
        return  # never ends: no switch is needed
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
    space = _Space(sorted(atoms))
    # the comparisons the atoms stand for: an atom's own text, or a condition's comparison
    meaning: dict[str, Literal] = {a: (a, False) for a in atoms}
    for key, (name, negated) in conds.items():
        if key in parts:
            meaning[key] = (f"cond:{name}", negated)
    impossible = _impossible(space, _enum_groups(meaning, enums), _order_groups(meaning, parts))

    def holds(name: str) -> int:
        atom, negated = conds[name]
        return space.literal((f"cond:{atom}", negated))

    never = 0
    for c in b.conditions:
        if c.never:
            never |= holds(c.name)
    ends = 0
    for c in live:
        ends |= holds(c.name)
    valid = ends & ~never & ~impossible & space.full   # the assignments in which b ends

    def when(e: int) -> str:
        env = space.env(e)
        ended = [c.name for c in b.conditions if env[f"cond:{conds[c.name][0]}"]
                 != conds[c.name][1]]
        return _describe(env, ended)

    explicit = [(i, space.of(f) & valid) for i, (_, f) in enumerate(formulas) if f is not None]
    if all(f is not None for _, f in formulas):   # else `otherwise` holds when none does
        covered = 0
        for _, m in explicit:
            covered |= m
        _report_missing(ctx, s, b, valid & ~covered, when)
    # the overlaps where the parameters have their values: a switch a parameter rules out
    # in this subsystem (`when reported and work_time == 1`, work_time 2) overlaps nothing
    agree = _by_params(space, atoms, parts, _fixed_params(s))
    explicit = [(i, m & agree) for i, m in explicit]
    _report_overlaps(ctx, s, b, formulas, explicit, when)


def _report_missing(ctx: CheckContext, s: Subsystem, b: Behaviour, missing: int,
                    when: Callable[[int], str]) -> None:
    """E603 for the assignments ``missing`` (the first three shown, the others counted)."""
    if not missing:
        return
    count = missing.bit_count()
    shown = "; ".join(when(e) for e, _ in zip(_bits(missing), range(3), strict=False))
    shown += f"; and {count - 3} more" if count > 3 else ""
    ctx.bag.error("E603", f"after behaviour '{b.name}' of {s.id} ends, no switch condition "
                  f"holds {shown}", b.span,
                  f"add `switch {b.name} -> NEXT otherwise` or cover these cases")


def _report_overlaps(ctx: CheckContext, s: Subsystem, b: Behaviour,
                     formulas: list[tuple[Switch, F | None]],
                     explicit: list[tuple[int, int]], when: Callable[[int], str]) -> None:
    """W604 once per switch that may hold with switches declared before it: naming the
    first of them (it is taken), with the count of the others. Switches with the same
    assignments are counted together, so the cost is the switches times the distinct sets
    of assignments, not the pairs of switches."""
    before: dict[int, list[int]] = {}   # a set of assignments -> the switches that hold in it
    masks = dict(explicit)
    for j, mask in explicit:
        if not mask:
            continue
        first: int | None = None
        others = 0
        for m, switches in before.items():
            if m & mask:
                others += len(switches)
                if first is None or switches[0] < first:
                    first = switches[0]
        before.setdefault(mask, []).append(j)
        if first is None:
            continue
        more = others - 1
        ctx.bag.warn("W604", f"switches from '{b.name}' of {s.id} overlap "
                     f"{when(next(_bits(masks[first] & mask)))}: both hold, "
                     "and the one declared first is taken" + (
                         f" (this switch also overlaps {more} other switch"
                         f"{'es' if more > 1 else ''} declared before it)" if more else ""),
                     formulas[j][0].span,
                     "make the conditions disjoint, or put the switch meant to win first",
                     related=(Related(formulas[first][0].span, "this switch also holds, and is "
                                      "declared first: it is taken"),))


def _check_reachability(ctx: CheckContext, s: Subsystem) -> None:
    entry = [sw.target for sw in s.switches if sw.source is None]
    if not entry:
        return
    leaving: dict[str, list[str]] = {}
    for sw in s.switches:
        if sw.source is not None and sw.target is not None:
            leaving.setdefault(sw.source, []).append(sw.target)
    seen: set[str] = set()
    stack = [t for t in entry if t is not None]
    while stack:
        b = stack.pop()
        if b in seen:
            continue
        seen.add(b)
        stack += leaving.get(b, ())
    for behaviour in s.behaviours:
        if behaviour.name not in seen:
            ctx.bag.warn("W605", f"behaviour '{behaviour.name}' of {s.id} is never entered",
                         behaviour.span, "no switch chain from the initial behaviour leads to it")


def _check_subsystem(ctx: CheckContext, s: Subsystem, unchecked: set[str]) -> None:
    enums = {n: t for n, t in ctx.system.types if isinstance(t, EnumT)}
    outgoing: dict[str, list[Switch]] = {}
    for sw in s.switches:
        if sw.source is not None:
            outgoing.setdefault(sw.source, []).append(sw)
    for b in s.behaviours:
        if b.name not in unchecked:
            _check_behaviour(ctx, s, b, outgoing.get(b.name, []), enums)
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
