"""Property tests: mutated specifications never crash the compiler, and every IR it
produces is well-formed."""

from __future__ import annotations

from pathlib import Path

from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from rssm_dsl.diagnostics import BY_CODE
from rssm_dsl.hpn.flatten import flatten
from rssm_dsl.hpn.wellformed import violations
from rssm_dsl.pipeline import compile_file
from tests.conftest import example_specs

SPECS = {p: p.read_text(encoding="utf-8") for p in example_specs()}
TOKENS = ["{", "}", "(", ")", "[", "]", ":", ":=", ";", "|", "->", "when", "case", "otherwise",
          "new(", "behaviour", "update", "memory", "switch", "end", "blocking", "output",
          "input", "to", "from", "c", "e.lwr", "E.lwr", "a2.c", "1.5", "-", "not", "\"",
          "/*", "//", "\n", "\x00", "é", "true", "skip", "send", "receive", "@ 0 Hz"]


@st.composite
def mutated(draw: st.DrawFn) -> tuple[Path, str]:
    path = draw(st.sampled_from(sorted(SPECS)))
    text = SPECS[path]
    for _ in range(draw(st.integers(1, 4))):
        op = draw(st.sampled_from(["delete", "insert", "duplicate", "swap"]))
        i = draw(st.integers(0, len(text)))
        j = min(len(text), i + draw(st.integers(0, 40)))
        if op == "delete":
            text = text[:i] + text[j:]
        elif op == "insert":
            text = text[:i] + draw(st.sampled_from(TOKENS)) + text[i:]
        elif op == "duplicate":
            text = text[:j] + text[i:j] + text[j:]
        else:
            k = draw(st.integers(0, len(text)))
            a, b = sorted((i, k))
            text = text[:a] + text[b:] + text[a:b]
    return path, text


@settings(max_examples=150, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(mutated())
def test_mutations_never_crash(case: tuple[Path, str]) -> None:
    path, text = case
    comp = compile_file(path, overrides={path.resolve(): text})
    for d in comp.diagnostics:
        assert d.code in BY_CODE
        assert d.span.line >= 0 and d.message
    if comp.hpn is not None:
        assert violations(comp.hpn) == []
        net = flatten(comp.hpn)
        assert all(0 <= p < len(net.places) for t in net.transitions for p in t.pre + t.post)
