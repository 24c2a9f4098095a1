"""The launch runner: what the generated launch files describe, the command lines it
derives (as `ros2 launch` would run them), and running real processes (stand-in node
executables in a fake install prefix) with durations, signals and exit codes."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

from rssm_dsl.pipeline import compile_file
from rssm_dsl.ros2 import launch_runner as lr
from rssm_dsl.ros2.generator import generate, write_workspace
from tests.conftest import ROOT

NODE = """#!{python}
import signal, sys, time, pathlib
out = pathlib.Path({out!r})
out.write_text(" ".join(sys.argv[1:]))
mode = {mode!r}
if mode == "exit":
    sys.exit({code})
def stop(*_):
    out.write_text(out.read_text() + " SIGINT")
    sys.exit(0)
signal.signal(signal.SIGINT, stop)
time.sleep(60)
"""


def fake_prefix(tmp: Path, package: str, nodes: dict[str, tuple[str, int]]) -> Path:
    """An install prefix holding `package` with one stand-in executable per node."""
    prefix = tmp / "install"
    (prefix / "share" / "ament_index" / "resource_index" / "packages").mkdir(parents=True,
                                                                             exist_ok=True)
    (prefix / "share" / "ament_index" / "resource_index" / "packages" / package).write_text("")
    lib = prefix / "lib" / package
    lib.mkdir(parents=True, exist_ok=True)
    for exe, (mode, code) in nodes.items():
        path = lib / exe
        path.write_text(NODE.format(python=sys.executable, out=str(tmp / f"{exe}.out"),
                                    mode=mode, code=code))
        path.chmod(0o755)
    return prefix


@pytest.fixture
def lwr4_launch(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Path:
    monkeypatch.chdir(ROOT)
    ws = generate(compile_file(Path("examples/lwr4_circle.rssm")))
    assert not isinstance(ws, list)
    write_workspace(ws, tmp_path / "src")
    return tmp_path / "src" / "lwr4_circle_a1" / "launch" / "a1.launch.py"


def test_generated_launch_file_describes_every_node(lwr4_launch: Path, tmp_path: Path,
                                                    monkeypatch: pytest.MonkeyPatch) -> None:
    prefix = fake_prefix(tmp_path, "lwr4_circle_a1", {})
    monkeypatch.setenv("AMENT_PREFIX_PATH", str(prefix))
    nodes = lr.load_launch_file(lwr4_launch)
    params = str(prefix / "share" / "lwr4_circle_a1" / "config" / "params.yaml")
    assert [(n.package, n.executable, n.name, n.namespace, n.parameters) for n in nodes] == [
        ("lwr4_circle_a1", "c", "c", "a1", [params]),
        ("lwr4_circle_a1", "e_lwr", "e_lwr", "a1", [params]),
        ("lwr4_circle_a1", "E_lwr", "E_lwr", "a1", [params]),
    ]
    assert [n.fqn for n in nodes] == ["/a1/c", "/a1/e_lwr", "/a1/E_lwr"]
    assert lr.command(nodes[1], ["rssm.rate_hz:=10.0"]) == [
        str(prefix / "lib" / "lwr4_circle_a1" / "e_lwr"), "--ros-args", "-r", "__node:=e_lwr",
        "-r", "__ns:=/a1", "--params-file", params, "-p", "rssm.rate_hz:=10.0"]
    # the stand-ins leave no trace in sys.modules
    assert "launch" not in sys.modules and "launch_ros.actions" not in sys.modules


def test_dry_run_prints_the_commands(lwr4_launch: Path, tmp_path: Path,
                                     monkeypatch: pytest.MonkeyPatch,
                                     capsys: pytest.CaptureFixture[str]) -> None:
    prefix = fake_prefix(tmp_path, "lwr4_circle_a1", {})
    monkeypatch.setenv("AMENT_PREFIX_PATH", str(prefix))
    assert lr.main(["--dry-run", "-p", "/a1/c:radius:=0.1", str(lwr4_launch)]) == 0
    lines = [json.loads(x) for x in capsys.readouterr().out.splitlines()]
    assert [x["node"] for x in lines] == ["/a1/c", "/a1/e_lwr", "/a1/E_lwr"]
    assert lines[0]["command"][-2:] == ["-p", "radius:=0.1"]
    assert "-p" not in lines[1]["command"]


def test_unsupported_launch_actions_are_refused(tmp_path: Path,
                                                capsys: pytest.CaptureFixture[str]) -> None:
    f = tmp_path / "x.launch.py"
    f.write_text("from launch import LaunchDescription\nfrom launch_ros.actions import Node\n"
                 "def generate_launch_description():\n"
                 "    return LaunchDescription([Node(package='p', executable='e', "
                 "respawn=True)])\n")
    assert lr.main([str(f)]) == 2
    assert "Node(respawn=...) is not supported" in capsys.readouterr().err
    assert lr.main([str(tmp_path / "missing.launch.py")]) == 2


def _launch_file(tmp: Path, package: str, execs: list[str]) -> Path:
    f = tmp / "t.launch.py"
    nodes = ", ".join(f"Node(package={package!r}, executable={e!r}, name={e!r}, "
                      f"namespace='ns', arguments=['--flag'])" for e in execs)
    f.write_text("from launch import LaunchDescription\nfrom launch_ros.actions import Node\n"
                 f"def generate_launch_description():\n    return LaunchDescription([{nodes}])\n")
    return f


def _run(files: list[Path], env: dict[str, str], *args: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run([sys.executable, "-m", "rssm_dsl.ros2.launch_runner", *args,
                           *map(str, files)], env=env, capture_output=True, text=True,
                          timeout=60, check=False)


def test_runs_the_nodes_and_reports_their_exit_codes(tmp_path: Path) -> None:
    prefix = fake_prefix(tmp_path, "pkg", {"ok": ("exit", 0), "bad": ("exit", 3)})
    env = dict(os.environ, AMENT_PREFIX_PATH=str(prefix))
    done = _run([_launch_file(tmp_path, "pkg", ["ok"])], env, "--log-dir", str(tmp_path / "l"))
    assert done.returncode == 0, done.stderr
    assert (tmp_path / "ok.out").read_text() == "--flag --ros-args -r __node:=ok -r __ns:=/ns"
    assert "/ns/ok (pkg/ok) exited 0" in done.stderr
    assert (tmp_path / "l" / "ns.ok.log").exists()
    done = _run([_launch_file(tmp_path, "pkg", ["ok", "bad"])], env)
    assert done.returncode == 3 and "/ns/bad (pkg/bad) exited 3" in done.stderr


def test_duration_stops_the_nodes_with_sigint(tmp_path: Path) -> None:
    prefix = fake_prefix(tmp_path, "pkg", {"loop": ("loop", 0)})
    env = dict(os.environ, AMENT_PREFIX_PATH=str(prefix))
    done = _run([_launch_file(tmp_path, "pkg", ["loop"])], env, "--duration", "1.5")
    assert done.returncode == 124, done.stderr
    assert (tmp_path / "loop.out").read_text().endswith(" SIGINT")
    assert "/ns/loop (pkg/loop) exited 0" in done.stderr


def test_missing_package_is_reported(tmp_path: Path) -> None:
    env = dict(os.environ, AMENT_PREFIX_PATH=str(tmp_path))
    done = _run([_launch_file(tmp_path, "nowhere", ["x"])], env)
    assert done.returncode == 2
    assert "package 'nowhere' is not found on AMENT_PREFIX_PATH" in done.stderr


def test_system_launch_file_and_its_domain_argument(tmp_path: Path,
                                                    monkeypatch: pytest.MonkeyPatch,
                                                    capsys: pytest.CaptureFixture[str]) -> None:
    """The bringup package's system.launch.py: every agent's nodes in their namespaces with
    config/system.yaml, ROS_DOMAIN_ID set from the launch argument domain_id (default: the
    environment's, else 0), and use_sim_time from the launch argument (default false), given
    to every node as `-p use_sim_time:=...`."""
    monkeypatch.chdir(ROOT)
    ws = generate(compile_file(Path("tests/ros2/specs/relay.rssm")))
    assert not isinstance(ws, list)
    write_workspace(ws, tmp_path / "src")
    launch = tmp_path / "src" / "relay_bringup" / "launch" / "system.launch.py"
    for package in ("relay_bringup", "relay_src", "relay_dst"):
        prefix = fake_prefix(tmp_path, package, {})
    monkeypatch.setenv("AMENT_PREFIX_PATH", str(prefix))
    monkeypatch.setenv("ROS_DOMAIN_ID", "5")
    params = str(prefix / "share" / "relay_bringup" / "config" / "system.yaml")
    planned = lr.plan([launch], {"domain_id": "9"})
    wall = {"use_sim_time": "false"}
    assert [(n.package, n.fqn, n.parameters, env["ROS_DOMAIN_ID"]) for n, env in planned] == [
        ("relay_src", "/src/c", [params, wall], "9"),
        ("relay_dst", "/dst/c", [params, wall], "9"),
        ("relay_dst", "/dst/e_arm", [params, wall], "9")]
    sim = lr.plan([launch], {"use_sim_time": "true"})
    commands = [lr.command(n) for n, _ in sim]
    assert all(c[c.index("--params-file") + 1:] == [params, "-p", "use_sim_time:=true"]
               for c in commands), commands
    assert {env["ROS_DOMAIN_ID"] for _, env in lr.plan([launch])} == {"5"}
    monkeypatch.delenv("ROS_DOMAIN_ID")
    assert {env["ROS_DOMAIN_ID"] for _, env in lr.plan([launch])} == {"0"}
    with pytest.raises(lr.LaunchError, match="domian_id not declared"):
        lr.plan([launch], {"domian_id": "3"})
    assert lr.main(["--dry-run", str(launch), "domain_id:=9"]) == 0
    lines = [json.loads(x) for x in capsys.readouterr().out.splitlines()]
    assert [(x["node"], x["env"]) for x in lines] == [
        ("/src/c", {"ROS_DOMAIN_ID": "9"}), ("/dst/c", {"ROS_DOMAIN_ID": "9"}),
        ("/dst/e_arm", {"ROS_DOMAIN_ID": "9"})]


def test_set_environment_applies_to_the_nodes_after_it(tmp_path: Path) -> None:
    prefix = fake_prefix(tmp_path, "pkg", {"ok": ("exit", 0)})
    f = tmp_path / "env.launch.py"
    f.write_text(
        "from launch import LaunchDescription\nfrom launch.actions import "
        "DeclareLaunchArgument, SetEnvironmentVariable\nfrom launch.substitutions import "
        "LaunchConfiguration\nfrom launch_ros.actions import Node\n"
        "def generate_launch_description():\n    return LaunchDescription([\n"
        "        DeclareLaunchArgument('who'),\n"
        "        Node(package='pkg', executable='ok', name='first'),\n"
        "        SetEnvironmentVariable('RSSM_WHO', LaunchConfiguration('who')),\n"
        "        Node(package='pkg', executable='ok', name='second')])\n")
    env = dict(os.environ, AMENT_PREFIX_PATH=str(prefix))
    env.pop("RSSM_WHO", None)
    planned = lr.plan([f], {"who": "me"}, env)
    assert [(n.name, e.get("RSSM_WHO")) for n, e in planned] == [("first", None),
                                                                   ("second", "me")]
    with pytest.raises(lr.LaunchError, match="'who' has no default"):
        lr.plan([f], {}, env)
