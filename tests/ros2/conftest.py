"""Shared set-up of the ROS 2 tests: skip without rclpy; run scenarios on loopback only."""

from __future__ import annotations

import contextlib
import os
import signal
import subprocess
import sys
import tempfile
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

    Output goes to files, not pipes: a pipe stays open while any descendant lives, so a hung
    grandchild would hold the test until the timeout even after the scenario has exited. The
    scenario runs in a session of its own, killed whole at the end."""
    from ambulo.ros2.loopback import isolated, loopback_env

    with tempfile.TemporaryFile("w+") as out, tempfile.TemporaryFile("w+") as err:
        proc = subprocess.Popen(isolated([sys.executable, *args]), env=loopback_env(), stdout=out, stderr=err,
                                text=True, start_new_session=True)
        try:
            returncode = proc.wait(timeout=timeout_s)
        except subprocess.TimeoutExpired:
            returncode = None
        finally:
            with contextlib.suppress(ProcessLookupError):
                os.killpg(proc.pid, signal.SIGKILL)
            proc.wait()
        out.seek(0)
        err.seek(0)
        stdout, stderr = out.read(), err.read()
    if returncode != 0:
        why = f"timed out after {timeout_s:.0f} s" if returncode is None else f"failed ({returncode})"
        pytest.fail(f"{' '.join(args)} {why}:\n{stdout[-3000:]}\n{stderr[-6000:]}")
    return subprocess.CompletedProcess(proc.args, returncode, stdout, stderr)
