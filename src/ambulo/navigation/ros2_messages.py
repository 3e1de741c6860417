"""The navigator's ROS 2 messages, built from its state: the route as ``nav_msgs/Path``, footsteps
as ``visualization_msgs/MarkerArray``, poses as ``nav_msgs/Odometry`` and ``tf2_msgs/TFMessage``.

Path is an rclpy message object (made at replans only); Odometry and TFMessage are CDR bytes from
``ros2.cdr`` (as the bridge writes them: they go out at the camera rate); MarkerArray, which has no
Python wheel, is CDR bytes encoded by ``rosbags`` (its Kilted definition, texture and mesh fields
included) and published through a ``ros2.raw_types`` class. Every stamp is simulated time.
"""

from __future__ import annotations

import math

import numpy as np

from ..nav import FootstepPlan
from ..ros2 import cdr
from ..ros2.messages import header
from ..ros2.raw_types import typestore

LEFT_RGBA = (0.15, 0.75, 0.25, 0.9)
"""Colour of a left footstep (green, as the left side light of a vessel)."""
RIGHT_RGBA = (0.85, 0.2, 0.2, 0.9)
"""Colour of a right footstep (red)."""
START_ALPHA = 0.35
"""The two start feet (where the robot stands when the plan is made) are drawn fainter."""
FOOT_HEIGHT_M = 0.02
"""Thickness of a footstep's cube, m."""


def yaw_quat_xyzw(yaw_rad: float) -> tuple[float, float, float, float]:
    return (0.0, 0.0, math.sin(yaw_rad / 2), math.cos(yaw_rad / 2))


def yaw_of_quat_xyzw(x: float, y: float, z: float, w: float) -> float:
    """The heading (rotation about z) of a quaternion, rad."""
    return math.atan2(2 * (w * z + x * y), 1 - 2 * (y * y + z * z))


def path_msg(time_s: float, frame_id: str, path_xy_m: np.ndarray):
    """``nav_msgs/Path`` of a polyline (K, 2) m; each pose faces the next point (the last keeps
    the previous heading)."""
    from geometry_msgs.msg import PoseStamped
    from nav_msgs.msg import Path

    xy = np.asarray(path_xy_m, float).reshape(-1, 2)
    d = np.diff(xy, axis=0)
    yaws = np.arctan2(d[:, 1], d[:, 0]) if len(d) else np.zeros(0)
    yaws = np.concatenate([yaws, yaws[-1:] if len(yaws) else [0.0]])
    msg = Path(header=header(time_s, frame_id))
    for (x, y), yaw in zip(xy, yaws):
        pose = PoseStamped(header=msg.header)
        pose.pose.position.x, pose.pose.position.y = float(x), float(y)
        _, _, pose.pose.orientation.z, pose.pose.orientation.w = yaw_quat_xyzw(float(yaw))
        msg.poses.append(pose)
    return msg


class OdometryCdr:
    """``nav_msgs/Odometry`` CDR of planar poses, from the bridge's template (an rclpy message object
    costs ~2 ms to fill, its covariance arrays checked element by element)."""

    def __init__(self, frame_id: str, child_frame_id: str):
        self._template = cdr.odometry_template(frame_id, child_frame_id)

    def __call__(self, time_s: float, pose_xyyaw, velocity_b=(0.0, 0.0, 0.0)) -> bytes:
        """A planar pose (x m, y m, yaw rad) at z = 0 (the base on the floor) and a body-frame velocity
        (forward m/s, left m/s, yaw rate rad/s); covariances unknown (0)."""
        x, y, yaw = (float(v) for v in pose_xyyaw)
        vx, vy, wz = (float(v) for v in velocity_b)
        values = np.zeros(85)
        values[:7] = (x, y, 0.0, *yaw_quat_xyzw(yaw))
        values[43:49] = (vx, vy, 0.0, 0.0, 0.0, wz)  # after the pose's 36 covariances
        return self._template.fill(int(round(time_s * 1e9)), values=values)


def tf_cdr(time_s: float, parents: list[str], children: list[str], pos, quat_xyzw) -> bytes:
    """``tf2_msgs/TFMessage`` CDR of K transforms (``pos`` (K, 3) m, ``quat_xyzw`` (K, 4))."""
    return cdr.tf_message(int(round(time_s * 1e9)), parents, children, pos, quat_xyzw)


def _marker(store, time_s: float, frame_id: str, marker_id: int, action: int, xyz=(0.0, 0.0, 0.0), yaw_rad=0.0,
            scale=(0.0, 0.0, 0.0), rgba=(0.0, 0.0, 0.0, 0.0), ns: str = "footsteps"):
    t = store.types
    sec, nanosec = divmod(int(round(time_s * 1e9)), 1_000_000_000)
    hdr = t["std_msgs/msg/Header"](t["builtin_interfaces/msg/Time"](sec, nanosec), frame_id)
    qx, qy, qz, qw = yaw_quat_xyzw(yaw_rad)
    pose = t["geometry_msgs/msg/Pose"](t["geometry_msgs/msg/Point"](*map(float, xyz)),
                                       t["geometry_msgs/msg/Quaternion"](qx, qy, qz, qw))
    empty = np.zeros(0, np.uint8)
    return t["visualization_msgs/msg/Marker"](
        header=hdr, ns=ns, id=marker_id, type=1, action=action, pose=pose,  # type 1: CUBE
        scale=t["geometry_msgs/msg/Vector3"](*map(float, scale)), color=t["std_msgs/msg/ColorRGBA"](*map(float, rgba)),
        lifetime=t["builtin_interfaces/msg/Duration"](0, 0), frame_locked=False, points=[], colors=[],
        texture_resource="", texture=t["sensor_msgs/msg/CompressedImage"](hdr, "", empty), uv_coordinates=[], text="",
        mesh_resource="", mesh_file=t["visualization_msgs/msg/MeshFile"]("", empty), mesh_use_embedded_materials=False)


def footstep_markers_cdr(time_s: float, frame_id: str, plan: FootstepPlan | None, foot_size_m=(0.22, 0.10)) -> bytes:
    """``visualization_msgs/MarkerArray`` CDR: a DELETEALL (the previous plan's markers go), then one
    CUBE per foot of ``plan`` (the sole's size, left green, right red, the two start feet faint),
    ids 0.. in plan order."""
    store = typestore()
    markers = [_marker(store, time_s, frame_id, 0, 3)]  # 3: DELETEALL
    if plan is not None:
        feet = np.asarray(plan.footsteps_xyyaw_w, float)
        z = np.asarray(plan.foot_z_m, float)
        for i, ((x, y, yaw), side) in enumerate(zip(feet, plan.foot_sides)):
            r, g, b, a = LEFT_RGBA if side > 0 else RIGHT_RGBA
            markers.append(_marker(store, time_s, frame_id, i, 0, (x, y, z[i] + FOOT_HEIGHT_M / 2), yaw,
                                   (foot_size_m[0], foot_size_m[1], FOOT_HEIGHT_M),
                                   (r, g, b, a * START_ALPHA if i < 2 else a)))
    array = store.types["visualization_msgs/msg/MarkerArray"](markers)
    return bytes(store.serialize_cdr(array, "visualization_msgs/msg/MarkerArray"))


__all__ = ["LEFT_RGBA", "RIGHT_RGBA", "OdometryCdr", "footstep_markers_cdr", "path_msg", "tf_cdr", "yaw_of_quat_xyzw",
           "yaw_quat_xyzw"]
