"""Hostile Python bindings at check time: a module named like a path (E208 where the binding
is written, in `rssmc check` and in the language server alike), a module too deep or too large
to read (W228, within seconds and a bounded memory), never an internal error."""

from __future__ import annotations

import subprocess
import sys
import textwrap
import time
from pathlib import Path

import pytest

from rssm_dsl.bindings import BindingError, find_module, import_module, split_binding
from rssm_dsl.pipeline import compile_file
from tests.conftest import ROOT

SPEC = textwrap.dedent("""\
    extern f(x: float) -> float = "{binding}"

    device receptor Probe @ 10 Hz {{
      output level: float nonblocking
      binding "{device}"
    }}

    system s {{
      agent a {{
        control @ 10 Hz {{
          memory m: float = 0.0

          behaviour run {{
            update memory {{ m := f(m) }}
            terminal done when m > 1000.0
          }}
          initial run
          switch run -> end when done
        }}
      }}
    }}
    """)
GOOD_DEVICE = "rssm_stdlib.devices.constant:ConstantDevice"


def rssmc(*args: str | Path, cwd: Path = ROOT,
          ) -> tuple[subprocess.CompletedProcess[str], float, int]:
    """The command's result, its wall time and its peak resident size in MB."""
    wrapper = textwrap.dedent(f"""
        import resource, subprocess, sys
        r = subprocess.run({[sys.executable, "-m", "rssm_dsl", *map(str, args)]!r},
                           capture_output=True, text=True, timeout=120)
        sys.stdout.write(r.stdout)
        sys.stderr.write(r.stderr)
        sys.stderr.write("\\nMAXRSS %d\\n" % resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss)
        sys.exit(r.returncode)
    """)
    t = time.monotonic()
    r = subprocess.run([sys.executable, "-c", wrapper], cwd=cwd, capture_output=True,
                       text=True, timeout=180)
    wall = time.monotonic() - t
    err, _, rss = r.stderr.rpartition("\nMAXRSS ")
    r.stderr = err
    return r, wall, int(rss.strip()) // 1024


def write_spec(folder: Path, binding: str, device: str = GOOD_DEVICE) -> Path:
    spec = folder / "spec.rssm"
    spec.write_text(SPEC.format(binding=binding, device=device), encoding="utf-8")
    return spec


# ------------------------------------------------------------------ a module named like a path

@pytest.mark.parametrize("name", ["../outside/evil2", "/etc/passwd", "a/b", "a..b", ".a",
                                  "a.", "pkg.mod-x", "C:\\\\x", "a.*"])
def test_a_module_that_is_not_a_dotted_name_is_refused(name: str, tmp_path: Path) -> None:
    with pytest.raises(BindingError):
        split_binding(f"{name}:f")
    with pytest.raises(BindingError):
        find_module(name, [tmp_path])
    with pytest.raises(BindingError):
        import_module(name, [tmp_path])


@pytest.mark.parametrize("where", ["extern", "device"])
def test_a_binding_holding_a_path_is_e208_at_the_binding(where: str, tmp_path: Path) -> None:
    evil = "../outside/evil2:f"
    (tmp_path / "outside").mkdir()
    (tmp_path / "outside" / "evil2.py").write_text("def f(x):\n    return x\n")
    work = tmp_path / "work"
    work.mkdir()
    spec = (write_spec(work, evil) if where == "extern"
            else write_spec(work, "math:sqrt", device=evil))
    line = 1 if where == "extern" else 5
    comp = compile_file(spec)
    assert [(d.code, d.span.line) for d in comp.diagnostics if d.code == "E208"] == [
        ("E208", line)]
    r, _, _ = rssmc("check", spec)
    assert r.returncode == 1, r.stderr
    assert f"spec.rssm:{line}:" in r.stderr and "error[E208]" in r.stderr
    assert "Traceback" not in r.stderr and "E900" not in r.stderr


def test_the_language_server_reports_e208_without_a_traceback(tmp_path: Path) -> None:
    from rssm_dsl.lsp.analysis import analyze_text
    from rssm_dsl.semantics.loader import display_path

    spec = write_spec(tmp_path, "../outside/evil2:f", device="../x/y:Z")
    text = spec.read_text(encoding="utf-8")
    got = analyze_text(spec.as_uri(), spec, display_path(spec), text, 1, {}, None)
    assert sorted((d.code, d.span.line) for d in got.diagnostics) == [("E208", 1),
                                                                      ("E208", 5)]


# ------------------------------------------------------------------ a module too deep or too large

def test_a_200000_term_sum_is_w228_within_5_s_and_500_mb(tmp_path: Path) -> None:
    (tmp_path / "deep.py").write_text("x = " + "+".join(["1"] * 200_000)
                                      + "\n\ndef f(a):\n    return a\n")
    spec = write_spec(tmp_path, "deep:f")
    r, wall, rss = rssmc("check", spec)
    assert r.returncode == 0, r.stderr
    assert "spec.rssm:1:" in r.stderr and "warning[W228]" in r.stderr, r.stderr
    assert "Traceback" not in r.stderr and "E900" not in r.stderr
    assert wall < 5.0 + 2.0, wall          # the interpreter's start beside the 5 s
    assert rss < 500, rss


@pytest.mark.parametrize(("source", "why"), [
    ("x = " + "+".join(["1"] * 100_000), "too deeply nested"),        # under the token cap
    ("x = " + "-" * 200_000 + "1", "too"),                             # the parser's stack
    ("x = [" + ",".join(["1"] * 140_000) + "]", "tokens"),            # flat but large
])
def test_modules_the_checker_does_not_read_are_w228(source: str, why: str,
                                                     tmp_path: Path) -> None:
    (tmp_path / "deep.py").write_text(source + "\n\ndef f(a):\n    return a\n")
    comp = compile_file(write_spec(tmp_path, "deep:f"))
    found = [d for d in comp.diagnostics if d.code == "W228"]
    assert len(found) == 1 and why in found[0].message and found[0].span.line == 1
    assert comp.ok


def test_a_module_over_4_mb_is_w228_without_being_read(tmp_path: Path) -> None:
    with (tmp_path / "big.py").open("w") as f:
        f.write("def f(a):\n    return a\n")
        f.write("# " + "x" * (5 << 20) + "\n")
    t = time.monotonic()
    comp = compile_file(write_spec(tmp_path, "big:f"))
    assert time.monotonic() - t < 5.0
    found = [d for d in comp.diagnostics if d.code == "W228"]
    assert len(found) == 1 and "too large" in found[0].message


def test_simulate_says_the_module_cannot_be_imported(tmp_path: Path) -> None:
    (tmp_path / "deep.py").write_text("x = " + "+".join(["1"] * 100_000)
                                      + "\n\ndef f(a):\n    return a\n")
    spec = write_spec(tmp_path, "deep:f")
    r, _, _ = rssmc("simulate", spec, "--steps", "5", "--no-live")
    assert r.returncode == 1, r.stderr
    assert "error[E801]" in r.stderr and "Traceback" not in r.stderr and "E900" not in r.stderr
