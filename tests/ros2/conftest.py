"""Shared set-up of the ROS 2 tests: skip without rclpy; run scenarios on loopback only."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

HERE = Path(__file__).resolve().parent


def needs_rclpy():
    try:
        import rclpy  # noqa: F401, PLC0415
        import sensor_msgs.msg  # noqa: F401, PLC0415
    except ImportError:
        pytest.skip("needs rclpy: pip install 'ambulo[ros2]'")


def run_loopback(args: list[str], timeout_s: float = 240.0) -> subprocess.CompletedProcess:
    """``python args...`` in a loopback-only network namespace (or localhost-only discovery), on a
    domain id of its own; fails the test with the process's output if it fails."""
    from ambulo.ros2.loopback import isolated, loopback_env  # noqa: PLC0415

    proc = subprocess.run(isolated([sys.executable, *args]), env=loopback_env(), capture_output=True, text=True,
                          timeout=timeout_s)
    if proc.returncode != 0:
        pytest.fail(f"{' '.join(args)} failed ({proc.returncode}):\n{proc.stdout[-3000:]}\n{proc.stderr[-6000:]}")
    return proc
