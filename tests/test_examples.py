"""Every example compiles with zero diagnostics and gives a well-formed HPN."""

from __future__ import annotations

from pathlib import Path

import pytest

from rssm_dsl.diagnostics.render import render_text
from rssm_dsl.hpn.flatten import flatten
from rssm_dsl.hpn.wellformed import violations
from rssm_dsl.pipeline import compile_file
from tests.conftest import ROOT, example_specs

SPECS = example_specs()


def test_there_are_examples() -> None:
    assert (ROOT / "examples" / "lwr4_circle.rssm") in SPECS


@pytest.mark.parametrize("spec", SPECS, ids=lambda p: str(p.relative_to(ROOT)))
def test_example_compiles_clean(spec: Path) -> None:
    comp = compile_file(spec)
    assert not comp.diagnostics, render_text(comp.diagnostics, comp.program.line)
    assert comp.hpn is not None
    assert violations(comp.hpn) == []
    net = flatten(comp.hpn)
    assert net.initial and net.final
    # every flat transition is connected and every IR place ends up in one flat place
    assert all(t.pre and t.post for t in net.transitions)
    assert sum(len(p.origin) for p in net.places) == len(comp.hpn.places)
