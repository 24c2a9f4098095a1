"""The acknowledgement protocol of the generated nodes' channels, without DDS: the scenarios
of channel_protocol.py (an Outbox and an Inbox over a hand-delivered in-process bus: lost,
reordered, late and foreign messages) run in the ROS venv, whose rclpy and std_msgs the
runtime imports."""

from __future__ import annotations

import subprocess

import pytest

from rssm_dsl.ros2 import toolchain
from tests.conftest import ROOT

pytestmark = pytest.mark.ros2

SCENARIOS = 9


def test_every_scenario_of_the_channel_protocol_holds(ros_venv: toolchain.RosVenv) -> None:
    r = subprocess.run([str(ros_venv.python), str(ROOT / "tests/ros2/channel_protocol.py")],
                       cwd=ROOT, capture_output=True, text=True, timeout=120)
    assert r.returncode == 0, r.stdout + r.stderr
    assert r.stdout.count("\nok ") + r.stdout.startswith("ok ") == SCENARIOS, r.stdout
