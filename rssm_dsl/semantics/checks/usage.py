"""Unused buffers, memory and parameters (W701-W703)."""

from __future__ import annotations

from collections.abc import Iterator

from rssm_dsl.semantics.checks.context import CheckContext
from rssm_dsl.syntax import ast
from rssm_dsl.syntax.walk import names, statement_exprs


def _exprs(decl: ast.SubsystemDecl) -> Iterator[tuple[ast.Expr, str | None]]:
    """Every expression of the subsystem, with the variable whose reads in it do not count:
    `count := count + 1` does not make `count` used."""
    for m in decl.memory:
        if m.init is not None:
            yield m.init, None
    for b in decl.buffers:
        if b.init is not None:
            yield b.init, None
    for p in decl.params:
        yield p.value, None
    for bd in decl.behaviours:
        yield from _behaviour_exprs(bd)
    for sw in decl.switches:
        if sw.condition is not None:
            yield sw.condition, None


def _behaviour_exprs(bd: ast.BehaviourDecl) -> Iterator[tuple[ast.Expr, str | None]]:
    for c in bd.conditions:
        yield c.expr, None
    for u in bd.updates:
        for case in u.cases:
            if case.condition is not None:
                yield case.condition, None
            for st in case.body:
                yield from statement_exprs(st)


def names_read(decl: ast.SubsystemDecl) -> set[str]:
    """The names the subsystem's expressions read (analyze keeps them with each agent's
    work: see AgentMemo)."""
    out: set[str] = set()
    for root, own in _exprs(decl):
        out.update(n.name for n in names(root) if n.name != own)
    return out


def check_usage(ctx: CheckContext) -> None:
    for s in ctx.system.subsystems():
        decl = ctx.decls.get(s.id)
        if decl is None or not s.behaviours:
            continue  # no behaviours: E609 says it all
        read = ctx.read[s.id] | ctx.property_reads.get(s.id, set())
        written = ctx.written.get(s.id, set())
        for b in s.inputs:
            if b.name not in read:
                ctx.bag.warn("W701", f"input '{b.name}' of {s.id} is never read", b.span,
                             "use it in a partial function or a condition, or remove it")
        for b in s.outputs:
            if b.name not in written:
                ctx.bag.warn("W701", f"output '{b.name}' of {s.id} is never written", b.span,
                             f"add `update {b.name} {{ ... }}` to a behaviour")
        for v in s.memory:
            if v.name not in read:
                ctx.bag.warn("W702", f"memory '{v.name}' of {s.id} is never read", v.span,
                             "nothing depends on it (reading it only to update it does not "
                             "count): remove it, or use it")
        for v in s.params:
            if v.name not in read:
                ctx.bag.warn("W703", f"param '{v.name}' of {s.id} is never read", v.span)
