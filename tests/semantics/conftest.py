"""Fixtures of the semantic tests: the ROS 2 ones (ROS venv, build folder, a DDS domain per
test, processes killed at the end) are those of tests/ros2/conftest.py."""

from __future__ import annotations

from tests.ros2.conftest import build_dir, domain, processes, ros_venv

__all__ = ["build_dir", "domain", "processes", "ros_venv"]
