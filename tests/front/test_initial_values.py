"""Initial values and constants are computed before the run, by every backend alike
(rssm_dsl/interp/initial.py), without calling Python: an external operation called there is
E215 at its call (it used to pass the check and crash `rssmc simulate` with E900)."""

from __future__ import annotations

from pathlib import Path

import pytest

from rssm_dsl.pipeline import compile_file

SYSTEM = """extern two() -> float = "math:tau"
{const}
system s {{
  agent a {{
    control c @ 10 Hz {{
      {param}
      memory m: float = {memory}
      behaviour b {{
        update memory {{ m := m + {update} }}
        terminal done when m > 10.0
      }}
      initial b
      switch b -> b when done
    }}
  }}
}}
"""


@pytest.mark.parametrize(("where", "parts", "line"), [
    ("param", {"param": "param k: float = two()"}, 6),
    ("memory", {"memory": "two()"}, 7),
    ("const", {"const": "const K: float = 1.0 + two()"}, 2),
])
def test_a_call_in_an_initial_value_is_e215(where: str, parts: dict[str, str], line: int,
                                            tmp_path: Path) -> None:
    text = SYSTEM.format(**{"const": "", "param": "", "memory": "0.0", "update": "1.0",
                            **parts})
    path = tmp_path / f"{where}.rssm"
    path.write_text(text, encoding="utf-8")
    comp = compile_file(path)
    found = [(d.code, d.span.line) for d in comp.diagnostics if d.severity.value == "error"]
    assert found == [("E215", line)], comp.diagnostics


def test_a_call_in_an_update_is_fine(tmp_path: Path) -> None:
    path = tmp_path / "ok.rssm"
    path.write_text(SYSTEM.format(const="", param="", memory="0.0", update="two()"),
                    encoding="utf-8")
    comp = compile_file(path)
    assert comp.ok, comp.diagnostics
