"""The data-availability cases as the user wrote them (rssm_dsl/semantics/cases.py) mean what
the paper's full expansion means: for every combination of new(x) over ALL the inputs of the
subsystem, the interpreter runs the case of the clause that the paper's 2^nu cases would run
(the clause whose condition holds, else `otherwise`), whatever the inputs that no clause
reads."""

from __future__ import annotations

import random
from pathlib import Path

import pytest

from rssm_dsl.hpn.ir import PageKind
from rssm_dsl.interp.program import build_runtime
from rssm_dsl.pipeline import compile_file
from rssm_dsl.semantics.behaviours import eval_availability
from rssm_dsl.syntax import ast
from tests.conftest import EXAMPLES

SENDERS = ("a", "b", "c", "d")


def _names(inputs: int) -> tuple[str, ...]:
    return SENDERS[:inputs] if inputs <= len(SENDERS) else tuple(f"x{k}"
                                                                 for k in range(1, inputs + 1))


def _spec(body: str, inputs: int) -> str:
    names = _names(inputs)
    ins = "\n".join(f"      input {x}: int from p{x}.c nonblocking" for x in names)
    senders = "\n".join(f"""  agent p{x} {{
    control c @ 10 Hz {{
      output {x}: int to hub.c nonblocking
      behaviour go {{
        update {x} {{ {x} := 1 }}
        terminal never when false
      }}
      initial go
    }}
  }}""" for x in names)
    return f"""system cases {{
  agent hub {{
    control c @ 10 Hz {{
      memory m: int = 0
      output out: int to sink.c nonblocking
{ins}
      behaviour run {{
{body}
        terminal stop when m < 0
      }}
      initial run
      switch run -> end when stop
    }}
  }}
  agent sink {{
    control c @ 10 Hz {{
      memory seen: int = 0
      input out: int from hub.c nonblocking
      behaviour take {{
        update memory {{ seen := out }}
        terminal stop when seen < 0
      }}
      initial take
      switch take -> end when stop
    }}
  }}
{senders}
}}
"""


SPECS = {
    # one clause over one of three inputs; memory has no clause
    "one-of-three": (3, """        update out {
          case new(b):
            out := b
          otherwise:
            out := 0
        }
        update memory { m := m + a + b + c }"""),
    # clauses over b and d of four inputs, in both partial functions
    "two-of-four": (4, """        update out {
          case new(b) and not new(d):
            out := b
          case not new(b):
            out := d
          otherwise:
            skip
        }
        update memory {
          case new(d) or new(b):
            m := m + 1
          otherwise:
            m := m + a + c
        }"""),
    # a clause over every input: the paper's full expansion itself
    "all-of-two": (2, """        update out {
          case new(a) and new(b):
            out := a + b
          case (new(a) or new(b)) and not (new(a) and new(b)):
            out := 1
          otherwise:
            out := 0
        }
        update memory { m := m + 1 }"""),
}


def _expected(u: ast.UpdateDecl | None, inputs: tuple[str, ...], values: tuple[bool, ...]
              ) -> int | None:
    """The clause the paper's full expansion runs for new(x) = ``values``: the one whose
    condition holds (they are disjoint), else `otherwise` (None: no `update`, or a plain one
    with its one clause 0)."""
    if u is None:
        return None
    for i, case in enumerate(u.cases):
        if case.condition is not None and eval_availability(case.condition, inputs, values):
            return i
    return next(i for i, case in enumerate(u.cases) if case.condition is None)


# clauses over 20 of 22 inputs: more than FULL_SPLIT split inputs, so cubes, not 2^20 cases
BIG = 22
BIG_BODY = f"""        update out {{
          case {" and ".join(f"new(x{k})" for k in range(1, 21))}:
            out := x1
          case not new(x1) and new(x21):
            out := x21
          otherwise:
            out := 0
        }}
        update memory {{
          case new(x3) or new(x5):
            m := m + 1
          otherwise:
            skip
        }}"""


def big_masks(n: int, count: int) -> list[int]:
    """All new, none new, each input alone not new / alone new, and random masks."""
    rnd = random.Random(n)
    full = (1 << n) - 1
    return sorted({full, 0, *(full ^ 1 << k for k in range(n)), *(1 << k for k in range(n)),
                   *(rnd.getrandbits(n) for _ in range(count))})


