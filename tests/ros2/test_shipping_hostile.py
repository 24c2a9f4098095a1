"""What `rssmc ros2` ships of a binding's package folder when it holds more than Python
sources: links out of the package (a private key, /dev/zero), a FIFO, a link to itself, data
files. Only the package's Python sources are shipped, nothing is followed out of it, nothing
special is opened; what is left out is warning W868, and the command ends in seconds."""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

from rssm_dsl.pipeline import compile_file
from rssm_dsl.ros2.generator import Workspace, generate, write_workspace
from rssm_dsl.ros2.shipping import read_shipped
from tests.conftest import EXAMPLES
from tests.ros2.conftest import SPECS

SECRET = "-----BEGIN OPENSSH PRIVATE KEY-----\nnot really\n"


@pytest.fixture
def project(tmp_path: Path) -> Path:
    """tests/ros2/specs/wire.rssm with its extern's module made a package, gadget_ops/, and a
    private key outside the project."""
    proj = tmp_path / "proj"
    (proj / "gadget_ops").mkdir(parents=True)
    shutil.copy(SPECS / "wire.rssm", proj)
    shutil.copy(SPECS / "gadget_device.py", proj)
    shutil.copy(SPECS / "gadget_ops.py", proj / "gadget_ops" / "__init__.py")
    (tmp_path / "secret").mkdir()
    (tmp_path / "secret" / "id_rsa").write_text(SECRET)
    return proj


def gen(proj: Path) -> Workspace:
    comp = compile_file(proj / "wire.rssm")
    assert comp.ok, [str(d) for d in comp.diagnostics]
    ws = generate(comp)
    assert not isinstance(ws, list), ws
    return ws


def shipped(ws: Workspace, part: str) -> list[str]:
    return sorted(rel.split("/", 1)[1] for rel in ws.copies if part in rel)


def w868(ws: Workspace) -> list[str]:
    return [w.message for w in ws.warnings if w.code == "W868"]


def rssmc_ros2(proj: Path, out: Path) -> subprocess.CompletedProcess[str]:
    return subprocess.run([sys.executable, "-m", "rssm_dsl", "ros2", "wire.rssm", "-o", str(out)],
                          cwd=proj, capture_output=True, text=True, timeout=60)


def test_a_plain_package_ships_its_python_sources_without_warnings(project: Path) -> None:
    (project / "gadget_ops" / "sub").mkdir()
    (project / "gadget_ops" / "sub" / "__init__.py").write_text("")
    (project / "gadget_ops" / "sub" / "more.py").write_text("X = 1\n")
    ws = gen(project)
    assert shipped(ws, "gadget_ops") == ["gadget_ops/__init__.py", "gadget_ops/sub/__init__.py",
                                         "gadget_ops/sub/more.py"]
    assert not w868(ws)


def test_a_link_to_a_private_key_is_not_shipped(project: Path, tmp_path: Path) -> None:
    (project / "gadget_ops" / "key.pem").symlink_to(tmp_path / "secret" / "id_rsa")
    (project / "gadget_ops" / "steal.py").symlink_to(tmp_path / "secret" / "id_rsa")
    ws = gen(project)
    assert shipped(ws, "gadget_ops") == ["gadget_ops/__init__.py"]
    assert all(SECRET.encode() not in src.read_bytes() for src in ws.copies.values())
    assert len(w868(ws)) == 2 and all("link out of" in m for m in w868(ws))
    out = tmp_path / "ws"
    r = rssmc_ros2(project, out)
    assert r.returncode == 0, r.stderr
    assert "warning[W868]" in r.stderr and "key.pem" in r.stderr
    assert not any(SECRET in p.read_text(errors="replace")
                   for p in out.rglob("*") if p.is_file())


def test_a_fifo_is_left_out_without_being_opened(project: Path, tmp_path: Path) -> None:
    os.mkfifo(project / "gadget_ops" / "pipe")
    os.mkfifo(project / "gadget_ops" / "pipe.py")
    out = tmp_path / "ws"
    r = rssmc_ros2(project, out)            # (it used to wait on the FIFO for ever)
    assert r.returncode == 0, r.stderr
    assert r.stderr.count("warning[W868]") == 2 and "FIFO" in r.stderr
    assert sorted(p.name for p in (out / "wire_runtime" / "gadget_ops").iterdir()) == [
        "__init__.py"]


