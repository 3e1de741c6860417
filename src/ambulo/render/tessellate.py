"""Triangle meshes of MuJoCo's geom types in the geom's own frame, for renderers that take triangles.

MuJoCo's rasterizer draws primitives from display lists it tessellates itself; a path tracer (and
any other renderer fed by ``scene_description``) needs the same shapes as triangles. Curved
surfaces get smooth vertex normals, so a sphere of ``slices`` x ``stacks`` quads shades as a
sphere; flat faces (box sides, cylinder caps, planes) get face normals.

Every function returns a ``TriangleMesh`` in the geom frame (m): MuJoCo sizes are half-sizes and
radii (``geom_size``), capsules and cylinders lie along the local z axis. Curved primitives also
carry ``surface_uv``: where MuJoCo 4's rasterizer puts a 2-D texture on them at texrepeat 1
(measured on its images, see ``TriangleMesh.surface_uv``), so other renderers put texels where it does.
"""

from __future__ import annotations

from dataclasses import dataclass

import mujoco
import numpy as np


@dataclass
class TriangleMesh:
    """Triangles of one geom in its own frame."""

    positions: np.ndarray
    """(V, 3) float32 vertex positions, m, geom frame."""
    normals: np.ndarray
    """(V, 3) float32 unit vertex normals, geom frame."""
    faces: np.ndarray
    """(F, 3) uint32 vertex indices, counter-clockwise seen from outside."""
    texcoords: np.ndarray | None = None
    """(V, 2) float32 texture coordinates when the model gives them (meshes with UVs), else None."""
    surface_uv: np.ndarray | None = None
    """(V, 2) float32 (u, v) of spheres, ellipsoids, cylinders and capsules at texrepeat 1, v down the
    texture's rows; None for flat primitives and meshes. MuJoCo 4's rasterizer, measured with a
    texture whose texels encode their own (column, row) (``test_tier_textures``): u = azimuth / 2 pi
    from the geom's +x towards +y; v = polar angle / pi from +z on spheres and ellipsoids (the angles
    of the unit sphere it is scaled from), (half-length - z) / length on tubes; each capsule cap spans
    the whole v range by itself (pole 0 to rim 1 on top, rim 0 to pole 1 below); a cylinder cap is
    planar, u = (1 + x / r) / 2, v = (1 + y / r) / 2 on both caps. Texrepeat multiplies both."""


def _grid_faces(rows: int, cols: int, offset: int = 0) -> np.ndarray:
    """Two triangles per cell of a (rows+1) x (cols+1) vertex grid, row-major."""
    r, c = np.meshgrid(np.arange(rows), np.arange(cols), indexing="ij")
    a = (r * (cols + 1) + c).ravel() + offset
    b, d = a + 1, a + cols + 1
    return np.concatenate([np.stack([a, b, d + 1], 1), np.stack([a, d + 1, d], 1)]).astype(np.uint32)


def _mesh(positions, normals, faces, texcoords=None, surface_uv=None) -> TriangleMesh:
    def floats(a):
        return None if a is None else np.asarray(a, np.float32)
    return TriangleMesh(np.asarray(positions, np.float32), np.asarray(normals, np.float32),
                        np.asarray(faces, np.uint32), floats(texcoords), floats(surface_uv))


def _merge(parts: list[TriangleMesh]) -> TriangleMesh:
    offsets = np.cumsum([0] + [len(p.positions) for p in parts[:-1]])
    uv = None if any(p.surface_uv is None for p in parts) else np.concatenate([p.surface_uv for p in parts])
    return _mesh(np.concatenate([p.positions for p in parts]), np.concatenate([p.normals for p in parts]),
                 np.concatenate([p.faces + o for p, o in zip(parts, offsets)]), surface_uv=uv)


def sphere_patch(slices: int, stacks: int, polar_from_rad: float = 0.0, polar_to_rad: float = np.pi,
                 ) -> TriangleMesh:
    """Unit-sphere band between two polar angles (0 = +z pole); smooth normals; ``surface_uv`` of the
    whole sphere (u = azimuth / 2 pi, v = polar / pi; the seam's column twice, at u = 0 and 1)."""
    polar = np.linspace(polar_from_rad, polar_to_rad, stacks + 1)
    azimuth = np.linspace(0.0, 2 * np.pi, slices + 1)
    p, a = np.meshgrid(polar, azimuth, indexing="ij")
    n = np.stack([np.sin(p) * np.cos(a), np.sin(p) * np.sin(a), np.cos(p)], -1).reshape(-1, 3)
    uv = np.stack([a / (2 * np.pi), p / np.pi], -1).reshape(-1, 2)
    return _mesh(n, n, _grid_faces(stacks, slices)[:, ::-1], surface_uv=uv)  # rows run down from +z: flip to face out


