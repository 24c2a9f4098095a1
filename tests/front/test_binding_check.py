"""`rssmc check` finds the Python side of a specification without running it
(rssm_dsl/semantics/checks/bindings.py): a missing function or class is E216, a function that
cannot take the extern's arguments E217, a module not found here only W218 (it may be
installed where the system runs). Modules are looked up where the run looks for them: next
to the file that declares the binding, then next to the root specification, then on
sys.path; namespace packages included. (The modules here are named bc_...: a module is
imported once per process, and other tests have their own `ops`.)"""

from __future__ import annotations

from pathlib import Path

import pytest

from rssm_dsl.interp import RunConfig, SimOptions, Simulator, build_runtime
from rssm_dsl.pipeline import Compilation, compile_file

SYSTEM = """{imports}
{externs}
system s {{
  agent a {{
    control c @ 10 Hz {{
      memory x: float = 1.0
      behaviour b {{
        update memory {{ x := {call} }}
        terminal done when x > 100.0
      }}
      initial b
      switch b -> b when done
    }}
  }}
}}
"""


def spec(tmp_path: Path, externs: str, call: str, imports: str = "",
         files: dict[str, str] | None = None) -> Compilation:
    for name, text in (files or {}).items():
        path = tmp_path / name
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text(text, encoding="utf-8")
    root = tmp_path / "root.rssm"
    root.write_text(SYSTEM.format(imports=imports, externs=externs, call=call), encoding="utf-8")
    return compile_file(root)


def found(comp: Compilation) -> list[tuple[str, int]]:
    return [(d.code, d.span.line) for d in comp.diagnostics]


OPS = "def twice(x):\n    return 2.0 * x\n\ndef add(x, y=1.0):\n    return x + y\n"


@pytest.mark.parametrize(("extern", "call", "want"), [
    ('extern f(x: float) -> float = "bc_ops:twice"', "f(x)", []),
    ('extern f(x: float) -> float = "bc_ops:add"', "f(x)", []),            # y has a default
    ('extern f(x: float, y: float) -> float = "bc_ops:add"', "f(x, x)", []),
    ('extern f(x: float, y: float) -> float = "bc_ops:twice"', "f(x, x)", [("E217", 2)]),
    ('extern f(x: float) -> float = "bc_ops:thrice"', "f(x)", [("E216", 2)]),
    ('extern f(x: float) -> float = "nowhere_xyz:f"', "f(x)", [("W218", 2)]),
    ('extern f(x: float) -> float = "bc_ops.sub:f"', "f(x)", [("E216", 2)]),   # ops is a module
])
def test_externs_are_found_as_the_run_finds_them(extern: str, call: str,
                                                 want: list[tuple[str, int]],
                                                 tmp_path: Path) -> None:
    comp = spec(tmp_path, extern, call, files={"bc_ops.py": OPS})
    assert found(comp) == want, comp.diagnostics


def test_what_check_reports_is_what_the_run_reports(tmp_path: Path) -> None:
    """The same extern that check passes runs; the one it rejects (E217) the run rejects
    (E804) with the same reason."""
    good = spec(tmp_path, 'extern f(x: float) -> float = "bc_ops:twice"', "f(x)",
                files={"bc_ops.py": OPS})
    assert good.ok and not good.diagnostics
    rt = build_runtime(good, RunConfig(base_dir=tmp_path))
    assert Simulator(rt, SimOptions(until=1.0)).run().ok
    bad = spec(tmp_path, 'extern f(x: float, y: float) -> float = "bc_ops:twice"', "f(x, x)",
               files={"bc_ops.py": OPS})
    (d,) = bad.diagnostics
    assert d.code == "E217" and "too many positional arguments" in d.message


def test_check_runs_none_of_the_user_s_code(tmp_path: Path) -> None:
    touched = tmp_path / "touched"
    comp = spec(tmp_path, 'extern f(x: float) -> float = "bc_sideeffect:twice"', "f(x)",
                files={"bc_sideeffect.py": f"open({str(touched)!r}, 'w').close()\n" + OPS})
    assert comp.ok and not comp.diagnostics
    assert not touched.exists()


