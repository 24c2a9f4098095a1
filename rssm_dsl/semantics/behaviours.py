"""Behaviours of a subsystem: partial transition functions (canonical decomposition) split
into data-availability cases (the rule: rssm_dsl/semantics/cases.py), terminal/error conditions,
send/receive arrangements, and the switches of the subsystem layer."""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import field
from functools import cache

from rssm_core.records import dataclass
from rssm_dsl.diagnostics import DiagnosticBag, Related
from rssm_dsl.semantics import cases as case_rule
from rssm_dsl.semantics.declarations import Globals
from rssm_dsl.semantics.model import (
    Arrangement,
    ArrLeaf,
    ArrPar,
    ArrSeq,
    Behaviour,
    Buffer,
    Condition,
    DataCase,
    PartialFunction,
    Switch,
)
from rssm_dsl.semantics.structure import Shell
from rssm_dsl.semantics.typecheck import (
    ExprChecker,
    Scope,
    Symbol,
    did_you_mean,
    guess_hint,
    mismatch_hint,
    owner_symbols,
)
from rssm_dsl.semantics.types import BOOL, Type, assignable
from rssm_dsl.source import Span
from rssm_dsl.syntax import ast
from rssm_dsl.syntax.printer import expr_text
from rssm_dsl.syntax.walk import names

MEMORY = "memory"
_KIND_TEXT = {"param": "parameter", "const": "constant", "local": "`let` value",
              "extern": "external operation"}


@cache
def combination_text(inputs: tuple[str, ...], new: case_rule.Combination) -> str:
    return case_rule.text(inputs, new)


def new_reads(e: ast.Expr, inputs: tuple[str, ...]) -> set[str]:
    """The inputs whose new(x) a case condition reads."""
    out: set[str] = set()
    todo = [e]
    while todo:
        match todo.pop():
            case ast.Call(function="new", args=(ast.Name(name=n),)) if n in inputs:
                out.add(n)
            case ast.Unary(operand=x):
                todo.append(x)
            case ast.Binary(left=a, right=b):
                todo += [a, b]
    return out


def split_inputs(updates: Iterable[ast.UpdateDecl], inputs: tuple[str, ...]) -> tuple[int, ...]:
    """The split inputs of a behaviour (rssm_dsl/semantics/cases.py): those whose new(x) a case clause
    of any of its partial functions reads, in declaration order."""
    read: set[str] = set()
    for u in updates:
        for c in u.cases:
            if c.condition is not None:
                read |= new_reads(c.condition, inputs)
    return tuple(k for k, x in enumerate(inputs) if x in read)


class _NotData(Exception):
    def __init__(self, span: Span) -> None:
        self.span = span


def eval_availability(e: ast.Expr, inputs: tuple[str, ...], new: case_rule.Combination
                       ) -> bool:
    """Evaluate a case condition made of new(x), and/or/not, true/false (every input it
    reads is given in ``new``)."""
    match e:
        case ast.Literal(value=bool() as v):
            return v
        case ast.Call(function="new", args=(ast.Name(name=n),)) if n in inputs:
            return bool(new[inputs.index(n)])
        case ast.Unary(op="not", operand=x):
            return not eval_availability(x, inputs, new)
        case ast.Binary(op="and", left=a, right=b):
            return eval_availability(a, inputs, new) and eval_availability(b, inputs, new)
        case ast.Binary(op="or", left=a, right=b):
            return eval_availability(a, inputs, new) or eval_availability(b, inputs, new)
    raise _NotData(e.span)


def data_only(e: ast.Expr, inputs: tuple[str, ...]) -> None:
    """Raise _NotData at the first part of a case condition that is not new(x) of an input,
    and/or/not, true/false (all of it, without evaluating it)."""
    match e:
        case ast.Literal(value=bool()):
            return
        case ast.Call(function="new", args=(ast.Name(name=n),)) if n in inputs:
            return
        case ast.Unary(op="not", operand=x):
            data_only(x, inputs)
            return
        case ast.Binary(op="and" | "or", left=a, right=b):
            data_only(a, inputs)
            data_only(b, inputs)
            return
    raise _NotData(e.span)


