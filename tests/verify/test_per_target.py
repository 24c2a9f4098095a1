"""A partial function's targets are computed one at a time for the verifier
(rssm_dsl/verify/dataplan.py, ``per_target``): a statement that needs an untracked value
(`x := x + 0.5`, x a float) leaves its own target unknown, not the finite one beside it in
the same `update memory`. Each target's statements, run alone, give what the whole body
gives it (a later statement sees what an earlier one assigned, a `let` is visible after
it): pinned here on random straight-line bodies, run by the interpreter's compiled code."""

from __future__ import annotations

import json
import random
import subprocess
import sys
from pathlib import Path
from typing import Any

import pytest

from rssm_dsl.interp.initial import InitialValues
from rssm_dsl.pipeline import compile_file
from rssm_dsl.verify.dataplan import _Sub, per_target

ROOT = Path(__file__).resolve().parents[2]
VARS = ("a", "b", "c", "d")


def _random_body(rng: random.Random) -> str:
    lines: list[str] = []
    lets: list[str] = []
    for i in range(rng.randint(2, 7)):
        operand = [*VARS, *lets, str(rng.randint(0, 3))]
        value = f"{rng.choice(operand)} {rng.choice('+-*')} {rng.choice(operand)}"
        if rng.random() < 0.25:
            name = f"l{i}"
            lines.append(f"let {name} = {value}")
            lets.append(name)
        else:
            lines.append(f"{rng.choice(VARS)} := {value}")
    if not any(":=" in x for x in lines):
        lines.append("a := b + 1")
    return "\n          ".join(lines)


def _spec(body: str) -> str:
    decls = "\n".join(f"      memory {v}: int = 0" for v in VARS)
    return f"""system s {{
  agent x {{
    control @ 10 Hz {{
{decls}
      behaviour run {{
        update memory {{
          {body}
        }}
        terminal never when false
      }}
      initial run
    }}
  }}
}}
"""


@pytest.mark.parametrize("seed", range(6))
def test_each_target_alone_gives_what_the_whole_body_gives(tmp_path: Path, seed: int) -> None:
    rng = random.Random(seed)
    checked = 0
    for k in range(40):
        spec = tmp_path / f"b{k}.rssm"
        spec.write_text(_spec(_random_body(rng)))
        comp = compile_file(spec)
        assert comp.ok and comp.system is not None, [str(d) for d in comp.diagnostics]
        sub = next(iter(comp.system.subsystems()))
        s = _Sub(sub, InitialValues(comp.system), comp.system)
        (case,) = [c for pf in sub.behaviour("run").functions for c in pf.cases]
        full, _ = s.compiler.case(case.body)
        parts = per_target(case.body)
        if parts is None:
            continue
        assert sorted(r for _, r in parts) == sorted({r for _, r in parts})   # once each
        for _ in range(5):
            env: dict[str, Any] = {v: rng.randint(-5, 5) for v in VARS}
            whole: dict[str, Any] = {}
            full(dict(env), whole)
            for body, root in parts:
                alone: dict[str, Any] = {}
                s.compiler.case(body)[0](dict(env), alone)
                assert alone[root] == whole[root], (root, body, env)
        checked += 1
    assert checked >= 10


def test_a_float_beside_a_range_leaves_the_range_tracked(tmp_path: Path) -> None:
    spec = tmp_path / "floaty.rssm"
    spec.write_text("""system floaty {
  agent a {
    control @ 10 Hz {
      memory x: float = 0.0
      memory n: 0..3 = 0
      behaviour run {
        update memory {
          x := x + 0.5
          n := if n < 3 then n + 1 else 0
        }
        terminal never when false
      }
      initial run
    }
  }
  property bounded: always a.c.n <= 3
}
""")
    run = subprocess.run([sys.executable, "-m", "rssm_dsl", "verify", str(spec), "--format",
                          "json"], capture_output=True, text=True, cwd=ROOT, timeout=300)
    (prop,) = json.loads(run.stdout)["user_properties"]
    assert prop["holds"] is True, prop
