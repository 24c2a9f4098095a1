"""`rssmc ros2` end to end (a subprocess, as a user runs it)."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

from tests.conftest import ROOT
from tests.ros2.conftest import SPECS


def rssmc(*args: str, cwd: Path = ROOT) -> subprocess.CompletedProcess[str]:
    return subprocess.run([sys.executable, "-m", "rssm_dsl", *args], cwd=cwd,
                          capture_output=True, text=True, timeout=120, check=False)


def test_writes_the_workspace(tmp_path: Path) -> None:
    out = tmp_path / "ws" / "src"
    done = rssmc("ros2", str(SPECS / "relay.rssm"), "-o", str(out), "--maintainer",
                 "Ada Lovelace <ada@example.org>", "--license", "BSD-3-Clause")
    assert done.returncode == 0, done.stderr
    written = sorted(p for p in out.rglob("*") if p.is_file())
    assert f"wrote {len(written)} files of 5 packages" in done.stderr
    # the semantics core is shipped unchanged: the nodes run the interpreter's code
    core = out / "relay_runtime" / "rssm_core"
    for src in (ROOT / "rssm_core").glob("*.py"):
        assert (core / src.name).read_bytes() == src.read_bytes()
    assert sorted(p.name for p in out.iterdir()) == [
        "README.md", "relay_bringup", "relay_dst", "relay_interfaces", "relay_runtime",
        "relay_src"]
    xml = (out / "relay_dst" / "package.xml").read_text()
    assert '<maintainer email="ada@example.org">Ada Lovelace</maintainer>' in xml
    assert "<license>BSD-3-Clause</license>" in xml


def test_errors_write_nothing(tmp_path: Path) -> None:
    spec = tmp_path / "bad.rssm"
    spec.write_text((SPECS / "relay.rssm").read_text().replace("agent dst", "agent runtime")
                    .replace("dst.c", "runtime.c"))
    out = tmp_path / "src"
    done = rssmc("ros2", str(spec), "-o", str(out), "--format", "json")
    assert done.returncode == 1
    assert [d["code"] for d in json.loads(done.stdout)] == ["E860"]
    assert not out.exists()
    done = rssmc("ros2", str(tmp_path / "missing.rssm"), "-o", str(out))
    assert done.returncode == 1 and not out.exists()
    done = rssmc("ros2", str(spec), "--maintainer", "nobody")
    assert done.returncode == 2
