"""The built wheel ships grammar/ and stdlib/ and works in a clean virtual environment with
the core install alone (no extras): check, compile, verify and fmt work, the environment stays
small, and `rssmc run` names the extra it needs in one line."""

from __future__ import annotations

import re
import shutil
import subprocess
import sys
import venv
import zipfile
from pathlib import Path

import pytest

from tests.conftest import EXAMPLES, ROOT


@pytest.mark.slow
def test_wheel_installs_and_compiles_in_a_clean_venv(tmp_path: Path) -> None:
    dist = tmp_path / "dist"
    subprocess.run([sys.executable, "-m", "pip", "wheel", "--no-deps", "-q", "-w", str(dist),
                    str(ROOT)], check=True, timeout=600)
    wheel = next(dist.glob("rssmc-*.whl"))
    names = zipfile.ZipFile(wheel).namelist()
    assert "rssm_dsl/_data/grammar/rssm.lark" in names
    assert "rssm_dsl/_data/stdlib/std/types.rssm" in names
    assert "rssm_dsl/_data/stdlib/lwr4plus/lwr4plus.xml" in names
    assert "rssm_dsl/emit/schema/hpn-ir.schema.json" in names

    env = tmp_path / "venv"
    venv.create(env, with_pip=True)
    py = env / "bin" / "python"
    subprocess.run([str(py), "-m", "pip", "install", "-q", str(wheel)], check=True, timeout=900)
    work = tmp_path / "work"
    work.mkdir()
    shutil.copy(EXAMPLES / "lwr4_circle.rssm", work)  # away from the checkout's stdlib/
    r = subprocess.run([str(env / "bin" / "rssmc"), "compile", "lwr4_circle.rssm", "-o", "out"],
                       cwd=work, capture_output=True, text=True, timeout=300)
    assert r.returncode == 0, r.stderr
    assert (work / "out" / "lwr4_circle.hpn.json").exists()
    # spans of stdlib declarations name the stdlib, not a path inside site-packages
    dump = (work / "out" / "lwr4_circle.hpn.txt").read_text()
    assert "site-packages" not in dump
    # the core install: no physics, no plots
    site = next((env / "lib").glob("python3*/site-packages"))
    size = sum(f.stat().st_size for f in env.rglob("*") if f.is_file())
    print(f"core venv: {size / 1e6:.0f} MB")
    quoted = re.search(r"a (\d+) MB venv", (ROOT / "README.md").read_text(encoding="utf-8"))
    assert quoted is not None
    assert abs(size / 1e6 - int(quoted[1])) <= 0.05 * int(quoted[1]), (
        f"README.md says the core venv is {quoted[1]} MB; it is {size / 1e6:.0f} MB")
    # typer-slim: typer on click alone, without rich and pydantic (23 MB, 100 ms a start)
    for heavy in ("mujoco", "pinocchio", "matplotlib", "networkx", "pydantic", "rich"):
        assert not (site / heavy).exists(), heavy
    rssmc = str(env / "bin" / "rssmc")

    def cli(*args: str) -> subprocess.CompletedProcess[str]:
        return subprocess.run([rssmc, *args], cwd=work, capture_output=True, text=True,
                              timeout=300)

    assert cli("--version").stdout.startswith("rssmc ")
    assert cli("check", "lwr4_circle.rssm").returncode == 0
    shutil.copy(EXAMPLES / "verify" / "handover.rssm", work)
    v = cli("verify", "handover.rssm")
    assert v.returncode == 0 and "VERIFIED" in v.stdout, v.stdout + v.stderr
    assert cli("fmt", "handover.rssm").returncode == 0
    assert cli("fmt", "--check", "handover.rssm").returncode == 0
    assert cli("check", "handover.rssm").returncode == 0
    r = cli("run", "lwr4_circle.rssm", "--until", "0.1")
    assert r.returncode == 2
    lines = r.stderr.strip().splitlines()
    assert len(lines) == 1 and "pip install 'rssmc[run]'" in lines[0], r.stderr
    assert not (work / "out" / "lwr4_circle-run").exists()    # nothing half-written

