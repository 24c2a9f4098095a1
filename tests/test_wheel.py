"""The built wheel ships grammar/ and stdlib/ and works in a clean virtual environment."""

from __future__ import annotations

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
