"""How a Replicator primitive becomes a MuJoCo geom: type and size for a scale, and XYZ Euler angles.

Replicator primitives are 1 m across at scale 1; MuJoCo sizes are half-extents and radii.
"""

from __future__ import annotations

import mujoco
import numpy as np

SLAB_HALF_M = 0.0005
"""Half thickness (m) of planes and disks: 1 mm, thin enough to read as flat, solid for scatter."""

_TYPES = {"cube": mujoco.mjtGeom.mjGEOM_BOX, "sphere": mujoco.mjtGeom.mjGEOM_ELLIPSOID,
          "cylinder": mujoco.mjtGeom.mjGEOM_CYLINDER, "disk": mujoco.mjtGeom.mjGEOM_CYLINDER,
          "plane": mujoco.mjtGeom.mjGEOM_BOX}


def geom_type(kind: str) -> mujoco.mjtGeom:
    return _TYPES[kind]


def geom_size(kind: str, scale) -> np.ndarray:
    """MuJoCo size (3,) of a ``kind`` primitive at ``scale`` (sx, sy, sz)."""
    sx, sy, sz = (float(v) for v in np.broadcast_to(np.asarray(scale, float), (3,)))
    if kind in ("cube", "sphere"):
        return np.array([sx, sy, sz]) / 2
    if kind == "cylinder":
        return np.array([sx / 2, sz / 2, 0.0])
    if kind == "disk":
        return np.array([sx / 2, SLAB_HALF_M, 0.0])
    if kind == "plane":
        return np.array([sx / 2, sy / 2, SLAB_HALF_M])
    raise ValueError(f"no geom for a {kind!r} prim")


def geom_offset_z(kind: str) -> float:
    """Where the geom sits below its prim: a plane's top face is at the prim's position."""
    return -SLAB_HALF_M if kind == "plane" else 0.0


def euler_xyz_deg_to_mat(angles_deg) -> np.ndarray:
    """(3, 3) rotation of USD's ``rotateXYZ`` (x first, then y, then z, about fixed axes): Rz Ry Rx."""
    x, y, z = np.radians(np.asarray(angles_deg, float))
    cx, sx, cy, sy, cz, sz = np.cos(x), np.sin(x), np.cos(y), np.sin(y), np.cos(z), np.sin(z)
    rx = np.array([[1, 0, 0], [0, cx, -sx], [0, sx, cx]])
    ry = np.array([[cy, 0, sy], [0, 1, 0], [-sy, 0, cy]])
    rz = np.array([[cz, -sz, 0], [sz, cz, 0], [0, 0, 1]])
    return rz @ ry @ rx