def ellipsoid(radii_m, slices: int = 32, stacks: int = 16) -> TriangleMesh:
    """Ellipsoid of semi-axes ``radii_m`` (a sphere when all three are equal)."""
    unit = sphere_patch(slices, stacks)
    radii = np.asarray(radii_m, np.float32)
    normals = unit.normals / radii  # the normal of x^2/a^2 + ... = 1 is (x/a^2, ...)
    normals /= np.linalg.norm(normals, axis=1, keepdims=True)
    return _mesh(unit.positions * radii, normals, unit.faces, surface_uv=unit.surface_uv)


def _disk(radius_m: float, z_m: float, slices: int, up: bool) -> TriangleMesh:
    a = np.linspace(0.0, 2 * np.pi, slices, endpoint=False)
    rim = np.stack([radius_m * np.cos(a), radius_m * np.sin(a), np.full(slices, z_m)], 1)
    pos = np.concatenate([[[0.0, 0.0, z_m]], rim])
    i = np.arange(slices)
    faces = np.stack([np.zeros(slices, int), 1 + i, 1 + (i + 1) % slices], 1)
    if not up:
        faces = faces[:, ::-1]
    uv = 0.5 + 0.5 * pos[:, :2] / radius_m  # planar, the same way up on both caps
    return _mesh(pos, np.tile([0.0, 0.0, 1.0 if up else -1.0], (slices + 1, 1)), faces, surface_uv=uv)


def _tube(radius_m: float, half_length_m: float, slices: int) -> TriangleMesh:
    a = np.linspace(0.0, 2 * np.pi, slices + 1)
    ring = np.stack([np.cos(a), np.sin(a), np.zeros_like(a)], 1)
    pos = np.concatenate([ring * radius_m + [0, 0, half_length_m], ring * radius_m - [0, 0, half_length_m]])
    u = a / (2 * np.pi)
    uv = np.concatenate([np.stack([u, np.zeros_like(u)], 1), np.stack([u, np.ones_like(u)], 1)])  # v: top to bottom
    return _mesh(pos, np.concatenate([ring, ring]), _grid_faces(1, slices)[:, ::-1], surface_uv=uv)


def cylinder(radius_m: float, half_length_m: float, slices: int = 32) -> TriangleMesh:
    """Closed cylinder along z: a smooth tube and two flat caps."""
    return _merge([_tube(radius_m, half_length_m, slices), _disk(radius_m, half_length_m, slices, True),
                   _disk(radius_m, -half_length_m, slices, False)])


