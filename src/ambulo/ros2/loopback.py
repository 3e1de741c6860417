"""Running ROS 2 processes with no traffic leaving the machine (tests, benchmarks).

Preferred: a private network namespace holding only the loopback interface (``unshare -n``, then
``ip link set lo up``; needs root or user namespaces and ``iproute2``): no DDS packet can reach a
LAN. Else: ROS 2's own localhost-only discovery (``ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST``,
Iron and newer). Both set a domain id of their own, so parallel runs do not see each other.
"""

from __future__ import annotations

import contextlib
import fcntl
import glob
import os
import random
import shutil
import signal
import subprocess
import sys
import tempfile


def loopback_env(domain_id: int | None = None, base: dict | None = None) -> dict:
    """``base`` (default ``os.environ``) with localhost-only discovery on a private domain id."""
    env = dict(os.environ if base is None else base)
    env["ROS_AUTOMATIC_DISCOVERY_RANGE"] = "LOCALHOST"
    env.pop("ROS_STATIC_PEERS", None)
    env.pop("ROS_LOCALHOST_ONLY", None)  # deprecated since Jazzy; conflicts with the range above
    # 1..101: the ids whose RTPS ports stay below the ephemeral range on every platform
    env["ROS_DOMAIN_ID"] = str(domain_id if domain_id is not None else random.randint(1, 101))
    return env


def can_unshare() -> bool:
    """Whether ``unshare -n`` with a loopback-only namespace works here."""
    if not (shutil.which("unshare") and shutil.which("ip")):
        return False
    probe = subprocess.run(["unshare", "-n", "sh", "-c", "ip link set lo up"], capture_output=True)
    return probe.returncode == 0


def isolated(argv: list[str]) -> list[str]:
    """``argv`` wrapped to run in a fresh loopback-only network namespace when possible (else as is,
    relying on ``loopback_env``'s localhost-only discovery); child processes share the namespace."""
    if not can_unshare():
        return list(argv)
    return ["unshare", "-n", "sh", "-c", 'ip link set lo up && exec "$@"', "ambulo-loopback", *argv]


def run_isolated(args: list[str], timeout_s: float) -> subprocess.CompletedProcess:
    """``python args...`` in a loopback-only network namespace (``isolated``) on a domain id of its own
    (``loopback_env``); ``returncode`` None if it outlived ``timeout_s``.

    Output goes to files, not pipes: a pipe stays open while any descendant lives, so a hung
    grandchild would hold the caller until the timeout even after the script has exited. The
    script runs in a session of its own, killed whole at the end."""
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
        return subprocess.CompletedProcess(proc.args, returncode, out.read(), err.read())


def clean_dead_fastdds_segments(shm_dir: str = "/dev/shm") -> int:
    """Remove the shared-memory segments of Fast DDS participants whose process died without closing
    them (``kill -9``): 0.5-17 MB each, in RAM, kept until reboot. A live owner holds an exclusive
    ``flock`` on the segment's ``_el`` file (what Fast DDS's ``fastdds shm clean`` checks too).
    Returns the number of segments removed."""
    removed = 0
    for lock_file in glob.glob(os.path.join(shm_dir, "fastdds_*_el")):
        try:
            fd = os.open(lock_file, os.O_RDWR)
        except OSError:
            continue
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except OSError:  # held: its participant is alive
            os.close(fd)
            continue
        segment = lock_file.removesuffix("_el")
        name = os.path.basename(segment)
        for path in (segment, os.path.join(shm_dir, f"sem.{name}_mutex"), lock_file):
            try:
                os.remove(path)
            except FileNotFoundError:
                pass
        os.close(fd)
        removed += 1
    return removed


__all__ = ["can_unshare", "clean_dead_fastdds_segments", "isolated", "loopback_env"]
