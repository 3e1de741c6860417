"""Shared set-up of the ROS 2 tests: skip without rclpy; run scenarios on loopback only."""

from __future__ import annotations

import subprocess
from pathlib import Path

import pytest

HERE = Path(__file__).resolve().parent


def needs_rclpy():
    try:
        import rclpy  # noqa: F401
        import sensor_msgs.msg  # noqa: F401
    except ImportError:
        pytest.skip("needs rclpy: pip install 'ambulo[ros2]'")


def run_loopback(args: list[str], timeout_s: float = 240.0) -> subprocess.CompletedProcess:
    """``python args...`` in a loopback-only network namespace (or localhost-only discovery), on a
    domain id of its own; fails the test with the process's output if it fails.

    The scenario's output goes to files and its session is killed whole at the end
    (``loopback.run_isolated``)."""
    from ambulo.ros2.loopback import run_isolated

    done = run_isolated(args, timeout_s)
    returncode, stdout, stderr = done.returncode, done.stdout, done.stderr
    if returncode != 0:
        why = f"timed out after {timeout_s:.0f} s" if returncode is None else f"failed ({returncode})"
        pytest.fail(f"{' '.join(args)} {why}:\n{stdout[-3000:]}\n{stderr[-6000:]}")
    return done
