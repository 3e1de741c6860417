"""``examples/ros2/jetbot_teleop.py``: an rclpy node drives the Jetbot through the bridge and reads /odom."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from .conftest import needs_rclpy, run_loopback

EXAMPLE = Path(__file__).resolve().parents[2] / "examples" / "ros2" / "jetbot_teleop.py"


def test_jetbot_teleop_example_drives_and_odom_agrees(tmp_path):
    needs_rclpy()
    proc = run_loopback([str(EXAMPLE), "--seconds", "2", "--speed", "0.3", "--record", str(tmp_path / "bag")])
    result = json.loads(proc.stdout.strip().splitlines()[-1])
    assert result["driven_m"] == pytest.approx(0.6, abs=0.06)
    assert result["odom_messages"] > 100  # 100 Hz of simulated time; a late reader may miss a few (keep-last 10)
    assert result["odom_last_xy"] == pytest.approx(result["sim_xy"], abs=0.01)  # the last one is < 1 step old
    assert (tmp_path / "bag" / "metadata.yaml").exists()