def test_a_link_to_dev_zero_is_not_followed(project: Path, tmp_path: Path) -> None:
    (project / "gadget_ops" / "zero.py").symlink_to("/dev/zero")
    out = tmp_path / "ws"
    r = rssmc_ros2(project, out)            # (it used to end in a MemoryError)
    assert r.returncode == 0, r.stderr
    assert "warning[W868]" in r.stderr and "zero.py" in r.stderr
    assert "E900" not in r.stderr and "Traceback" not in r.stderr


def test_a_link_to_itself_is_w868_not_a_problem_of_the_output(project: Path,
                                                              tmp_path: Path) -> None:
    (project / "gadget_ops" / "self").symlink_to("self")
    (project / "gadget_ops" / "loop").symlink_to(project / "gadget_ops")
    out = tmp_path / "ws"
    r = rssmc_ros2(project, out)
    assert r.returncode == 0, r.stderr
    assert r.stderr.count("warning[W868]") == 2
    assert "--output" not in r.stderr and "-o)" not in r.stderr


def test_a_link_inside_the_package_to_a_python_source_is_shipped(project: Path) -> None:
    (project / "gadget_ops" / "alias.py").symlink_to("__init__.py")
    ws = gen(project)
    assert shipped(ws, "gadget_ops") == ["gadget_ops/__init__.py", "gadget_ops/alias.py"]
    assert not w868(ws)


def test_files_that_are_not_python_sources_are_named_once(project: Path) -> None:
    for name in ("table.csv", "notes.txt", "model.bin"):
        (project / "gadget_ops" / name).write_text("data\n")
    ws = gen(project)
    assert shipped(ws, "gadget_ops") == ["gadget_ops/__init__.py"]
    [message] = w868(ws)
    assert "3 file(s)" in message and "table.csv" in message


def test_a_module_linked_from_outside_the_project_is_not_shipped(project: Path,
                                                                 tmp_path: Path) -> None:
    (project / "gadget_device.py").unlink()
    (project / "gadget_device.py").symlink_to(tmp_path / "secret" / "id_rsa")
    ws = gen(project)
    assert not shipped(ws, "gadget_device")
    assert any("gadget_device.py" in m and "link out of" in m for m in w868(ws))


@pytest.mark.parametrize("kind", ["link out", "fifo"])
def test_a_device_s_csv_file_is_shipped_only_when_it_is_a_regular_file_here(
        project: Path, tmp_path: Path, kind: str) -> None:
    csv = project / "thermo.csv"
    if kind == "fifo":
        os.mkfifo(csv)
    else:
        csv.symlink_to(tmp_path / "secret" / "id_rsa")
    ws = gen(project)
    assert not [rel for rel in ws.copies if rel.endswith(".csv")]
    assert any("thermo.csv" in m for m in w868(ws))
    csv.unlink()
    (project / "real.csv").write_text("level\n1.0\n")
    csv.symlink_to("real.csv")
    ws = gen(project)
    assert [rel for rel in ws.copies if rel.endswith(".csv")] == ["wire_gadget/data/thermo.csv"]
    assert not w868(ws)


def test_the_standard_library_still_ships_its_data_files() -> None:
    comp = compile_file(EXAMPLES / "lwr4_circle.rssm")
    ws = generate(comp)
    assert not isinstance(ws, list)
    assert any(rel.endswith("rssm_stdlib/lwr4plus/lwr4plus.xml") for rel in ws.copies)
    assert not w868(ws)


def test_a_file_replaced_by_a_fifo_after_it_was_chosen_is_not_read(project: Path,
                                                                   tmp_path: Path) -> None:
    ws = gen(project)
    target = tmp_path / "ws"
    source = project / "gadget_ops" / "__init__.py"
    source.unlink()
    os.mkfifo(source)
    with pytest.raises(OSError, match="not a regular file"):
        read_shipped(source)
    with pytest.raises(OSError):
        write_workspace(ws, target)
    assert not target.exists()          # all or nothing