def partial_availability(e: ast.Expr, inputs: tuple[str, ...], given: dict[str, bool]
                         ) -> bool | None:
    """A case condition with new(x) known for the inputs in ``given`` only: its value, or
    None when it still depends on the others."""
    match e:
        case ast.Literal(value=bool() as v):
            return v
        case ast.Call(function="new", args=(ast.Name(name=n),)) if n in inputs:
            return given.get(n)
        case ast.Unary(op="not", operand=x):
            inner = partial_availability(x, inputs, given)
            return None if inner is None else not inner
        case ast.Binary(op="and", left=a, right=b):
            va, vb = (partial_availability(a, inputs, given),
                      partial_availability(b, inputs, given))
            return False if va is False or vb is False else None if None in (va, vb) else True
        case ast.Binary(op="or", left=a, right=b):
            va, vb = (partial_availability(a, inputs, given),
                      partial_availability(b, inputs, given))
            return True if va is True or vb is True else None if None in (va, vb) else False
    raise _NotData(e.span)


def _errors_since(bag: DiagnosticBag, mark: int) -> bool:
    """Whether an error was reported after the first ``mark`` diagnostics (counting all of
    them after each clause was quadratic: 3,000 case clauses with errors took 8 s)."""
    return any(d.is_error for d in bag.items[mark:])


@dataclass
class SubsystemUsage:
    reads: set[str] = field(default_factory=set)
    written: set[str] = field(default_factory=set)


