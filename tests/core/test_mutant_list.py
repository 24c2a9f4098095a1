"""bench/mutants.py applies each named mutant by replacing a text that must occur exactly once
in the tree; this keeps the list in step with the code (the mutation run itself, which takes
minutes, is `python bench/mutants.py`)."""

from __future__ import annotations

import importlib.util
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]


def _mutants() -> list:  # type: ignore[type-arg]
    spec = importlib.util.spec_from_file_location("bench_mutants", ROOT / "bench" / "mutants.py")
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = module
    spec.loader.exec_module(module)
    return list(module.ALL)


@pytest.mark.parametrize("mutant", _mutants(), ids=lambda m: m.name)
def test_each_mutant_applies_to_exactly_one_place(mutant: object, tmp_path: Path) -> None:
    text = (ROOT / mutant.path).read_text(encoding="utf-8")  # type: ignore[attr-defined]
    assert text.count(mutant.old) == 1  # type: ignore[attr-defined]
    assert mutant.new != mutant.old  # type: ignore[attr-defined]
