"""Which behaviour runs next: the switch rule (the first `when` switch that holds, in
declaration order, `otherwise` last), evaluated once the behaviour has ended, with the
terminal and error conditions of its last iteration. Pinned on the interpreter for many
seeds (its choice among enabled transitions is seeded) and on the generated ROS 2 switch
function."""

from __future__ import annotations

from pathlib import Path

import pytest

from rssm_dsl.interp.initial import InitialValues
from rssm_dsl.pycode import var
from tests.interp.conftest import compile_text, run
from tests.ros2.test_pycode import generated_module

SPEC = """
system t {{
  agent a1 {{
    control c @ 100 Hz {{
      memory n: int = 0
      memory went: int = 0
      behaviour start {{
        update memory {{ n := n + 1 }}
        terminal {terminal}
      }}
      behaviour first {{
        update memory {{ went := 1 }}
        terminal never when false
      }}
      behaviour second {{
        update memory {{ went := 2 }}
        terminal never when false
      }}
      behaviour third {{
        update memory {{ went := 3 }}
        terminal never when false
      }}
      initial start
{switches}
    }}
  }}
}}
"""

# (terminal condition of `start`, switches leaving it, the behaviour that must follow)
CASES = [
    ("done when n >= 2",
     "switch start -> first when n >= 2\nswitch start -> second when n >= 1\n"
     "switch start -> third otherwise", "first"),
    ("done when n >= 2",
     "switch start -> second when n >= 5\nswitch start -> first when n >= 1\n"
     "switch start -> third otherwise", "first"),
    ("done when n >= 2",
     "switch start -> second when n >= 5\nswitch start -> first otherwise\n"
     "switch start -> third when n >= 9", "first"),
    # the switch sees the terminal condition that ended the behaviour (constant or not)
    ("done when true",
     "switch start -> first when done\nswitch start -> second otherwise", "first"),
    ("done when n >= 3",
     "switch start -> second when n < 3\nswitch start -> first when done", "first"),
]
WENT = {"first": 1, "second": 2, "third": 3}


def _spec(tmp_path: Path, terminal: str, switches: str) -> Path:
    path = tmp_path / "switch.rssm"
    path.write_text(SPEC.format(terminal=terminal, switches="      " + switches.replace(
        "\n", "\n      ")), encoding="utf-8")
    return path


@pytest.mark.parametrize(("terminal", "switches", "want"), CASES)
@pytest.mark.parametrize("seed", range(6))
def test_interpreter_takes_the_first_switch_that_holds(tmp_path: Path, terminal: str,
                                                       switches: str, want: str,
                                                       seed: int) -> None:
    path = _spec(tmp_path, terminal, switches)
    comp = compile_text(tmp_path, path.read_text(), path.name)
    rt, result = run(comp, max_steps=400, seed=seed)
    assert result.reason != "error", result.diagnostics
    c = rt.subsystems["a1.c"]
    assert c.behaviour == want
    assert c.vars["went"] == WENT[want]


@pytest.mark.parametrize(("terminal", "switches", "want"), CASES)
def test_generated_node_takes_the_first_switch_that_holds(tmp_path: Path, terminal: str,
                                                          switches: str, want: str) -> None:
    path = _spec(tmp_path, terminal, switches)
    comp = compile_text(tmp_path, path.read_text(), path.name)
    assert comp.system is not None and comp.hpn is not None
    agent = comp.system.agents[0]
    sub = agent.subsystems[0]
    ns, _ = generated_module(comp.system, comp.hpn, sub, agent.name, agent.designator,
                             InitialValues(comp.system), tmp_path)
    st = ns["State"]()
    n_end = next(n for n in range(1, 10) if _ends(terminal, n))
    setattr(st, var("n"), n_end)
    setattr(st, var("went"), 0)
    start = next(b for b, beh in enumerate(sub.behaviours, start=1) if beh.name == "start")
    assert ns[f"switch_{start}"](st, {"done": True}) == want


def _ends(terminal: str, n: int) -> bool:
    cond = terminal.split(" when ", 1)[1]
    return cond == "true" or eval(cond, {"n": n})  # the test's own conditions, not user text
