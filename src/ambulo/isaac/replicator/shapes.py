"""How a Replicator primitive becomes MuJoCo geoms: types, sizes and placements for a scale.

Replicator's primitives are Kit's mesh primitives, 100 cm across on a centimetre stage; ambulo's
are the same shapes 1 m across at scale 1 (MuJoCo sizes are half-extents and radii). MuJoCo has
no torus or cone geom, so:

- a torus (Kit's: tube radius 25 cm around a 50 cm ring, axis along z: 1.5 m across, 0.5 m tall)
  is a ring of ``TORUS_SEGMENTS`` capsules whose axes are the chords between Kit's 32 ring
  vertices, so its extent along x, y and z is the torus's exactly and its surface lies within
  ``R (1 - cos(pi/32))`` = 2.4 mm (at scale 1) of the smooth torus; the normals annotator's
  (the capsules' exact normals) are within 11.2 deg of the smooth torus's. Capsules are primitives, so a
  uniform scale per frame rewrites their sizes and positions (``geom_size``/``geom_pos``, both
  per world on the CPU and mujoco_warp engines); a non-uniform scale would make the tube
  elliptical, which capsules cannot be, and is refused.
- a cone (Kit's: 1 m tall, 1 m across its base, apex up along z, centred on its prim) is a
  mesh of ``CONE_SEGMENTS`` sides. MuJoCo fixes a mesh's vertices when the scene compiles (the
  renderers upload them once), so a cone takes its scale at ``rep.create.cone(scale=...)`` and a
  per-frame ``rep.modify.pose(scale=...)`` on a cone is refused.
"""

from __future__ import annotations

from dataclasses import dataclass

import mujoco
import numpy as np

from ambulo.utils.rotations import mat_to_quat

SLAB_HALF_M = 0.0005
"""Half thickness (m) of planes and disks: 1 mm, thin enough to read as flat, solid for scatter."""
TORUS_RING_M, TORUS_TUBE_M = 0.5, 0.25
"""Torus ring (centre of the tube) and tube radii at scale 1, m: Kit's 1.0 and 0.5 x its 50 cm half scale."""
TORUS_SEGMENTS = 32
"""Capsules around a torus: Kit's torus mesh has 32 vertices around its ring."""
CONE_SEGMENTS = 48
"""Sides of a cone's mesh (a multiple of 4, so its base reaches +-0.5 m along x and y exactly)."""

_TYPES = {"cube": mujoco.mjtGeom.mjGEOM_BOX, "sphere": mujoco.mjtGeom.mjGEOM_ELLIPSOID,
          "cylinder": mujoco.mjtGeom.mjGEOM_CYLINDER, "disk": mujoco.mjtGeom.mjGEOM_CYLINDER,
          "plane": mujoco.mjtGeom.mjGEOM_BOX, "torus": mujoco.mjtGeom.mjGEOM_CAPSULE,
          "cone": mujoco.mjtGeom.mjGEOM_MESH}
FIXED_SIZE = ("cone",)
"""Kinds whose size is fixed when the scene compiles (meshes): no per-frame or per-run drawn scale."""
UNIFORM_SCALE = ("torus",)
"""Kinds that take only a uniform scale (one number)."""
ROUND_XY = ("cylinder", "disk")
"""Kinds that scale x and y together."""


@dataclass(frozen=True)
class GeomPart:
    """One MuJoCo geom of a primitive, in its prim's frame."""

    size: np.ndarray
    """(3,) MuJoCo size (half-extents, radii, capsule half-length), m."""
    pos_m: np.ndarray
    """(3,) centre in the prim frame, m."""
    quat: np.ndarray
    """(4,) w, x, y, z orientation in the prim frame."""


def geom_type(kind: str) -> mujoco.mjtGeom:
    return _TYPES[kind]


def _scale3(scale) -> tuple[float, float, float]:
    sx, sy, sz = (float(v) for v in np.broadcast_to(np.asarray(scale, float), (3,)))
    return sx, sy, sz