def test_names_made_at_import_time_are_not_judged(tmp_path: Path) -> None:
    files = {"bc_star.py": "from math import *\n", "bc_dyn.py": "import math\nf = math.sqrt\n"}
    for binding in ("bc_star:sqrt", "bc_dyn:f", "math:sqrt", "bc_dyn:math"):
        comp = spec(tmp_path, f'extern f(x: float) -> float = "{binding}"', "f(x)", files=files)
        assert not comp.diagnostics, (binding, comp.diagnostics)


def test_a_library_s_externs_are_looked_up_next_to_the_library(tmp_path: Path) -> None:
    lib = ('extern lib_twice(x: float) -> float = "bc_libops:twice"\n')
    files = {"lib/tools.rssm": lib, "lib/bc_libops.py": OPS}
    comp = spec(tmp_path, "", "lib_twice(x)", imports='import "lib/tools.rssm"', files=files)
    assert comp.ok and not comp.diagnostics, comp.diagnostics
    rt = build_runtime(comp, RunConfig(base_dir=tmp_path))
    result = Simulator(rt, SimOptions(until=1.0)).run()
    assert result.ok, result.message
    # a missing function of the library's module is reported in the library, where it is bound
    files["lib/bc_libops.py"] = "def other(x):\n    return x\n"
    comp = spec(tmp_path, "", "lib_twice(x)", imports='import "lib/tools.rssm"', files=files)
    (d,) = comp.diagnostics
    assert (d.code, Path(d.span.file).name, d.span.line) == ("E216", "tools.rssm", 1)


def test_namespace_packages(tmp_path: Path) -> None:
    files = {"bc_robotns/arm/kinematics.py": OPS}          # no __init__.py anywhere
    comp = spec(tmp_path, 'extern f(x: float) -> float = "bc_robotns.arm.kinematics:twice"',
                "f(x)", files=files)
    assert comp.ok and not comp.diagnostics, comp.diagnostics
    rt = build_runtime(comp, RunConfig(base_dir=tmp_path))
    assert Simulator(rt, SimOptions(until=1.0)).run().ok
    comp = spec(tmp_path, 'extern f(x: float) -> float = "bc_robotns.arm.dynamics:twice"',
                "f(x)", files=files)
    assert found(comp) == [("W218", 2)]


DEVICE = """device effector Valve @ 10 Hz {{
  input open: bool nonblocking
  binding "{binding}"
}}
system s {{
  agent a {{
    control c @ 10 Hz {{
      output open: bool to e.v nonblocking = false
      behaviour b {{
        update open {{ open := true }}
        terminal never when false
      }}
      initial b
    }}
    effector v @ 10 Hz {{
      input open: bool from c nonblocking
      output cmd: bool to E.v nonblocking
      behaviour b {{
        update cmd {{ cmd := open }}
        terminal never when false
      }}
      initial b
    }}
    real effector v: Valve
  }}
}}
"""


@pytest.mark.parametrize(("binding", "want"), [
    ("bc_valves:Valve", []),
    ("bc_valves:Gate", [("E216", 3)]),
    ("bc_valves:make_valve", [("E216", 3)]),          # a function, not a class
    ("rssm_stdlib.devices.constant:ConstantDevice", []),
    ("rssm_stdlib.devices.constant:Nothing", [("E216", 3)]),
])
def test_device_bindings(binding: str, want: list[tuple[str, int]], tmp_path: Path) -> None:
    (tmp_path / "bc_valves.py").write_text("class Valve:\n    pass\n\ndef make_valve():\n"
                                        "    return Valve()\n", encoding="utf-8")
    root = tmp_path / "valve.rssm"
    root.write_text(DEVICE.format(binding=binding), encoding="utf-8")
    assert found(compile_file(root)) == want


def test_a_module_name_too_long_for_the_file_system_is_not_found(tmp_path: Path) -> None:
    long = "m" * 300
    comp = spec(tmp_path, f'extern f(x: float) -> float = "{long}.{long}:f"', "f(x)")
    assert found(comp) == [("W218", 2)]
