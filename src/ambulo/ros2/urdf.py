"""A URDF of the robots as the bridge names their frames, for ``/robot_description`` (rviz2's
RobotModel display draws each link's visuals at the pose /tf gives that link).

Links are the bodies (the root is ``base_link``), with one visual per MuJoCo geom of groups 0-2:
boxes, spheres, cylinders and ellipsoids as themselves (an ellipsoid as its bounding sphere), a
capsule as a cylinder plus two spheres; meshes, planes and height fields are left out. Joints are
``fixed`` for welded bodies, ``continuous``/``revolute``/``prismatic`` for one hinge or slide, and
``floating`` for bodies with several joints (rviz takes every link's pose from /tf anyway).
"""

from __future__ import annotations

from xml.sax.saxutils import quoteattr

import mujoco
import numpy as np

from ambulo.core.names import DOF_JOINT_TYPES

from .frames import RobotFrames

# plain ints: numpy integers compare equal to MuJoCo's enums, but `in (enum, ...)` does not match
_BOX, _SPHERE, _CAPSULE, _ELLIPSOID, _CYLINDER = (int(mujoco.mjtGeom.mjGEOM_BOX), int(mujoco.mjtGeom.mjGEOM_SPHERE),
                                                  int(mujoco.mjtGeom.mjGEOM_CAPSULE),
                                                  int(mujoco.mjtGeom.mjGEOM_ELLIPSOID),
                                                  int(mujoco.mjtGeom.mjGEOM_CYLINDER))
_HINGE = int(mujoco.mjtJoint.mjJNT_HINGE)


def rpy(quat_wxyz) -> np.ndarray:
    """URDF's fixed-axis roll, pitch, yaw (R = Rz(yaw) Ry(pitch) Rx(roll)) of a wxyz quaternion."""
    mat = np.empty(9)
    mujoco.mju_quat2Mat(mat, np.asarray(quat_wxyz, float))
    r = mat.reshape(3, 3)
    pitch = np.arcsin(-np.clip(r[2, 0], -1.0, 1.0))
    if abs(r[2, 0]) < 1 - 1e-9:
        return np.array([np.arctan2(r[2, 1], r[2, 2]), pitch, np.arctan2(r[1, 0], r[0, 0])])
    return np.array([np.arctan2(-r[1, 2], r[1, 1]), pitch, 0.0])  # gimbal lock: yaw folded into roll


def _origin(pos, quat) -> str:
    xyz = " ".join(f"{v:.9g}" for v in pos)
    return f'<origin xyz="{xyz}" rpy="{" ".join(f"{v:.9g}" for v in rpy(quat))}"/>'


def _visuals(model: mujoco.MjModel, body: int) -> list[str]:
    out = []
    for g in range(model.body_geomadr[body], model.body_geomadr[body] + model.body_geomnum[body]):
        if model.geom_group[g] > 2:
            continue
        kind, size, pos, quat = int(model.geom_type[g]), model.geom_size[g], model.geom_pos[g], model.geom_quat[g]
        mat = model.geom_matid[g]
        rgba = model.mat_rgba[mat] if mat >= 0 else model.geom_rgba[g]
        shapes = []
        if kind == _BOX:
            shapes.append((pos, f'<box size="{2 * size[0]:.9g} {2 * size[1]:.9g} {2 * size[2]:.9g}"/>'))
        elif kind == _SPHERE or kind == _ELLIPSOID:
            shapes.append((pos, f'<sphere radius="{size.max() if kind == _ELLIPSOID else size[0]:.9g}"/>'))
        elif kind == _CYLINDER or kind == _CAPSULE:
            shapes.append((pos, f'<cylinder radius="{size[0]:.9g}" length="{2 * size[1]:.9g}"/>'))
            if kind == _CAPSULE:  # the end caps, at +-half-length along the geom's z
                axis = np.empty(3)
                mujoco.mju_rotVecQuat(axis, np.array([0.0, 0.0, size[1]]), quat)
                shapes += [(pos + s * axis, f'<sphere radius="{size[0]:.9g}"/>') for s in (1, -1)]
        color = " ".join(f"{v:.4g}" for v in rgba)
        for i, (where, geometry) in enumerate(shapes):
            name = quoteattr(f"geom{g}_{i}_color")
            out.append(f"<visual>{_origin(where, quat)}<geometry>{geometry}</geometry>"
                       f"<material name={name}><color rgba=\"{color}\"/></material></visual>")
    return out


def _joint(model: mujoco.MjModel, body: int, parent: str, child: str) -> str:
    count, first = int(model.body_jntnum[body]), int(model.body_jntadr[body])
    kind, extra = "fixed", ""
    if count == 1 and int(model.jnt_type[first]) in DOF_JOINT_TYPES:
        hinge = int(model.jnt_type[first]) == _HINGE
        axis = " ".join(f"{v:.9g}" for v in model.jnt_axis[first])
        extra = f'<axis xyz="{axis}"/>'
        if model.jnt_limited[first]:
            low, high = model.jnt_range[first]
            kind = "revolute" if hinge else "prismatic"
            extra += f'<limit lower="{low:.9g}" upper="{high:.9g}" effort="0" velocity="0"/>'
        else:
            kind = "continuous" if hinge else "prismatic"
            if not hinge:
                extra += '<limit lower="-1e9" upper="1e9" effort="0" velocity="0"/>'
    elif count:
        kind = "floating"
    return (f"<joint name={quoteattr(child + '_joint')} type=\"{kind}\"><parent link={quoteattr(parent)}/>"
            f"<child link={quoteattr(child)}/>{_origin(model.body_pos[body], model.body_quat[body])}{extra}</joint>")


def robot_description(model: mujoco.MjModel, robots: list[RobotFrames], odom: str) -> str:
    """One URDF for ``robots``: rooted at the base link with one robot, at ``odom`` with several."""
    links, joints = [], []
    for robot in robots:
        root = robot.dynamic[0]
        for body, name in robot.frame_of_body.items():
            links.append(f"<link name={quoteattr(name)}>{''.join(_visuals(model, body))}</link>")
            if body == root.body:
                continue
            parent = robot.frame_of_body.get(int(model.body_parentid[body]))
            if parent is not None:
                joints.append(_joint(model, body, parent, name))
        if len(robots) > 1:
            joints.append(f"<joint name={quoteattr(root.child + '_odom_joint')} type=\"floating\">"
                          f"<parent link={quoteattr(odom)}/><child link={quoteattr(root.child)}/></joint>")
    if len(robots) > 1:
        links.insert(0, f"<link name={quoteattr(odom)}/>")
    name = robots[0].name if len(robots) == 1 else "ambulo_scene"
    return (f'<?xml version="1.0"?>\n<robot name={quoteattr(name)}>\n' + "\n".join(links + joints) + "\n</robot>\n")


__all__ = ["robot_description", "rpy"]
