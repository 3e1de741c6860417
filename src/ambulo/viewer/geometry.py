"""The scene's shapes from a compiled ``MjModel``: one triangle mesh per visible geom, in its body's
frame, with its colour. Built once per model and sent to the browser once; afterwards only body
poses travel.

Visible means what MuJoCo's own viewer shows by default: geom groups 0-2 (group 3 and up hold
collision-only geoms by convention) and alpha > 0. A geom with a material and the default rgba
takes the material's colour, as ``mjv_updateScene`` does. Textures are not sent (flat colours).
Planes become a finite square (MuJoCo's "infinite" plane, size 0, is drawn 20 m wide).
"""

from __future__ import annotations

from dataclasses import dataclass

import mujoco
import numpy as np
import trimesh

from ..utils.rotations import quat_to_mat

VISIBLE_GROUPS = (0, 1, 2)
"""Geom groups MuJoCo's viewer shows by default (``mjvOption.geomgroup``)."""

DEFAULT_RGBA = (0.5, 0.5, 0.5, 1.0)
"""MuJoCo's default ``geom_rgba``: a geom left at it shows its material's colour."""

INFINITE_PLANE_HALF_M = 10.0
"""Half width of a plane whose size is 0 (infinite in MuJoCo)."""


@dataclass(frozen=True)
class GeomShape:
    """One visible geom as a mesh in its body's frame.

    Attributes:
      geom_id, body_id: ids in the model.
      vertices_b: (V, 3) float32, m, body frame (the geom's pose is applied).
      faces: (F, 3) int32 vertex indices.
      rgba: (4,) float in [0, 1].
      is_plane: a ground plane (drawn with a grid on it).
    """

    geom_id: int
    body_id: int
    vertices_b: np.ndarray
    faces: np.ndarray
    rgba: tuple[float, float, float, float]
    is_plane: bool


def geom_rgba(model: mujoco.MjModel, geom: int) -> tuple[float, float, float, float]:
    """The colour MuJoCo draws ``geom`` with: its material's if it has one and kept the default rgba."""
    rgba = model.geom_rgba[geom]
    mat = int(model.geom_matid[geom])
    if mat >= 0 and np.allclose(rgba, DEFAULT_RGBA):
        rgba = model.mat_rgba[mat]
    return tuple(float(c) for c in rgba)


def _primitive(model: mujoco.MjModel, geom: int) -> trimesh.Trimesh | None:
    """The geom's shape in its own frame (MuJoCo's axes: capsules and cylinders along z)."""
    kind, size = int(model.geom_type[geom]), model.geom_size[geom]
    t = mujoco.mjtGeom
    if kind == t.mjGEOM_PLANE:
        hx = size[0] if size[0] > 0 else INFINITE_PLANE_HALF_M
        hy = size[1] if size[1] > 0 else INFINITE_PLANE_HALF_M
        vertices = np.array([[-hx, -hy, 0], [hx, -hy, 0], [hx, hy, 0], [-hx, hy, 0]], dtype=np.float64)
        return trimesh.Trimesh(vertices, np.array([[0, 1, 2], [0, 2, 3]]), process=False)
    if kind == t.mjGEOM_BOX:
        return trimesh.creation.box(extents=2.0 * size[:3])
    if kind == t.mjGEOM_SPHERE:
        return trimesh.creation.icosphere(subdivisions=2, radius=size[0])
    if kind == t.mjGEOM_ELLIPSOID:
        mesh = trimesh.creation.icosphere(subdivisions=2, radius=1.0)
        mesh.vertices = mesh.vertices * size[:3]
        return mesh
    if kind == t.mjGEOM_CAPSULE:  # size: radius, half length of the cylinder part
        return trimesh.creation.capsule(height=2.0 * size[1], radius=size[0], count=[16, 8])
    if kind == t.mjGEOM_CYLINDER:
        return trimesh.creation.cylinder(radius=size[0], height=2.0 * size[1], sections=20)
    if kind == t.mjGEOM_MESH:
        mesh_id = int(model.geom_dataid[geom])
        v0, nv = int(model.mesh_vertadr[mesh_id]), int(model.mesh_vertnum[mesh_id])
        f0, nf = int(model.mesh_faceadr[mesh_id]), int(model.mesh_facenum[mesh_id])
        # compiled mesh vertices are in the geom's frame (MuJoCo moved the mesh to its inertial frame
        # and put that offset into geom_pos/geom_quat)
        return trimesh.Trimesh(model.mesh_vert[v0:v0 + nv].copy(), model.mesh_face[f0:f0 + nf].copy(), process=False)
    return None  # heightfields and SDF geoms: not drawn yet


def visible_geoms(model: mujoco.MjModel) -> list[int]:
    """Ids of the geoms MuJoCo's viewer shows by default."""
    return [g for g in range(model.ngeom)
            if int(model.geom_group[g]) in VISIBLE_GROUPS and geom_rgba(model, g)[3] > 0.0]


def geom_shapes(model: mujoco.MjModel) -> list[GeomShape]:
    """Every visible geom as a ``GeomShape`` (geoms of kinds not drawn are left out)."""
    shapes = []
    for g in visible_geoms(model):
        mesh = _primitive(model, g)
        if mesh is None:
            continue
        rot_b = quat_to_mat(model.geom_quat[g])
        vertices_b = np.asarray(mesh.vertices) @ rot_b.T + model.geom_pos[g]
        shapes.append(GeomShape(
            geom_id=g, body_id=int(model.geom_bodyid[g]), vertices_b=vertices_b.astype(np.float32),
            faces=np.asarray(mesh.faces, dtype=np.int32), rgba=geom_rgba(model, g),
            is_plane=int(model.geom_type[g]) == mujoco.mjtGeom.mjGEOM_PLANE))
    return shapes


GROUND_MIN_M = 2.0
"""A horizontal plane at least this wide is ground (below: a decor plane)."""


def is_ground(shape: GeomShape) -> bool:
    """A plane lying flat (in its body's frame: ground planes hang from the world) and wide."""
    if not shape.is_plane:
        return False
    v = shape.vertices_b
    span = v.max(axis=0) - v.min(axis=0)
    return bool(span[2] < 1e-6 and min(span[0], span[1]) >= GROUND_MIN_M)


def static_bodies(model: mujoco.MjModel) -> np.ndarray:
    """(nbody,) bool: bodies welded to the world (they never move, so their poses are sent once)."""
    return (model.body_weldid == 0) & (model.body_mocapid < 0)


def body_name(model: mujoco.MjModel, body: int) -> str:
    return mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_BODY, body) or f"body_{body}"


def root_bodies(model: mujoco.MjModel) -> list[int]:
    """Bodies that move and hang from the world: one per robot or free object (the pose read-out's rows)."""
    moving = ~static_bodies(model)
    return [b for b in range(1, model.nbody) if int(model.body_parentid[b]) == 0 and moving[b]]


def subtree(model: mujoco.MjModel, root: int) -> list[int]:
    """``root`` and every body below it."""
    return [b for b in range(model.nbody) if int(model.body_rootid[b]) == int(model.body_rootid[root])
            and _descends(model, b, root)]


def _descends(model: mujoco.MjModel, body: int, ancestor: int) -> bool:
    while body != ancestor and body != 0:
        body = int(model.body_parentid[body])
    return body == ancestor
