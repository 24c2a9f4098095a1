"""Property tests for the parser: printing a parsed expression and parsing it again gives
the same tree, for random expressions of the language."""

from __future__ import annotations

from hypothesis import given, settings
from hypothesis import strategies as st

from rssm_dsl.source import SourceFile
from rssm_dsl.syntax import ast
from rssm_dsl.syntax.parser import parse
from rssm_dsl.syntax.printer import expr_text

NAMES = st.sampled_from(["x", "y", "phase", "state", "cmd", "k_2", "_t"])


def exprs() -> st.SearchStrategy[str]:
    leaf = st.one_of(
        NAMES,
        st.integers(0, 10**6).map(str),
        st.floats(0, 1e6, allow_nan=False, allow_infinity=False).map(repr),
        st.sampled_from(["true", "false", "pi"]),
    )

    def extend(inner: st.SearchStrategy[str]) -> st.SearchStrategy[str]:
        binop = st.sampled_from(["+", "-", "*", "/", "%", "and", "or", "<", "<=", "==", "!="])
        return st.one_of(
            st.tuples(inner, binop, inner).map(lambda t: f"{t[0]} {t[1]} {t[2]}"),
            inner.map(lambda e: f"({e})"),
            inner.map(lambda e: f"-{e}"),
            inner.map(lambda e: f"not {e}"),
            st.tuples(NAMES, st.lists(inner, max_size=3)).map(
                lambda t: f"{t[0]}({', '.join(t[1])})"),
            st.lists(inner, min_size=1, max_size=3).map(lambda xs: f"[{', '.join(xs)}]"),
            st.tuples(inner, NAMES).map(lambda t: f"({t[0]}).{t[1]}"),
            st.tuples(inner, inner).map(lambda t: f"({t[0]})[{t[1]}]"),
            st.tuples(inner, inner, inner).map(lambda t: f"if {t[0]} then {t[1]} else {t[2]}"),
        )

    return st.recursive(leaf, extend, max_leaves=12)


def parse_const(text: str) -> ast.Expr | None:
    result = parse(SourceFile("<t>", f"const c = {text}\n"))
    if result.diagnostics or result.module is None:
        return None
    decl = result.module.decls[0]
    assert isinstance(decl, ast.ConstDecl)
    return decl.value


@settings(max_examples=300, deadline=None)
@given(exprs())
def test_print_parse_roundtrip(text: str) -> None:
    first = parse_const(text)
    if first is None:  # e.g. chained comparisons, which the grammar rejects
        return
    printed = expr_text(first)
    second = parse_const(printed)
    assert second is not None, printed
    assert expr_text(second) == printed