def _check(path: Path, subsystem: str, masks: list[int] | None = None) -> int:
    comp = compile_file(path)
    assert comp.ok and comp.system is not None and comp.program is not None, \
        [d.message for d in comp.diagnostics]
    rt = build_runtime(comp)
    s = rt.subsystems[subsystem]
    inputs = tuple(b.name for b in s.model.inputs)
    decl = next(sd for sd in _subsystem_decls(comp.program) if sd.span == s.model.span)
    checked = 0
    if masks is None:
        masks = list(range(1 << len(inputs)))
    for page in comp.hpn.pages.values():  # type: ignore[union-attr]
        if page.kind is not PageKind.PARTIAL or page.owner != subsystem:
            continue
        p_in = rt.net.place_index[page.in_place]
        # the case transitions of the page, with their place (as the interpreter's CaseGroup
        # holds them when the cases are a table, else each with its guard)
        rows = [(t.index, t.post[0]) for t in rt.net.transitions if t.pre == (p_in,)]
        group = rt.case_groups.get(p_in)
        for mask in masks:
            values = tuple(bool(mask >> k & 1) for k in range(len(inputs)))
            s.new.mask = mask
            enabled = [place for t, place in rows
                       if rt.guards[t] is None or rt.guards[t]()]  # type: ignore[misc]
            # exactly one case is enabled, and the case group (if any) picks that one
            assert len(enabled) == 1, (page.id, values, enabled)
            place = enabled[0]
            if group is not None:
                assert group.table[group.select(mask)][1] == place
            op = comp.hpn.places[rt.net.places[place].name].operation  # type: ignore[union-attr]
            assert op is not None and op.behaviour is not None and op.case is not None
            beh = s.model.behaviour(op.behaviour)
            pf = next(f for f in beh.functions if f.target == op.target)
            case = next(c for c in pf.cases if c.index == op.case)
            bd = next(b for b in decl.behaviours if b.name == op.behaviour)
            u = next((x for x in bd.updates if x.target == op.target), None)
            want = _expected(u, inputs, values)
            got = case.source_case
            assert got == want or (want is None and got in (None, 0)), \
                (page.id, values, got, want)
            checked += 1
    return checked


def _subsystem_decls(program: object) -> list[ast.SubsystemDecl]:
    out: list[ast.SubsystemDecl] = []
    todo = [program]
    while todo:
        x = todo.pop()
        if isinstance(x, ast.SubsystemDecl):
            out.append(x)
        elif isinstance(x, tuple | list):
            todo += list(x)
        elif hasattr(x, "__dataclass_fields__"):
            todo += [getattr(x, f) for f in x.__dataclass_fields__]  # type: ignore[attr-defined]
    return out


@pytest.mark.parametrize("name", SPECS)
def test_the_case_run_is_the_full_expansions_for_every_new_combination(
        tmp_path: Path, name: str) -> None:
    inputs, body = SPECS[name]
    path = tmp_path / f"{name}.rssm"
    path.write_text(_spec(body, inputs), encoding="utf-8")
    # two partial functions (out, memory), each tried with every one of the 2^nu combinations
    assert _check(path, "hub.c") == 2 * 2 ** inputs


def test_clauses_over_twenty_inputs_give_the_cases_they_decide(tmp_path: Path) -> None:
    """Beyond FULL_SPLIT split inputs a function has one case per decided cube: the chain of
    a 20-literal conjunction gives 22 cases, not 2^20, and each new() combination still runs
    the full expansion's clause."""
    path = tmp_path / "big.rssm"
    path.write_text(_spec(BIG_BODY, BIG), encoding="utf-8")
    comp = compile_file(path)
    assert comp.ok and comp.system is not None
    hub = next(s for a in comp.system.agents for s in a.subsystems if a.name == "hub")
    out, memory = hub.behaviours[0].functions
    assert len(out.cases) == 22 and len(memory.cases) == 3
    masks = big_masks(BIG, 300)
    assert _check(path, "hub.c", masks) == 2 * len(masks)


def test_the_paper_example_too() -> None:
    assert _check(EXAMPLES / "lwr4_circle.rssm", "a1.e.lwr") == 2 * 2 ** 2


TWO_AT_ONCE = """system twice {
  agent hub {
    control c @ 10 Hz {
      input a: int from pa.c blocking
      input b: int from pb.c nonblocking
      memory both: int = 0
      memory only_a: int = 0
      memory only_b: int = 0
      memory none: int = 0
      memory sum: int = 0
      behaviour run {
        update memory {
          case new(a) and new(b):
            both := both + 1
            sum := sum + a + b
          case new(a) and not new(b):
            only_a := only_a + 1
          case new(b) and not new(a):
            only_b := only_b + 1
          otherwise:
            none := none + 1
        }
        terminal stop when both + only_a + only_b + none >= 6 and sum > 0
      }
      initial run
      switch run -> end when stop
    }
  }
  agent pa {
    control c @ 10 Hz {
      memory k: int = 0
      output a: int to hub.c nonblocking
      behaviour go {
        update a { a := k + 1 }
        update memory { k := k + 1 }
        terminal never when false
      }
      initial go
    }
  }
  agent pb {
    control c @ 10 Hz {
      output b: int to hub.c nonblocking
      behaviour once {
        update b { b := 100 }
        terminal sent when true
      }
      initial once
      switch once -> end when sent
    }
  }
}
"""


@pytest.mark.parametrize("seed", [0, 1, 2, 3])
def test_two_inputs_received_in_one_iteration_are_both_new(tmp_path: Path, seed: int) -> None:
    """b's producer sends one sample and ends; a's sends every iteration and the hub waits
    for it. The iteration after the receive that took b's one sample (and a's sample) sees
    new(a) and new(b) both true: exactly one `both` case, with b's value; every other
    iteration but the first sees new(a) alone (new(b) was used and is false again); the
    first sees nothing new."""
    from tests.semantics.interp_runner import simulate

    path = tmp_path / "twice.rssm"
    path.write_text(TWO_AT_ONCE)
    run = simulate(path, until=3.0, seed=seed)
    m = run.memory["hub.c"]
    assert (m["both"], m["only_a"], m["only_b"], m["none"]) == (1, 4, 0, 1), m
    assert m["sum"] > 100                     # b's value and a's fresh one were read
