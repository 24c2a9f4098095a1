"""Walking expressions without recursion (deeply nested input must not hit the stack limit)."""

from __future__ import annotations

from collections.abc import Iterator

from rssm_dsl.syntax import ast


def children(e: ast.Expr) -> list[ast.Expr]:
    """The direct subexpressions of an expression."""
    match e:
        case ast.FieldAccess():
            return [e.value]
        case ast.InBehaviour():
            return [e.subject]
        case ast.Unary():
            return [e.operand]
        case ast.Index():
            return [e.value, e.index]
        case ast.Binary():
            return [e.left, e.right]
        case ast.IfExpr():
            return [e.condition, e.then, e.otherwise]
        case ast.Call():
            return list(e.args)
        case ast.ArrayLit():
            return list(e.items)
        case ast.RecordLit():
            return [v for _, v in e.fields]
    return []


def names(e: ast.Expr) -> Iterator[ast.Name]:
    """Every name an expression mentions."""
    stack: list[ast.Expr] = [e]
    while stack:
        x = stack.pop()
        if isinstance(x, ast.Name):
            yield x
        else:
            stack += children(x)


def statement_exprs(st: ast.Stmt) -> Iterator[tuple[ast.Expr, str | None]]:
    """The expressions a statement evaluates (the value, the indexes of its target), each
    with the name of the variable the statement assigns (None for the indexes)."""
    if isinstance(st, ast.Let):
        yield st.value, None
    elif isinstance(st, ast.Assign):
        target = st.target
        while isinstance(target, ast.FieldAccess | ast.Index):
            if isinstance(target, ast.Index):
                yield target.index, None
            target = target.value
        yield st.value, target.name if isinstance(target, ast.Name) else None
