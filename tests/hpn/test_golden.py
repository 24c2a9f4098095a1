"""Golden files: the canonical IR dump of every example, and every file `rssmc compile`
writes for the LWR4+ example. Update with `pytest --update-goldens` (refused in CI)."""

from __future__ import annotations

from pathlib import Path

import pytest

from rssm_dsl.emit import EMITTERS
from rssm_dsl.emit.dump import dump_text
from rssm_dsl.pipeline import compile_file
from tests.conftest import ROOT, example_specs

GOLDEN = ROOT / "tests" / "golden"


def check_golden(path: Path, actual: str, update: bool) -> None:
    if update:
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text(actual, encoding="utf-8")
        return
    assert path.exists(), f"missing golden {path}; run pytest --update-goldens"
    expected = path.read_text(encoding="utf-8")
    assert actual == expected, f"{path} differs; review and run pytest --update-goldens"


@pytest.mark.parametrize("spec", example_specs(), ids=lambda p: p.stem)
def test_dump_golden(spec: Path, update_goldens: bool, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.chdir(ROOT)
    comp = compile_file(spec.relative_to(ROOT))
    assert comp.hpn is not None
    rel = spec.relative_to(ROOT / "examples").with_suffix(".hpn.txt")
    check_golden(GOLDEN / "dump" / rel, dump_text(comp.hpn), update_goldens)


def test_compile_outputs_golden(update_goldens: bool, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.chdir(ROOT)
    comp = compile_file(Path("examples/lwr4_circle.rssm"))
    assert comp.hpn is not None
    for emitter in EMITTERS.values():
        for rel, text in emitter(comp.hpn).items():
            check_golden(GOLDEN / "lwr4_circle" / rel, text, update_goldens)
