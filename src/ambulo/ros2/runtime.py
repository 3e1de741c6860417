"""Finding rclpy: a sourced ROS 2 distro if there is one, else the PyPI wheels of the ``ros2`` extra.

The wheels (``ros-rclpy[fastrtps]``, Kilted, Fast DDS 3) bring ``ros_wheels_bootstrapper``, which
sets ``LD_LIBRARY_PATH`` for the ROS libraries by re-executing Python once at start-up; a sourced
distro sets it in the shell. Either way ``import rclpy`` is all it takes.
"""

from __future__ import annotations

import os
import tempfile
from pathlib import Path

INSTALL_HINT = "pip install 'ambulo[ros2]' (real rclpy from PyPI), or source a ROS 2 distro (Humble or newer)"


class Ros2Unavailable(RuntimeError):
    """rclpy or a message package cannot be imported; the message says what to install."""


def import_rclpy():
    """``rclpy``, or ``Ros2Unavailable`` naming what to install."""
    try:
        import nav_msgs.msg  # noqa: F401
        import rclpy  # first: the message packages need its type support loaded
        import rosgraph_msgs.msg  # noqa: F401

        # isort: split
        import sensor_msgs.msg  # noqa: F401
    except ImportError as err:
        raise Ros2Unavailable(f"the ROS 2 bridge needs {err.name or 'rclpy'!r}, which cannot be imported "
                              f"({err}); {INSTALL_HINT}") from err
    return rclpy


_PROFILE = """<?xml version="1.0" encoding="UTF-8"?>
<!-- ambulo's Fast DDS transports: shared memory with 16 MB segments (the default 512 kB cannot hold a
     640x480 image, which then goes over UDP in 64 kB fragments) and UDP sockets with 4 MB buffers
     (the kernel default 208 kB delays and drops images to other hosts). -->
<dds xmlns="http://www.eprosima.com"><profiles>
  <transport_descriptors>
    <transport_descriptor><transport_id>ambulo_shm</transport_id><type>SHM</type>
      <segment_size>16777216</segment_size></transport_descriptor>
    <transport_descriptor><transport_id>ambulo_udp</transport_id><type>UDPv4</type>
      <sendBufferSize>4194304</sendBufferSize><receiveBufferSize>4194304</receiveBufferSize>{whitelist}
    </transport_descriptor>
  </transport_descriptors>
  <!-- reliable writers: a heartbeat every 10 ms instead of every 3 s. When a subscriber joins, its reader
       often matches our writer tens of ms after our writer matched it, so it drops what came in that
       gap and, reliable and in order, holds every later sample until the gap is resent: with the
       default timings that took ~120 ms (the reader's 70 ms initial ACKNACK), now one heartbeat. -->
  <data_writer profile_name="ambulo_writer" is_default_profile="true"><times>
    <heartbeat_period><sec>0</sec><nanosec>10000000</nanosec></heartbeat_period>
    <nack_response_delay><sec>0</sec><nanosec>1000000</nanosec></nack_response_delay>
  </times></data_writer>
  <participant profile_name="ambulo_bridge" is_default_profile="true"><rtps>
    <userTransports><transport_id>ambulo_shm</transport_id><transport_id>ambulo_udp</transport_id></userTransports>
    <useBuiltinTransports>false</useBuiltinTransports>
  </rtps></participant>
</profiles></dds>
"""


def use_fastdds_profile() -> str | None:
    """Give this process's Fast DDS participants ambulo's transports (see ``_PROFILE``), unless the user
    chose a profile or another RMW; localhost-only discovery keeps UDP on 127.0.0.1. Returns the path.
    Call before the first ROS 2 context of the process; only the bridge's side changes, peers keep theirs."""
    if any(os.environ.get(v) for v in ("FASTDDS_DEFAULT_PROFILES_FILE", "FASTRTPS_DEFAULT_PROFILES_FILE")):
        return None
    if os.environ.get("RMW_IMPLEMENTATION", "rmw_fastrtps_cpp") != "rmw_fastrtps_cpp":
        return None
    localhost = os.environ.get("ROS_AUTOMATIC_DISCOVERY_RANGE", "").upper() in ("LOCALHOST", "OFF") or \
        os.environ.get("ROS_LOCALHOST_ONLY") == "1"
    whitelist = "<interfaceWhiteList><address>127.0.0.1</address></interfaceWhiteList>" if localhost else ""
    path = Path(tempfile.gettempdir()) / f"ambulo-fastdds-{'localhost' if localhost else 'any'}-{os.getuid()}.xml"
    text = _PROFILE.format(whitelist=whitelist)
    if not path.exists() or path.read_text() != text:
        path.write_text(text)
    os.environ["FASTDDS_DEFAULT_PROFILES_FILE"] = str(path)
    return str(path)


__all__ = ["INSTALL_HINT", "Ros2Unavailable", "import_rclpy", "use_fastdds_profile"]
