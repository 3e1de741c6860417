"""The TF tree of a World: every link of every robot, plus sensor frames, as ROS frame names.

Each robot's root body becomes ``base_link`` (child of ``odom``: the simulator's world, so odometry
is ground truth); every other body is a frame named after the body, child of its parent body.
Bodies welded to their parent and sensor frames are fixed: they go to ``/tf_static`` once. Camera
frames follow ROS's optical convention (REP 103: z forward, x right, y down).
"""

from __future__ import annotations

from dataclasses import dataclass

import mujoco
import numpy as np

from ..utils.rotations import mat_to_quat

OPTICAL_FROM_GL = np.diag([1.0, -1.0, -1.0])
"""OpenGL camera axes (x right, y up, looking down -z) -> ROS optical axes (x right, y down, z forward)."""


@dataclass
class Link:
    """One transform of the tree: ``child`` in ``parent``; body ids index ``MjData.xpos``."""

    parent: str
    child: str
    body: int
    parent_body: int
    """-1: the parent is the odom frame (the world)."""


@dataclass
class StaticFrame:
    parent: str
    child: str
    pos: np.ndarray
    """(3,) m, child origin in the parent frame."""
    quat_wxyz: np.ndarray


@dataclass
class RobotFrames:
    name: str
    robot: object
    prefix: str
    dynamic: list[Link]
    static: list[StaticFrame]
    frame_of_body: dict[int, str]
    """MuJoCo body id -> frame name."""


def robot_frames(model: mujoco.MjModel, robot, name: str, prefix: str, odom: str, base: str) -> RobotFrames:
    """The links of ``robot`` (an ``Articulation``): jointed ones dynamic, welded ones static."""
    entity = robot.entity
    ids = [int(b) for b in entity._body_ids_np]
    names = {b: prefix + (base if b == entity.root_body_id else n) for b, n in zip(ids, entity.body_names)}
    dynamic = [Link(odom, names[entity.root_body_id], entity.root_body_id, -1)]
    static = []
    for b in ids:
        if b == entity.root_body_id:
            continue
        parent = int(model.body_parentid[b])
        if parent not in names:
            continue
        if model.body_jntnum[b] == 0:  # welded: the model's offset is the transform
            static.append(StaticFrame(names[parent], names[b], model.body_pos[b].copy(), model.body_quat[b].copy()))
        else:
            dynamic.append(Link(names[parent], names[b], b, parent))
    return RobotFrames(name, robot, prefix, dynamic, static, names)


def relative(pos_p, quat_p, pos_c, quat_c) -> tuple[np.ndarray, np.ndarray]:
    """(K, 3) positions and (K, 4) wxyz of children in their parents, from world poses (MuJoCo's
    quaternion routines: a handful of links per robot, so a loop of C calls beats batched NumPy)."""
    pos, quat = np.empty((len(pos_c), 3)), np.empty((len(pos_c), 4))
    inverse = np.empty(4)
    for k in range(len(pos_c)):
        mujoco.mju_negQuat(inverse, quat_p[k])
        mujoco.mju_rotVecQuat(pos[k], pos_c[k] - pos_p[k], inverse)
        mujoco.mju_mulQuat(quat[k], inverse, quat_c[k])
    return pos, quat


def xyzw(quat_wxyz) -> np.ndarray:
    """MuJoCo's (..., 4) (w, x, y, z) as ROS's (x, y, z, w)."""
    return np.asarray(quat_wxyz, float)[..., [1, 2, 3, 0]]


def static_from_world(parent: str, child: str, body_pos, body_rot, pos_w, rot_w) -> StaticFrame:
    """A fixed frame from world poses of its body (``body_rot`` (3, 3)) and of itself."""
    pos = body_rot.T @ (np.asarray(pos_w) - body_pos)
    return StaticFrame(parent, child, pos, mat_to_quat(body_rot.T @ rot_w))


def leaf(prim_path: str) -> str:
    """``/World/Jetbot/chassis/imu`` -> ``imu``: a sensor's frame name."""
    return prim_path.rstrip("/").rsplit("/", 1)[-1] or "sensor"


__all__ = ["OPTICAL_FROM_GL", "Link", "RobotFrames", "StaticFrame", "leaf", "relative", "robot_frames",
           "static_from_world", "xyzw"]
