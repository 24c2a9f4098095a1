"""An output a behaviour sends by default without updating it, to a consumer that tells new
data from old (W611).

Every output buffer of a subsystem is sent in every iteration of every one of its behaviours
(docs/language.md, "Buffers and channels"): a behaviour without a `send` arrangement sends
them all, in declaration order, whether it updates them or not. A behaviour that has no
`update OUT` (or one that never assigns it: only `skip` and `let`) sends OUT's last value
again in each of its iterations, and the consumer takes it as fresh data each time. That
matters when the consumer acts on fresh data, that is when a `case` clause of it reads
`new(IN)` of the input the channel feeds: a request sent once by one behaviour is a new
request in every iteration of the next one. So the warning is given for such channels only
(a set point sent again to an effector that just uses the latest one is fine). Writing the
behaviour's `send` arrangement says that sending every output is meant, so a behaviour with
one is not warned about; nor is an output that no behaviour writes (W701 says so).
"""

from __future__ import annotations

from rssm_dsl.semantics.checks.context import CheckContext
from rssm_dsl.syntax import ast


def _assigns(u: ast.UpdateDecl) -> bool:
    """Whether the partial function can change its target: some case assigns it."""
    return any(isinstance(st, ast.Assign) for case in u.cases for st in case.body)


def _new_reads(e: ast.Expr, out: set[str]) -> None:
    """Add to `out` the names whose new(x) a case condition reads (E503 and E506 are the
    behaviours' checks: a condition is walked as written)."""
    todo = [e]
    while todo:
        match todo.pop():
            case ast.Call(function="new", args=(ast.Name(name=n),)):
                out.add(n)
            case ast.Unary(operand=x):
                todo.append(x)
            case ast.Binary(left=a, right=b):
                todo += [a, b]


def _fresh_reads(decl: ast.SubsystemDecl) -> set[str]:
    """The inputs of a subsystem whose new(x) a case clause of its behaviours reads."""
    out: set[str] = set()
    for bd in decl.behaviours:
        for u in bd.updates:
            for case in u.cases:
                if case.condition is not None:
                    _new_reads(case.condition, out)
    return out


def _check_subsystem(ctx: CheckContext, sid: str, decl: ast.SubsystemDecl,
                     outputs: tuple[tuple[str, str, str], ...]) -> None:
    """`outputs`: (output, its consumer's id, the consumer's input) of each output some
    behaviour writes and whose consumer reads new() of that input."""
    for bd in decl.behaviours:
        if bd.send:
            continue  # the arrangement names every output: sending them all is what it says
        assigned = {u.target for u in bd.updates if _assigns(u)}
        for name, consumer, into in outputs:
            if name in assigned:
                continue
            ctx.bag.warn(
                "W611", f"behaviour '{bd.name}' of {sid} sends output '{name}' in every "
                f"iteration without updating it: {consumer} gets its last value again each "
                f"time, and new({into}) holds for it", bd.name_span,
                f"give '{bd.name}' an `update {name} {{ ... }}` (a value {consumer} ignores, "
                "or a sequence number it compares), or write the behaviour's `send` "
                "arrangement if sending the value again is meant")


def check_default_sends(ctx: CheckContext) -> None:
    fresh: dict[str, set[str]] = {}

    def reads_new(consumer: str, name: str) -> bool:
        if consumer not in fresh:
            decl = ctx.decls.get(consumer)
            fresh[consumer] = _fresh_reads(decl) if decl is not None else set()
        return name in fresh[consumer]

    feeds: dict[str, dict[str, tuple[str, str]]] = {}
    for ch in ctx.system.channels:
        if reads_new(ch.consumer.owner, ch.consumer.name):
            feeds.setdefault(ch.producer.owner, {})[ch.producer.name] = (
                ch.consumer.owner, ch.consumer.name)
    for s in ctx.system.subsystems():
        decl = ctx.decls.get(s.id)
        fed = feeds.get(s.id)
        if decl is None or not s.behaviours or not fed:
            continue
        written = ctx.written.get(s.id, set())
        outputs = tuple((b.name, *fed[b.name]) for b in s.outputs
                        if b.name in fed and b.name in written)
        if not outputs:
            continue

        def check(c: CheckContext, sid: str = s.id, decl: ast.SubsystemDecl = decl,
                  outputs: tuple[tuple[str, str, str], ...] = outputs) -> None:
            _check_subsystem(c, sid, decl, outputs)

        # what it reads: the subsystem's declaration (the same object while its agent is
        # unchanged) and the outputs it warns about, with their consumers
        ctx.reuse(("default-sends", s.id, decl, *(x for o in outputs for x in o)), check)