def geom_size(kind: str, scale) -> np.ndarray:
    """MuJoCo size (3,) of a one-geom ``kind`` primitive at ``scale`` (sx, sy, sz)."""
    sx, sy, sz = _scale3(scale)
    if kind in ("cube", "sphere"):
        return np.array([sx, sy, sz]) / 2
    if kind == "cylinder":
        return np.array([sx / 2, sz / 2, 0.0])
    if kind == "disk":
        return np.array([sx / 2, SLAB_HALF_M, 0.0])
    if kind == "plane":
        return np.array([sx / 2, sy / 2, SLAB_HALF_M])
    raise ValueError(f"no single geom for a {kind!r} prim")


def geom_offset_z(kind: str) -> float:
    """Where the geom sits below its prim: a plane's top face is at the prim's position."""
    return -SLAB_HALF_M if kind == "plane" else 0.0


def geom_parts(kind: str, scale) -> list[GeomPart]:
    """The geoms of a ``kind`` primitive at ``scale`` (not cones: see ``cone_mesh``)."""
    if kind == "torus":
        return torus_capsules(float(np.mean(_scale3(scale))))
    if kind == "cone":
        raise ValueError("a cone is one mesh geom: build it from cone_mesh(scale)")
    return [GeomPart(geom_size(kind, scale), np.array([0.0, 0.0, geom_offset_z(kind)]), np.array([1.0, 0, 0, 0]))]


def torus_capsules(scale: float) -> list[GeomPart]:
    """``TORUS_SEGMENTS`` capsules along the chords of the ring, x uniform ``scale``."""
    n = TORUS_SEGMENTS
    ring, half_chord = TORUS_RING_M * scale, TORUS_RING_M * scale * np.sin(np.pi / n)
    parts = []
    for k in range(n):
        mid = 2 * np.pi * (k + 0.5) / n  # chord from vertex k (angle 2 pi k / n) to vertex k + 1
        radial = np.array([np.cos(mid), np.sin(mid), 0.0])
        tangent = np.array([-np.sin(mid), np.cos(mid), 0.0])
        rot = np.stack([[0.0, 0.0, 1.0], radial, tangent], axis=1)  # capsule z along the chord
        parts.append(GeomPart(np.array([TORUS_TUBE_M * scale, half_chord, 0.0]),
                              radial * ring * np.cos(np.pi / n), mat_to_quat(rot)))
    return parts


def cone_mesh(scale) -> tuple[np.ndarray, np.ndarray]:
    """A cone's vertices (V, 3) m in its prim frame and faces (F, 3) int, outward, at ``scale``:
    apex at z = +0.5 sz, base circle (radius 0.5 sx, 0.5 sy) at z = -0.5 sz."""
    sx, sy, sz = _scale3(scale)
    angles = 2 * np.pi * np.arange(CONE_SEGMENTS) / CONE_SEGMENTS
    rim = np.c_[0.5 * sx * np.cos(angles), 0.5 * sy * np.sin(angles), np.full(CONE_SEGMENTS, -0.5 * sz)]
    verts = np.vstack([rim, [[0.0, 0.0, 0.5 * sz], [0.0, 0.0, -0.5 * sz]]])
    apex, base = CONE_SEGMENTS, CONE_SEGMENTS + 1
    k = np.arange(CONE_SEGMENTS)
    nxt = (k + 1) % CONE_SEGMENTS
    sides = np.c_[k, nxt, np.full_like(k, apex)]  # counter-clockwise seen from outside
    bottom = np.c_[nxt, k, np.full_like(k, base)]
    return verts, np.vstack([sides, bottom]).astype(np.int32)


def euler_xyz_deg_to_mat(angles_deg) -> np.ndarray:
    """(3, 3) rotation of USD's ``rotateXYZ`` (x first, then y, then z, about fixed axes): Rz Ry Rx."""
    x, y, z = np.radians(np.asarray(angles_deg, float))
    cx, sx, cy, sy, cz, sz = np.cos(x), np.sin(x), np.cos(y), np.sin(y), np.cos(z), np.sin(z)
    rx = np.array([[1, 0, 0], [0, cx, -sx], [0, sx, cx]])
    ry = np.array([[cy, 0, sy], [0, 1, 0], [-sy, 0, cy]])
    rz = np.array([[cz, -sz, 0], [sz, cz, 0], [0, 0, 1]])
    return rz @ ry @ rx
