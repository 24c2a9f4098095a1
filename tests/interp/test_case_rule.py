"""The data-availability cases as the user wrote them (rssm_dsl/semantics/cases.py) mean what
the paper's full expansion means: for every combination of new(x) over ALL the inputs of the
subsystem, the interpreter runs the case of the clause that the paper's 2^nu cases would run
(the clause whose condition holds, else `otherwise`), whatever the inputs that no clause
reads."""

from __future__ import annotations

import itertools
from pathlib import Path

import pytest

from rssm_dsl.hpn.ir import PageKind
from rssm_dsl.interp.program import build_runtime
from rssm_dsl.pipeline import compile_file
from rssm_dsl.semantics.behaviours import eval_availability
from rssm_dsl.syntax import ast
from tests.conftest import EXAMPLES

SENDERS = ("a", "b", "c", "d")


def _spec(body: str, inputs: int) -> str:
    names = SENDERS[:inputs]
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


def _check(path: Path, subsystem: str) -> int:
    comp = compile_file(path)
    assert comp.ok and comp.system is not None and comp.program is not None, \
        [d.message for d in comp.diagnostics]
    rt = build_runtime(comp)
    s = rt.subsystems[subsystem]
    inputs = tuple(b.name for b in s.model.inputs)
    decl = next(sd for sd in _subsystem_decls(comp.program) if sd.span == s.model.span)
    checked = 0
    for page in comp.hpn.pages.values():  # type: ignore[union-attr]
        if page.kind is not PageKind.PARTIAL or page.owner != subsystem:
            continue
        group = rt.case_groups[rt.net.place_index[page.in_place]]
        op_of = {row[1]: rt.net.places[row[1]].name for row in group.table}
        for values in itertools.product((True, False), repeat=len(inputs)):
            mask = sum(1 << k for k, v in enumerate(values) if v)
            s.new.mask = mask
            _, place, _, _ = group.table[group.select(mask)]
            op = comp.hpn.places[op_of[place]].operation  # type: ignore[union-attr]
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
            # the guards of the case transitions agree: exactly that case is enabled
            enabled = [row for row in group.table
                       if rt.guards[row[0]] is None or rt.guards[row[0]]()]  # type: ignore[misc]
            assert [row[1] for row in enabled] == [place], (page.id, values)
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


def test_the_paper_example_too() -> None:
    assert _check(EXAMPLES / "lwr4_circle.rssm", "a1.e.lwr") == 2 * 2 ** 2
