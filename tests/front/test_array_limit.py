"""A value holds at most MAX_VALUES numbers (E206 beyond): `memory w: int[1000000000000]`
passed the check and exhausted memory when simulated."""

from __future__ import annotations

from pathlib import Path

import pytest

from rssm_dsl.pipeline import compile_file
from rssm_dsl.semantics.declarations import MAX_VALUES

SPEC = """{decls}
system s {{
  agent a {{
    control c @ 10 Hz {{
      memory w: {type}
      behaviour b {{
        update memory {{ w := w }}
        terminal never when false
      }}
      initial b
    }}
  }}
}}
"""


@pytest.mark.parametrize(("decls", "type", "ok"), [
    ("", "int[1000000000000]", False),
    ("", f"float[{MAX_VALUES}]", True),
    ("", f"float[{MAX_VALUES + 1}]", False),
    ("", "float[480][640][3]", True),                        # an RGB image
    ("", f"float[{MAX_VALUES // 2 + 1}][2]", False),        # nested arrays multiply
    ("record P { x: float, y: float, z: float }", f"P[{MAX_VALUES // 3}]", True),
    ("record P { x: float, y: float, z: float }", f"P[{MAX_VALUES // 3 + 1}]", False),
])
def test_a_value_holds_at_most_max_values_numbers(decls: str, type: str, ok: bool,
                                                  tmp_path: Path) -> None:
    path = tmp_path / "big.rssm"
    path.write_text(SPEC.format(decls=decls, type=type), encoding="utf-8")
    comp = compile_file(path, build=False)
    errors = [(d.code, d.span.line) for d in comp.diagnostics if d.is_error]
    assert errors == ([] if ok else [("E206", 5)]), comp.diagnostics
