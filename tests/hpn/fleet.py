"""A coordinator and N robots: the coordinator's control subsystem has one input per robot
(robot k's control subsystem sends ``s<k>`` to it, non-blocking). Used by
tests/hpn/test_many_inputs.py and bench/cases.py.

``cases``: the coordinator's `update memory` has case clauses over new(s1) and new(s2) only
(2 split inputs whatever N); otherwise it has none (one case)."""

from __future__ import annotations


def fleet(n: int, cases: bool = False) -> str:
    inputs = "\n".join(f"      input s{k}: int from r{k}.c nonblocking" for k in range(1, n + 1))
    total = " + ".join(f"s{k}" for k in range(1, n + 1))
    if cases:
        update = (f"        update memory {{\n"
                  f"          case new(s1) and new(s2):\n            total := {total}\n"
                  f"          case new(s1) and not new(s2):\n            total := s1\n"
                  f"          otherwise:\n            skip\n        }}")
    else:
        update = f"        update memory {{ total := {total} }}"
    robots = "\n".join(f"""  agent r{k} {{
    control c @ 10 Hz {{
      output s{k}: int to coord.c nonblocking
      behaviour go {{
        update s{k} {{ s{k} := {k} }}
        terminal never when false
        send s{k}
      }}
      initial go
    }}
  }}""" for k in range(1, n + 1))
    return f"""system fleet {{
  agent coord {{
    control c @ 10 Hz {{
      memory total: int = 0
{inputs}
      behaviour run {{
{update}
        terminal overflow when total < 0
      }}
      initial run
      switch run -> end when overflow
    }}
  }}
{robots}
}}
"""
