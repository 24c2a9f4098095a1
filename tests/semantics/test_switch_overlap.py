"""W604 (two switches from one behaviour may both fire) and E603 (none may) read comparisons
as the same atom whatever their form: `x > 0`, `0 < x` and `not (x <= 0)` are one atom, and
two terminal conditions whose comparisons are complementary never hold together."""

from __future__ import annotations

from pathlib import Path

import pytest

from rssm_dsl.pipeline import compile_file

SPEC = """system s {{
  agent a {{
    control c @ 10 Hz {{
      memory x: int = 0
      memory y: int = 0
      behaviour b {{
        update memory {{ x := x + 1 + y }}
{terminals}
      }}
      behaviour d {{
        update memory {{ x := x - 1 }}
        terminal never when false
      }}
      initial b
{switches}
    }}
  }}
}}
"""


def codes(tmp_path: Path, terminals: list[str], switches: list[str]) -> list[str]:
    path = tmp_path / "s.rssm"
    path.write_text(SPEC.format(terminals="\n".join(f"        {t}" for t in terminals),
                                switches="\n".join(f"      {s}" for s in switches)),
                    encoding="utf-8")
    return sorted(d.code for d in compile_file(path).diagnostics)


ONE_END = ["terminal done when y > 2"]


@pytest.mark.parametrize(("terminals", "switches", "want"), [
    # complementary terminal conditions: exactly one holds when b ends
    (["terminal pos when x > 0", "terminal nonpos when x <= 0"],
     ["switch b -> d when pos", "switch b -> b when nonpos"], []),
    (["terminal pos when x > 0", "terminal nonpos when 0 >= x"],
     ["switch b -> d when pos", "switch b -> b when nonpos"], []),
    (["terminal pos when 0 < x", "terminal nonpos when not (x > 0)"],
     ["switch b -> d when pos", "switch b -> b when nonpos"], []),
    # overlapping terminal conditions may both hold
    (["terminal pos when x > 0", "terminal big when x > 5"],
     ["switch b -> d when pos", "switch b -> b when big"], ["W604"]),
    # switch conditions over data, complementary in any operand order
    (ONE_END, ["switch b -> d when x > 3", "switch b -> b when x <= 3"], []),
    (ONE_END, ["switch b -> d when 3 < x", "switch b -> b when x <= 3"], []),
    (ONE_END, ["switch b -> d when x >= y", "switch b -> b when y > x"], []),
    (ONE_END, ["switch b -> d when x != 3", "switch b -> b when 3 == x"], []),
    # not complementary: x == 3 is neither; but never both (x < 3 implies x <= 3)
    (ONE_END, ["switch b -> d when x > 3", "switch b -> b when x < 3"], ["E603"]),
    (ONE_END, ["switch b -> d when x > 3", "switch b -> b when x < 3",
               "switch b -> b when x == 3"], []),
    (ONE_END, ["switch b -> d when x >= 3", "switch b -> b when x < 3"], []),
    (ONE_END, ["switch b -> d when x >= 3", "switch b -> b when x <= 3"], ["W604"]),
    (ONE_END, ["switch b -> d when x < 3", "switch b -> b when x == 3",
               "switch b -> b when 3 < x"], []),
    # the same comparison twice overlaps
    (ONE_END, ["switch b -> d when x > 3", "switch b -> b when 3 < x",
               "switch b -> b otherwise"], ["W604"]),
    # a switch repeating a condition's comparison is that condition
    (["terminal pos when x > 0", "terminal nonpos when x <= 0"],
     ["switch b -> d when 0 < x", "switch b -> b when nonpos"], []),
])
def test_switch_conditions_read_as_one_atom(terminals: list[str], switches: list[str],
                                            want: list[str], tmp_path: Path) -> None:
    assert codes(tmp_path, terminals, switches) == want
