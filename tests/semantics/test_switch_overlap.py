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


def test_a_parameter_rules_an_overlap_out_per_instance(tmp_path: Path) -> None:
    """W604 with the parameters' values: `when reported and work_time == 1` overlaps the
    switch after it only in the instance whose work_time is 1, and the warning names it
    (the acceptance trial of issue 32 got "(and in 5 more instances of Robot)" for a
    parameter ruling the overlap out in those five)."""
    spec = tmp_path / "robots.rssm"
    spec.write_text("""agent Robot(work_time: 1..3 = 2, quick: bool = false) {
  control @ 10 Hz {
    memory worked: 0..3 = 0
    behaviour work {
      update memory { worked := worked + 1 }
      terminal finished when worked >= work_time
    }
    behaviour report {
      terminal reported when true
    }
    initial work
    switch work -> report when finished
    switch report -> end when reported and work_time == 1
    switch report -> work when reported and not quick
    switch report -> end when reported
  }
}
system s {
  agent r[1..4]: Robot()
  agent r5: Robot(work_time = 1)
  agent r6: Robot(quick = true)
}
""")
    comp = compile_file(spec)
    w604 = sorted((d.span.line, d.message) for d in comp.diagnostics if d.code == "W604")
    # line 14 (`not quick`) overlaps line 13 in r5 only; line 15 overlaps line 14 where
    # quick is false (r1-r5: r1's warning, and 4 more) and line 13 in r5
    assert [line for line, _ in w604] == [14, 15], w604
    assert "of r5.c overlap" in w604[0][1] and "more instance" not in w604[0][1], w604[0]
    assert "of r1.c overlap" in w604[1][1] and "(and in 4 more instances of Robot)" in \
        w604[1][1], w604[1]
