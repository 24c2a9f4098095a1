"""The packages as a ROS engineer deploys them (specs/deploy.rssm, two agents): the whole
system started from the one launch file of its bringup package, from a folder that is not the
workspace, on the DDS domain its launch argument names; data topics carrying standard
messages that a hand-written rclpy node subscribes to, with the types the ROS graph shows; the
replayed CSV file found in the agent package's share folder, or in the folder the
rssm.base_dir parameter names."""

from __future__ import annotations

import json
import subprocess
from pathlib import Path
from typing import Any

import pytest

from rssm_dsl.ros2 import toolchain
from tests.ros2.conftest import (
    SPECS,
    Built,
    Processes,
    build_spec,
    launch_cmd,
    node_env,
    wait_ready,
    with_rssmc,
)

pytestmark = [pytest.mark.ros2, pytest.mark.slow]

DEPLOY = SPECS / "deploy.rssm"
LISTENER = Path(__file__).resolve().parent / "std_listener.py"
NODES = ("/sensor/r_feed", "/sensor/c", "/sensor/R_feed", "/ctl/c")
LEVELS = {1.0, 2.0, 3.0, 4.0, 5.0}                          # feed.csv
SPOTS = {(0.1, 0.2, 0.3), (0.4, 0.5, 0.6), (0.7, 0.8, 0.9), (1.0, 1.1, 1.2), (1.3, 1.4, 1.5)}


def _events(path: Path) -> list[dict[str, Any]]:
    return [json.loads(x) for x in path.read_text().splitlines() if x.strip()]


def _received(trace: Path, buffer: str) -> list[Any]:
    return [e["received"][buffer]["value"] for e in _events(trace)
            if e["event"] == "iteration" and buffer in e["received"]]


def _run_system(built: Built, tmp: Path, processes: Processes, env: dict[str, str],
                seconds: float, params: list[str] = (),  # type: ignore[assignment]
                arguments: dict[str, str] | None = None) -> str:
    """Run system.launch.py from a folder of its own (not the workspace); its log."""
    elsewhere = tmp / "elsewhere"
    elsewhere.mkdir()
    launch = processes.start(
        launch_cmd([built.system_launch_file("deploy")], seconds, tmp / "logs", params,
                   arguments), env, tmp / "launch.log", cwd=elsewhere)
    try:
        code = launch.wait(timeout=seconds + 60)
    except subprocess.TimeoutExpired:
        pytest.fail("the launch runner did not stop the nodes")
    log = (tmp / "launch.log").read_text()
    assert code == 124, log                     # ran until the duration ended them
    for node in NODES:                          # every node of both agents ran, and stopped well
        assert f"[launch_runner] {node} " in log, log
        assert "exited 0" in log.split(f"[launch_runner] {node} ")[1].split("\n")[0], log
    return log


def test_whole_system_from_one_launch_file(ros_venv: toolchain.RosVenv, build_dir: Path,
                                           domain: int, tmp_path: Path,
                                           processes: Processes) -> None:
    built = build_spec(DEPLOY, ros_venv, build_dir)
    env = node_env(built, domain, tmp_path)
    listener = processes.start([str(ros_venv.python), str(LISTENER), "--topic",
                                "/sensor/c/total", "--duration", "16"], env,
                               tmp_path / "listener.log")
    wait_ready(listener, tmp_path / "listener.log")
    # the nodes get their domain from the launch argument, not from the environment
    _run_system(built, tmp_path, processes, with_rssmc(dict(env, ROS_DOMAIN_ID="0"), tmp_path),
                22.0, arguments={"domain_id": str(domain)})
    assert listener.wait(timeout=60) == 0
    heard = json.loads((tmp_path / "listener.log").read_text().splitlines()[-1])

    # a hand-written std_msgs/Float64 subscriber got the sums sensor.c sent to ctl.c
    values: list[float] = heard["values"]
    assert len(values) >= 5, heard
    assert all(v == int(v) for v in values) and max(values) > 5.0, values
    assert values == sorted(values), values
    taken = _received(tmp_path / "trace" / "ctl.c.jsonl", "total")
    assert set(values) <= set(taken), (values, taken)      # blocking: each sample taken
    assert taken == sorted(taken), taken
    # blocking on both sides over std_msgs/Float64: every sample taken once, none skipped
    seqs = [e["received"]["total"]["seq"] for e in _events(tmp_path / "trace" / "ctl.c.jsonl")
            if e["event"] == "iteration" and "total" in e["received"]]
    assert seqs == list(range(1, len(seqs) + 1)), seqs

    # the types the ROS graph shows, as `ros2 topic list -t` would
    types = heard["types"]
    expected = {
        "/sensor/c/total": "std_msgs/msg/Float64",
        "/sensor/r_feed/reading": "std_msgs/msg/Float64",
        "/sensor/R_feed/level": "std_msgs/msg/Float64",
        "/sensor/R_feed/spot": "geometry_msgs/msg/Vector3",
        "/sensor/r_feed/where": "geometry_msgs/msg/PointStamped",   # deploy.ros2.toml
        "/sensor/c/motion": "geometry_msgs/msg/TwistStamped",       # a Twist-shaped record
        "/sensor/c/total/info": "deploy_interfaces/msg/SampleInfo",
        "/sensor/c/total/ack": "deploy_interfaces/msg/Ack",
        "/sensor/c/motion/info": "deploy_interfaces/msg/SampleInfo",
    }
    for topic, kind in expected.items():
        assert types.get(topic) == [kind], (topic, types.get(topic))
    assert "/sensor/c/motion/ack" not in types                # non-blocking: no ack topic

    # the replayed file was found in the package's share folder (launched from elsewhere)
    levels = _received(tmp_path / "trace" / "sensor.r.feed.jsonl", "level")
    # (the first rows may be replayed before r.feed's subscription is matched: the device's
    # output is non-blocking, so only values of the file, up to its last, are certain)
    assert len(levels) >= 10 and set(levels) <= LEVELS and 5.0 in levels, levels
    where = _received(tmp_path / "trace" / "sensor.c.jsonl", "where")
    assert where and {tuple(w) for w in where} <= SPOTS | {(0.0, 0.0, 0.0)}, where
    # the record went through geometry_msgs/TwistStamped and back
    motions = _received(tmp_path / "trace" / "ctl.c.jsonl", "motion")
    assert motions and all(tuple(m["linear"]) in SPOTS | {(0.0, 0.0, 0.0)} for m in motions)
    assert all(m["angular"][:2] == [0.0, 0.0] for m in motions), motions


def test_replay_file_from_the_base_dir_parameter(ros_venv: toolchain.RosVenv, build_dir: Path,
                                                 domain: int, tmp_path: Path,
                                                 processes: Processes) -> None:
    built = build_spec(DEPLOY, ros_venv, build_dir)
    env = node_env(built, domain, tmp_path)                 # domain_id: $ROS_DOMAIN_ID
    other = tmp_path / "recorded"
    other.mkdir()
    (other / "feed.csv").write_text("level,spot[0],spot[1],spot[2]\n10.0,0,0,0\n20.0,0,0,1\n")
    _run_system(built, tmp_path, processes, with_rssmc(env, tmp_path), 12.0,
                params=[f"/sensor/R_feed:rssm.base_dir:={other}"])
    levels = _received(tmp_path / "trace" / "sensor.r.feed.jsonl", "level")
    assert levels and set(levels) <= {10.0, 20.0} and 20.0 in levels, levels