def capsule(radius_m: float, half_length_m: float, slices: int = 32, stacks: int = 16) -> TriangleMesh:
    """Capsule along z: a tube of ``2 half_length_m`` between two hemispheres."""
    parts = []
    for sign, (lo, hi) in ((1.0, (0.0, np.pi / 2)), (-1.0, (np.pi / 2, np.pi))):
        cap = sphere_patch(slices, stacks // 2, lo, hi)
        uv = cap.surface_uv * [1.0, 2.0] - [0.0, 0.0 if sign > 0 else 1.0]  # each cap spans v in [0, 1]
        parts.append(_mesh(cap.positions * radius_m + [0.0, 0.0, sign * half_length_m], cap.normals, cap.faces,
                           surface_uv=uv))
    return _merge([parts[0], _tube(radius_m, half_length_m, slices), parts[1]])


def box(half_sizes_m) -> TriangleMesh:
    """Box of half-sizes ``half_sizes_m``: 6 faces of 4 vertices each (flat normals)."""
    h = np.asarray(half_sizes_m, float)
    parts = []
    for axis in range(3):
        u, v = (axis + 1) % 3, (axis + 2) % 3  # (u, v, axis) is right-handed
        for sign in (1.0, -1.0):
            corners = np.zeros((4, 3))
            corners[:, axis] = sign * h[axis]
            corners[:, u] = np.array([-1, 1, 1, -1]) * h[u]
            corners[:, v] = np.array([-1, -1, 1, 1]) * h[v] * sign
            normal = np.zeros(3)
            normal[axis] = sign
            parts.append(_mesh(corners, np.tile(normal, (4, 1)), [[0, 1, 2], [0, 2, 3]]))
    return _merge(parts)


def plane(half_x_m: float, half_y_m: float) -> TriangleMesh:
    """The z = 0 rectangle facing +z."""
    pos = [[-half_x_m, -half_y_m, 0], [half_x_m, -half_y_m, 0], [half_x_m, half_y_m, 0], [-half_x_m, half_y_m, 0]]
    return _mesh(pos, np.tile([0.0, 0.0, 1.0], (4, 1)), [[0, 1, 2], [0, 2, 3]])


def heightfield(model: mujoco.MjModel, hfield_id: int) -> TriangleMesh:
    """The top surface of height field ``hfield_id``: x spans columns, y rows (MuJoCo's layout)."""
    rows, cols = int(model.hfield_nrow[hfield_id]), int(model.hfield_ncol[hfield_id])
    sx, sy, sz, _ = model.hfield_size[hfield_id]
    adr = int(model.hfield_adr[hfield_id])
    z = model.hfield_data[adr:adr + rows * cols].reshape(rows, cols) * sz
    y, x = np.meshgrid(np.linspace(-sy, sy, rows), np.linspace(-sx, sx, cols), indexing="ij")
    pos = np.stack([x, y, z], -1).reshape(-1, 3)
    dz_dy, dz_dx = np.gradient(z, y[:, 0], x[0])
    normals = np.stack([-dz_dx, -dz_dy, np.ones_like(z)], -1).reshape(-1, 3)
    normals /= np.linalg.norm(normals, axis=1, keepdims=True)
    return _mesh(pos, normals, _grid_faces(rows - 1, cols - 1))


def model_mesh(model: mujoco.MjModel, mesh_id: int) -> TriangleMesh:
    """Mesh ``mesh_id`` as compiled (geom frame), one vertex per face corner.

    MuJoCo indexes positions, normals and UVs of a face corner separately (``mesh_face``,
    ``mesh_facenormal``, ``mesh_facetexcoord``); renderers want one index per vertex, so the
    corners are unshared.
    """
    vadr, fadr, fnum = int(model.mesh_vertadr[mesh_id]), int(model.mesh_faceadr[mesh_id]), int(model.mesh_facenum[mesh_id])
    corners = model.mesh_face[fadr:fadr + fnum].ravel()
    pos = model.mesh_vert[vadr + corners]
    nadr = int(model.mesh_normaladr[mesh_id])
    normals = model.mesh_normal[nadr + model.mesh_facenormal[fadr:fadr + fnum].ravel()]
    texcoords = None
    if model.mesh_texcoordnum[mesh_id] > 0:
        tadr = int(model.mesh_texcoordadr[mesh_id])
        texcoords = model.mesh_texcoord[tadr + model.mesh_facetexcoord[fadr:fadr + fnum].ravel()]
    return _mesh(pos, normals, np.arange(3 * fnum).reshape(-1, 3), texcoords)


def geom_mesh(model: mujoco.MjModel, geom_type: int, size_m, data_id: int, *,
              infinite_half_m: float, slices: int = 32, stacks: int = 16) -> TriangleMesh | None:
    """The triangles of a geom of ``geom_type`` and ``size_m``; None for types drawn otherwise.

    ``data_id``: the mesh or height field id (``geom_dataid``). ``infinite_half_m``: the half
    extent given to a plane of size 0, which MuJoCo draws out to the far clip plane.
    """
    t = mujoco.mjtGeom
    s = np.asarray(size_m, float)
    if geom_type == t.mjGEOM_PLANE:
        return plane(s[0] if s[0] > 0 else infinite_half_m, s[1] if s[1] > 0 else infinite_half_m)
    if geom_type == t.mjGEOM_SPHERE:
        return ellipsoid((s[0],) * 3, slices, stacks)
    if geom_type == t.mjGEOM_ELLIPSOID:
        return ellipsoid(s, slices, stacks)
    if geom_type == t.mjGEOM_CAPSULE:
        return capsule(s[0], s[1], slices, stacks)
    if geom_type == t.mjGEOM_CYLINDER:
        return cylinder(s[0], s[1], slices)
    if geom_type == t.mjGEOM_BOX:
        return box(s)
    if geom_type in (t.mjGEOM_MESH, t.mjGEOM_SDF) and data_id >= 0:
        return model_mesh(model, data_id)
    if geom_type == t.mjGEOM_HFIELD and data_id >= 0:
        return heightfield(model, data_id)
    return None


__all__ = ["TriangleMesh", "box", "capsule", "cylinder", "ellipsoid", "geom_mesh", "heightfield", "model_mesh",
           "plane", "sphere_patch"]