class BehaviourPass:
    def __init__(self, bag: DiagnosticBag, g: Globals, shell: Shell) -> None:
        self.bag = bag
        self.g = g
        self.shell = shell
        self.checker = ExprChecker(bag)
        self.usage = SubsystemUsage()
        self.inputs: tuple[Buffer, ...] = tuple(shell.inputs())
        self.outputs: tuple[Buffer, ...] = tuple(shell.outputs())
        self.input_names = tuple(b.name for b in self.inputs)
        syms = owner_symbols(g.symbols(), shell.params, shell.memory, shell.buffers)
        # declared with a type that is unknown (already reported): known names, no checks
        self.unresolved: dict[str, str] = {}
        for d in shell.unresolved:
            kind = ("param" if isinstance(d, ast.ParamDecl) else "memory"
                    if isinstance(d, ast.MemoryDecl) else d.direction.value)
            self.unresolved[d.name] = kind
            syms[d.name] = Symbol(kind, None, d.span)
        self.symbols = syms
        self.all_conditions: dict[str, str] = {}  # condition name -> behaviour
        # behaviours with a switch already reported (unknown behaviour, bad condition): the
        # switching check skips them, and the reachability of this subsystem's behaviours
        self.unchecked: set[str] = set()

    def scope(self, new_allowed: bool = False) -> Scope:
        return Scope(self.symbols, self.g.externs, new_allowed, self.input_names,
                     reads=self.usage.reads)

    # ------------------------------------------------------------------ entry
    def run(self, decl: ast.SubsystemDecl) -> tuple[tuple[Behaviour, ...], tuple[Switch, ...]]:
        behaviours: list[Behaviour] = []
        seen: dict[str, Span] = {}
        if not decl.behaviours:
            self.bag.error("E609", f"{self.shell.id} has no behaviours", decl.name_span,
                           "add `behaviour NAME { ... }` and `initial NAME`")
            return (), ()
        for bd in decl.behaviours:
            for c in bd.conditions:
                self.all_conditions.setdefault(c.name, bd.name)
        for bd in decl.behaviours:
            if bd.name in seen:
                self.bag.error("E101", f"behaviour '{bd.name}' is declared twice", bd.name_span,
                               related=(Related(seen[bd.name], "first declared here"),))
                continue
            if bd.name == "end":
                self.bag.error("E101", "'end' names the end of the subsystem; choose another "
                               "behaviour name", bd.name_span)
                continue
            seen[bd.name] = bd.name_span
            behaviours.append(self._behaviour(bd))
        switches = self._switches(decl, {b.name: b for b in behaviours})
        return tuple(behaviours), switches

    # ------------------------------------------------------------------ behaviour
    def _behaviour(self, bd: ast.BehaviourDecl) -> Behaviour:
        updates: dict[str, ast.UpdateDecl] = {}
        out_names = {b.name for b in self.outputs}
        for u in bd.updates:
            if u.target in updates:
                self.bag.error("E403", f"two partial functions for '{u.target}' in behaviour "
                               f"'{bd.name}'", u.target_span,
                               related=(Related(updates[u.target].target_span, "the first one"),))
                continue
            if u.target != MEMORY and u.target not in out_names:
                if self.unresolved.get(u.target) != "output":
                    self._bad_target(u)
                continue
            updates[u.target] = u
        functions: list[PartialFunction] = []
        targets = [b.name for b in self.outputs] + [MEMORY]
        split = split_inputs(updates.values(), self.input_names)
        for psi, target in enumerate(targets, start=1):
            functions.append(self._function(psi, target, updates.get(target), bd, split))
        conditions = self._conditions(bd)
        send = self._arrangement(bd, bd.send, self.outputs, "send")
        receive = self._arrangement(bd, bd.receive, self.inputs, "receive")
        return Behaviour(bd.name, bd.span, tuple(functions), conditions, send, receive)

    def _bad_target(self, u: ast.UpdateDecl) -> None:
        if u.target in self.input_names:
            self.bag.error("E402", f"'{u.target}' is an input buffer: no partial function "
                           "writes it", u.target_span,
                           "inputs are filled by receiving; update an output buffer or memory")
        elif any(v.name == u.target for v in self.shell.memory):
            self.bag.error("E404", f"'{u.target}' is a memory variable: memory has one partial "
                           "function", u.target_span, "write it inside `update memory { ... }`")
        else:
            outs = ", ".join(b.name for b in self.outputs) or "none"
            self.bag.error("E404", f"'{u.target}' is not an output buffer of {self.shell.id}",
                           u.target_span, f"update one of its outputs ({outs}) or memory")

    def _function(self, psi: int, target: str, u: ast.UpdateDecl | None,
                  bd: ast.BehaviourDecl, split: tuple[int, ...]) -> PartialFunction:
        n = len(self.inputs)
        if u is None:  # no partial function written: one void case
            return PartialFunction(psi, target, (DataCase(1, (None,) * n, (), bd.span, None),),
                                   bd.span)
        for case in u.cases:
            self._body(case.body, target)
        if all(c.condition is None for c in u.cases):
            split = ()  # no case clause: one case (the text distinguishes nothing)
        return PartialFunction(psi, target, self._cases(u, split), u.span)

    def _cases(self, u: ast.UpdateDecl, split: tuple[int, ...]) -> tuple[DataCase, ...]:
        """One case per combination of new(x) of the ``split`` inputs (rssm_dsl/semantics/cases.py);
        the clauses are checked disjoint and exhaustive over them, which is exact: no clause
        reads another input."""
        inputs = self.input_names
        combos = (case_rule.combinations(split, len(inputs))
                  if len(split) <= case_rule.FULL_SPLIT else [])
        explicit: list[tuple[int, ast.Case]] = []
        fallback: tuple[int, ast.Case] | None = None
        broken = False  # a condition already reported: coverage is not checked
        for i, case in enumerate(u.cases):
            if case.condition is None:
                if fallback is not None:
                    self.bag.error("E502", "two `otherwise` cases", case.span,
                                   related=(Related(fallback[1].span, "the first one"),))
                    continue
                fallback = (i, case)
                continue
            mark = len(self.bag.items)
            self.checker.check(case.condition, self.scope(new_allowed=True), BOOL)
            if (_errors_since(self.bag, mark)
                    or any(n.name in self.unresolved for n in names(case.condition))):
                broken = True
                continue
            try:
                if len(split) <= case_rule.FULL_SPLIT:
                    for combo in combos:
                        eval_availability(case.condition, inputs, combo)
                else:
                    data_only(case.condition, inputs)
            except _NotData as e:
                self.bag.error("E506", "a case condition may only combine new(x) of input "
                               "buffers with and/or/not", e.span,
                               "test data values inside the case, with `if ... then ... else`")
                broken = True
                continue
            explicit.append((i, case))
        out: list[DataCase] = []
        missing: list[str] = []
        overlaps: dict[tuple[int, int], list[str]] = {}
        if len(split) > case_rule.FULL_SPLIT:
            combos = self._cubes(explicit, split)
        for varpi, combo in enumerate(combos, start=1):
            covering = [(i, c) for i, c in explicit if eval_availability(c.condition, inputs, combo)]  # type: ignore[arg-type]
            if len(covering) > 1:
                overlaps.setdefault((covering[0][0], covering[1][0]), []).append(
                    combination_text(inputs, combo))
            if not covering and fallback is not None:
                covering = [fallback]
            if not covering:
                missing.append(combination_text(inputs, combo))
                continue
            index, case = covering[0]
            out.append(DataCase(varpi, combo, case.body, case.span, index))
        for (i1, i2), texts in sorted(overlaps.items()):
            self.bag.error("E502", "cases overlap when " + "; ".join(texts), u.cases[i2].span,
                           "make the case conditions disjoint",
                           related=(Related(u.cases[i1].span, "this case also covers it"),))
        if missing and not broken:
            self.bag.error(
                "E501", f"no case of `update {u.target}` covers: " + "; ".join(missing),
                u.target_span, "add the missing case(s) or an `otherwise:` case",
            )
        return tuple(out)

    def _cubes(self, explicit: list[tuple[int, ast.Case]], split: tuple[int, ...]
               ) -> list[case_rule.Combination]:
        """The cases of a function whose behaviour splits more than FULL_SPLIT inputs
        (rssm_dsl/semantics/cases.py): the leaves of a decision on new(x), input by input (in
        declaration order, new first), of the inputs the clauses still undecided read; a leaf
        is reached when every clause is decided (a partial evaluation), so it stands for one
        clause (or `otherwise`, or a missing or overlapping combination, which the caller
        reports) for every value of the inputs it leaves open."""
        inputs = self.input_names
        n = len(inputs)
        reads = [{inputs.index(x) for x in new_reads(c.condition, inputs)}  # type: ignore[arg-type]
                 for _, c in explicit]
        out: list[case_rule.Combination] = []
        todo: list[dict[int, bool]] = [{}]
        while todo:
            known = todo.pop()
            given = {inputs[k]: v for k, v in known.items()}
            open_ = [r for (_, c), r in zip(explicit, reads, strict=True)
                     if partial_availability(c.condition, inputs, given) is None]  # type: ignore[arg-type]
            nxt = next((k for k in split if k not in known and any(k in r for r in open_)),
                       None)
            if nxt is None:
                out.append(tuple(known.get(k) for k in range(n)))
                continue
            todo += [{**known, nxt: False}, {**known, nxt: True}]   # new first (popped first)
        return out

    # ------------------------------------------------------------------ statements
    def _body(self, body: tuple[ast.Stmt, ...], target: str) -> None:
        scope = self.scope()
        for stmt in body:
            match stmt:
                case ast.Skip():
                    pass
                case ast.Let():
                    if scope.lookup(stmt.name) is not None:
                        self.bag.error("E101", f"'{stmt.name}' is already declared", stmt.span,
                                       "choose another name for the local value")
                    t = self.checker.check(stmt.value, scope)
                    scope.extra[stmt.name] = Symbol("local", t, stmt.span)
                case ast.Assign():
                    self._assign(stmt, scope, target)

    def _assign(self, stmt: ast.Assign, scope: Scope, target: str) -> None:
        root = self.checker.root_name(stmt.target)
        if root is None:
            self.bag.error("E205", "only buffers and memory can be assigned", stmt.target.span)
            return
        sym = scope.lookup(root.name)
        if sym is None:
            guess = did_you_mean(root.name, scope.names)
            self.bag.error("E102", f"'{root.name}' is not declared here", root.span,
                           guess_hint(guess, scope, root.span) if guess else None)
            self.checker.check(stmt.value, scope)
            return
        allowed = (sym.kind == "memory") if target == MEMORY else (
            sym.kind == "output" and root.name == target)
        if sym.kind == "input":
            self.bag.error("E402", f"'{root.name}' is an input buffer and cannot be written",
                           root.span, "inputs are filled by receiving")
        elif sym.kind not in ("memory", "output"):
            self.bag.error("E205", f"'{root.name}' is a {_KIND_TEXT.get(sym.kind, sym.kind)} "
                           "and cannot be assigned", root.span,
                           "only output buffers and memory variables are assigned; keep a "
                           "changing value in memory")
        elif not allowed:
            what = "memory" if target == MEMORY else f"output '{target}'"
            where = "`update memory`" if sym.kind == "memory" else f"`update {root.name}`"
            self.bag.error(
                "E401", f"the partial function for {what} writes '{root.name}' ({sym.kind})",
                root.span, f"canonical decomposition: move this into {where}",
            )
        reads_before = set(scope.reads)
        lt: Type | None = self.checker.check(stmt.target, scope)
        scope.reads.clear()
        scope.reads.update(reads_before | self._index_reads(stmt.target, scope))
        if allowed:
            self.usage.written.add(root.name)
        if lt is None:
            self.checker.check(stmt.value, scope)
            return
        got = self.checker.check(stmt.value, scope, lt)
        if got is not None and not assignable(got, lt):
            self.bag.error("E201", f"cannot assign {got} to '{root.name}' of type {lt}",
                           stmt.value.span, hint=mismatch_hint(got, lt))
        elif got is not None:
            self.checker.fits(stmt.value, lt, expr_text(stmt.target))

    def _index_reads(self, target: ast.Expr, scope: Scope) -> set[str]:
        names: set[str] = set()
        while isinstance(target, ast.FieldAccess | ast.Index):
            if isinstance(target, ast.Index):
                sub = Scope(scope.symbols, scope.externs, extra=scope.extra)
                self.checker.check(target.index, sub)
                names |= sub.reads
            target = target.value
        return names

    # ------------------------------------------------------------------ conditions
    def _conditions(self, bd: ast.BehaviourDecl) -> tuple[Condition, ...]:
        out: list[Condition] = []
        seen: dict[str, Span] = {}
        for c in bd.conditions:
            if c.name in seen:
                self.bag.error("E101", f"condition '{c.name}' is declared twice in behaviour "
                               f"'{bd.name}'", c.name_span,
                               related=(Related(seen[c.name], "first declared here"),))
                continue
            if c.name in self.symbols:
                self.bag.error("E101", f"condition '{c.name}' has the name of a "
                               f"{self.symbols[c.name].kind}", c.name_span)
                continue
            seen[c.name] = c.name_span
            self.checker.expect(c.expr, self.scope(), BOOL, f"{c.kind} condition '{c.name}'")
            out.append(Condition(c.kind, c.name, c.expr, c.span))
        if not any(c.kind == "terminal" for c in out):
            self.bag.error("E602", f"behaviour '{bd.name}' has no terminal condition", bd.name_span,
                           "add `terminal NAME when EXPR` (`terminal never when false` runs "
                           "forever)")
        return tuple(out)

    # ------------------------------------------------------------------ arrangements
    def _arrangement(self, bd: ast.BehaviourDecl, decls: tuple[ast.Arrangement, ...],
                     buffers: tuple[Buffer, ...], verb: str) -> Arrangement | None:
        if len(decls) > 1:
            self.bag.error("E610", f"behaviour '{bd.name}' has {len(decls)} `{verb}` "
                           "declarations", decls[1].span, f"combine them: `{verb} a; b` "
                           f"(in sequence) or `{verb} a | b` (in parallel)")
        if not decls:
            if not buffers:
                return None
            leaves: tuple[Arrangement, ...] = tuple(ArrLeaf(b.name, bd.span) for b in buffers)
            return leaves[0] if len(leaves) == 1 else ArrSeq(leaves, bd.span)
        kind = "output" if verb == "send" else "input"
        names = {b.name for b in buffers} | {n for n, k in self.unresolved.items() if k == kind}
        seen: dict[str, Span] = {}

        def convert(a: ast.Arrangement) -> Arrangement:
            match a:
                case ast.ArrBuffer():
                    if a.name not in names:
                        self.bag.error("E607", f"'{a.name}' is not an {kind} buffer of "
                                       f"{self.shell.id}", a.span)
                    elif a.name in seen:
                        self.bag.error("E607", f"'{a.name}' appears twice in `{verb}`", a.span,
                                       related=(Related(seen[a.name], "first here"),))
                    seen.setdefault(a.name, a.span)
                    return ArrLeaf(a.name, a.span)
                case ast.ArrSeq():
                    return ArrSeq(tuple(convert(x) for x in a.items), a.span)
                case ast.ArrPar():
                    return ArrPar(tuple(convert(x) for x in a.items), a.span)

        # several declarations (E610, reported above) are checked as one sequence
        whole = decls[0] if len(decls) == 1 else ast.ArrSeq(decls[0].span.to(decls[-1].span),
                                                            decls)
        result = convert(whole)
        missing = [b.name for b in buffers if b.name not in seen]
        if missing:
            self.bag.error("E606", f"`{verb}` of behaviour '{bd.name}' misses "
                           + ", ".join(missing), decls[0].span,
                           f"every {kind} buffer is {'sent' if verb == 'send' else 'received'} "
                           "once per iteration")
        return result

    # ------------------------------------------------------------------ switches
    def _switches(self, decl: ast.SubsystemDecl, behaviours: dict[str, Behaviour]
                  ) -> tuple[Switch, ...]:
        out: list[Switch] = []
        if len(decl.initial) != 1:
            span = decl.initial[1].span if len(decl.initial) > 1 else decl.name_span
            first = decl.behaviours[0].name if decl.behaviours else "NAME"
            self.bag.error("E601", f"{self.shell.id} needs exactly one `initial` behaviour, "
                           f"it has {len(decl.initial)}", span,
                           f"add `initial {first}` (the behaviour the subsystem starts in)"
                           if not decl.initial else "keep one `initial` line",
                           related=tuple(Related(i.span, "an initial behaviour")
                                         for i in decl.initial[:1] if len(decl.initial) > 1))
        for ini in decl.initial[:1]:
            if ini.behaviour not in behaviours:
                self._no_behaviour(ini.behaviour, ini.behaviour_span, behaviours)
                continue
            out.append(Switch(0, None, ini.behaviour, None, False, ini.span))
        for i, sw in enumerate(decl.switches, start=1):
            ok = True
            if sw.source not in behaviours:
                self._no_behaviour(sw.source, sw.source_span, behaviours)
                ok = False
            if sw.target != "end" and sw.target not in behaviours:
                self._no_behaviour(sw.target, sw.target_span, behaviours,
                                   "switch to `end` to finish the subsystem")
                ok = False
            if sw.condition is not None and sw.source in behaviours:
                mark = len(self.bag.items)
                self._switch_condition(sw.condition, behaviours[sw.source])
                if _errors_since(self.bag, mark):
                    ok = False
            if not ok and sw.source in behaviours:
                self.unchecked.add(sw.source)
            if ok:
                out.append(Switch(i, sw.source, None if sw.target == "end" else sw.target,
                                  sw.condition, sw.condition is None, sw.span))
        return tuple(out)

    def _no_behaviour(self, name: str, span: Span, behaviours: dict[str, Behaviour],
                      hint: str | None = None) -> None:
        guess = did_you_mean(name, behaviours)
        self.bag.error("E102", f"no behaviour '{name}' in {self.shell.id}", span,
                       f"did you mean '{guess}'?" if guess else hint)

    def _switch_condition(self, e: ast.Expr, source: Behaviour) -> None:
        scope = self.scope()
        for c in source.conditions:
            scope.extra[c.name] = Symbol("condition", BOOL, c.span)
        for name in names(e):
            if scope.lookup(name.name) is None and name.name in self.all_conditions:
                self.bag.error("E608", f"'{name.name}' is a condition of behaviour "
                               f"'{self.all_conditions[name.name]}', not of '{source.name}'",
                               name.span, "a switch may test the conditions of its source "
                               "behaviour only")
                return
        self.checker.expect(e, scope, BOOL, "a switch condition")
