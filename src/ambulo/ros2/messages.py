"""Typed ROS 2 messages for the topics published at sensor rates (camera info, lidar).

The per-step topics (clock, joint states, IMU, odometry, /tf, images) are encoded straight to CDR
by ``cdr.py``: building rclpy message objects would cost more than the physics step.
"""

from __future__ import annotations

import array

import numpy as np
from builtin_interfaces.msg import Time
from sensor_msgs.msg import CameraInfo, LaserScan, PointCloud2, PointField
from std_msgs.msg import Header


def stamp(time_s: float) -> Time:
    """Simulated seconds as ``builtin_interfaces/Time`` (whole nanoseconds)."""
    ns = int(round(time_s * 1e9))
    return Time(sec=ns // 1_000_000_000, nanosec=ns % 1_000_000_000)


def header(time_s: float, frame_id: str) -> Header:
    return Header(stamp=stamp(time_s), frame_id=frame_id)


def camera_info(time_s: float, frame_id: str, width: int, height: int, k_matrix) -> CameraInfo:
    """Pinhole intrinsics ``k_matrix`` (3, 3) px; no distortion (``plumb_bob``, D = 0)."""
    k = np.asarray(k_matrix, float)
    msg = CameraInfo(header=header(time_s, frame_id), width=int(width), height=int(height),
                     distortion_model="plumb_bob")
    msg.d = [0.0] * 5
    msg.k = k.ravel()
    msg.r = np.eye(3).ravel()
    msg.p = np.hstack([k, np.zeros((3, 1))]).ravel()
    return msg


def laser_scan(time_s: float, frame_id: str, azimuths_rad, ranges, min_range: float, max_range: float,
               period_s: float) -> LaserScan:
    """One planar ring of ranges (m) at evenly spaced azimuths, counter-clockwise from +x."""
    az = np.asarray(azimuths_rad, float)
    msg = LaserScan(header=header(time_s, frame_id), angle_min=float(az[0]), angle_max=float(az[-1]),
                    angle_increment=float(az[1] - az[0]) if len(az) > 1 else 0.0, time_increment=0.0,
                    scan_time=float(period_s), range_min=float(min_range), range_max=float(max_range))
    msg.ranges = array.array("f", np.asarray(ranges, np.float32).tobytes())
    return msg


def point_cloud(time_s: float, frame_id: str, points) -> PointCloud2:
    """(K, 3) m points in the sensor frame as x, y, z float32 fields."""
    pts = np.ascontiguousarray(points, np.float32).reshape(-1, 3)
    fields = [PointField(name=n, offset=4 * i, datatype=PointField.FLOAT32, count=1) for i, n in enumerate("xyz")]
    msg = PointCloud2(header=header(time_s, frame_id), height=1, width=len(pts), fields=fields, is_bigendian=False,
                      point_step=12, row_step=12 * len(pts), is_dense=True)
    msg.data = array.array("B", pts.tobytes())
    return msg


__all__ = ["camera_info", "header", "laser_scan", "point_cloud", "stamp"]


def occupancy_grid(time_s: float, frame_id: str, costmap):
    """A ``nav_msgs/OccupancyGrid`` of an ``ambulo.perception.Costmap`` (Nav2's cost translation: see
    ``Costmap.occupancy_grid_data``); the map's origin is the lower-left corner of cell [0, 0]
    (``ambulo.maps.to_msg`` builds it)."""
    from ..maps import to_msg

    return to_msg({"header": {"frame_id": frame_id}, "info": costmap.occupancy_grid_info(),
                   "data": costmap.occupancy_grid_data()}, stamp=stamp(time_s))
