"""Print expressions and statements back as RSSM text (canonical spacing, minimal parentheses)."""

from __future__ import annotations

from rssm_dsl.syntax import ast

_PREC = {"or": 1, "and": 2, "==": 4, "!=": 4, "<": 4, "<=": 4, ">": 4, ">=": 4,
         "+": 5, "-": 5, "*": 6, "/": 6, "%": 6}


def _num(v: bool | int | float) -> str:
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, int):
        return str(v)
    text = repr(v)
    return text if any(c in text for c in ".eEn") else text + ".0"


def expr_text(e: ast.Expr, parent: int = 0) -> str:
    """Text of an expression; `parent` is the precedence of the enclosing operator."""
    match e:
        case ast.Literal():
            return _num(e.value)
        case ast.Name():
            return e.name
        case ast.FieldAccess():
            inner = expr_text(e.value, 9)
            if isinstance(e.value, ast.Literal) and not isinstance(e.value.value, bool):
                inner = f"({inner})"  # `1.x` would lex as the number `1.`
            return f"{inner}.{e.field}"
        case ast.Index():
            return f"{expr_text(e.value, 9)}[{expr_text(e.index)}]"
        case ast.Call():
            return f"{e.function}({', '.join(expr_text(a) for a in e.args)})"
        case ast.Unary():
            inner = expr_text(e.operand, 7 if e.op == "-" else 3)
            text = f"-{inner}" if e.op == "-" else f"not {inner}"
            return f"({text})" if parent > (7 if e.op == "-" else 3) else text
        case ast.Binary():
            p = _PREC[e.op]
            right_p = p + 1 if p != 4 else 5
            left_p = p if p != 4 else 5
            text = f"{expr_text(e.left, left_p)} {e.op} {expr_text(e.right, right_p)}"
            return f"({text})" if parent > p else text
        case ast.IfExpr():
            text = (f"if {expr_text(e.condition)} then {expr_text(e.then)} "
                    f"else {expr_text(e.otherwise)}")
            return f"({text})" if parent > 0 else text
        case ast.ArrayLit():
            return "[" + ", ".join(expr_text(x) for x in e.items) + "]"
        case ast.RecordLit():
            return "{" + ", ".join(f"{n}: {expr_text(v)}" for n, v in e.fields) + "}"
        case ast.InBehaviour():  # binds like a postfix operator: no parentheses needed
            return f"{expr_text(e.subject, 9)} in {e.behaviour}"
    raise AssertionError(e)


def type_text(t: ast.TypeExpr) -> str:
    """Text of a type as written: ``float[3]``, ``Pose``, ``0..3``, ``(-5..5)[2]`` is written
    ``-5..5[2]``."""
    if isinstance(t, ast.ArrayType):
        return f"{type_text(t.element)}[{t.size}]"
    if isinstance(t, ast.RangeType):
        return f"{t.lo}..{t.hi}"
    return t.name


def stmt_text(s: ast.Stmt) -> str:
    match s:
        case ast.Assign():
            return f"{expr_text(s.target)} := {expr_text(s.value)}"
        case ast.Let():
            return f"let {s.name} = {expr_text(s.value)}"
        case ast.Skip():
            return "skip"
    raise AssertionError(s)


def property_text(p: ast.PropertyDecl) -> str:
    """`property NAME: always C` or `property NAME: whenever T eventually G`."""
    if p.kind == "always":
        assert p.condition is not None
        return f"property {p.name}: always {expr_text(p.condition)}"
    assert p.trigger is not None and p.goal is not None
    return (f"property {p.name}: whenever {expr_text(p.trigger)} "
            f"eventually {expr_text(p.goal)}")
