"""Exact geometry of MuJoCo's primitive geoms: surface normals at rendered points, extents in a body frame.

MuJoCo's renderer gives colour, depth and a geom id per pixel, but no normals. A pixel's geom id
and its point back-projected from depth give the normal from the geom's analytic shape: exact on
planes, boxes (their edges included, where depth differences would mix two faces), spheres,
ellipsoids, capsules and cylinders. Meshes, height fields and SDFs fall back to depth differences
taken between pixels of the same geom.

Extents are the support function of each shape along a body's axes: the tight axis-aligned box of
the geom in that body's frame (meshes from their vertices), where MuJoCo's ``geom_aabb`` corners
would over-cover a sphere or cylinder turned inside its body.
"""

from __future__ import annotations

import mujoco
import numpy as np

from .annotators import points_from_depth

_G = mujoco.mjtGeom
_ANALYTIC = (_G.mjGEOM_PLANE, _G.mjGEOM_BOX, _G.mjGEOM_SPHERE, _G.mjGEOM_ELLIPSOID, _G.mjGEOM_CAPSULE,
             _G.mjGEOM_CYLINDER)


def surface_normals_w(geom_ids: np.ndarray, depth: np.ndarray, k_matrix: np.ndarray, extrinsics_cw: np.ndarray,
                      model: mujoco.MjModel, geom_pos_w: np.ndarray, geom_rot_w: np.ndarray) -> np.ndarray:
    """(H, W, 3) float32 unit outward surface normals in the world frame; 0 where nothing is hit.

    ``geom_ids`` (H, W) int (-1: none) and ``depth`` (H, W) m to the image plane come from one
    render; ``k_matrix`` (3, 3) is OpenCV's (pixel centres at integers), ``extrinsics_cw`` (4, 4)
    maps world to the OpenCV camera; ``geom_pos_w`` (ngeom, 3) and ``geom_rot_w`` (ngeom, 3, 3)
    are the geoms' poses at that render.
    """
    out = np.zeros(depth.shape + (3,), np.float32)
    hit = (geom_ids >= 0) & np.isfinite(depth)
    if not hit.any():
        return out
    rot_cw, t_cw = extrinsics_cw[:3, :3], extrinsics_cw[:3, 3]
    p_w = (points_from_depth(np.where(hit, depth, 0.0), k_matrix)[hit] - t_cw) @ rot_cw
    g = geom_ids[hit]
    rot = geom_rot_w[g]
    local = np.einsum("pji,pj->pi", rot, p_w - geom_pos_w[g])  # R_g^T (p - c): the point in the geom frame
    n_local = _normals_local(model.geom_type[g], model.geom_size[g], local)
    n_w = np.einsum("pij,pj->pi", rot, n_local)
    fallback = ~np.isin(model.geom_type[g], _ANALYTIC)
    if fallback.any():  # meshes and height fields: differences of points on the same geom
        n_depth_w = _depth_normals(geom_ids, depth, k_matrix) @ rot_cw
        n_w[fallback] = np.nan_to_num(n_depth_w[hit][fallback])
    out[hit] = n_w
    return out


def _normals_local(types: np.ndarray, size: np.ndarray, p: np.ndarray) -> np.ndarray:
    """(P, 3) outward normals in each geom's frame at points ``p`` (P, 3) on geoms of ``types``."""
    n = np.zeros_like(p)
    n[:, 2] = 1.0  # planes face +z (and the fallback rows, overwritten by the caller)
    box = types == _G.mjGEOM_BOX
    if box.any():  # the face the point lies on is the axis where it is relatively farthest out
        ratio = np.abs(p[box]) / np.maximum(size[box], 1e-12)
        axis = ratio.argmax(1)
        face = np.zeros((box.sum(), 3))
        face[np.arange(len(axis)), axis] = np.sign(p[box][np.arange(len(axis)), axis])
        n[box] = face
    sphere = types == _G.mjGEOM_SPHERE
    n[sphere] = p[sphere]
    ellipsoid = types == _G.mjGEOM_ELLIPSOID  # gradient of sum (x_i / a_i)^2
    n[ellipsoid] = p[ellipsoid] / np.maximum(size[ellipsoid], 1e-12) ** 2
    capsule = types == _G.mjGEOM_CAPSULE  # away from the nearest point of the axis segment
    if capsule.any():
        axis_point = np.zeros((capsule.sum(), 3))
        axis_point[:, 2] = np.clip(p[capsule, 2], -size[capsule, 1], size[capsule, 1])
        n[capsule] = p[capsule] - axis_point
    cylinder = types == _G.mjGEOM_CYLINDER
    if cylinder.any():  # a cap where the point is nearer the cap plane than the side surface
        q, radius, half = p[cylinder], size[cylinder, 0], size[cylinder, 1]
        radial = np.hypot(q[:, 0], q[:, 1])
        on_cap = np.abs(np.abs(q[:, 2]) - half) < np.abs(radial - radius)
        n[cylinder] = np.where(on_cap[:, None], np.c_[np.zeros((len(q), 2)), np.sign(q[:, 2])],
                               np.c_[q[:, :2], np.zeros(len(q))])
    norm = np.linalg.norm(n, axis=1, keepdims=True)
    return n / np.where(norm > 0, norm, 1.0)


def _depth_normals(geom_ids: np.ndarray, depth: np.ndarray, k_matrix: np.ndarray) -> np.ndarray:
    """(H, W, 3) OpenCV-camera-frame normals facing the camera, from back-projected point
    differences toward neighbours on the same geom (so a silhouette never mixes two surfaces);
    of two such neighbours along an axis, the one at the closer depth. NaN where undefined."""
    p = points_from_depth(np.where(np.isfinite(depth), depth, np.nan), k_matrix)
    n = np.cross(_same_geom_difference(p, geom_ids, 0), _same_geom_difference(p, geom_ids, 1))
    n /= np.linalg.norm(n, axis=-1, keepdims=True)
    return np.where(np.sum(n * p, -1, keepdims=True) > 0, -n, n)


def _same_geom_difference(p: np.ndarray, geom_ids: np.ndarray, axis: int) -> np.ndarray:
    ahead = tuple(slice(1, None) if a == axis else slice(None) for a in range(2))
    behind = tuple(slice(None, -1) if a == axis else slice(None) for a in range(2))
    step = np.where((geom_ids[ahead] == geom_ids[behind])[..., None], p[ahead] - p[behind], np.nan)
    fwd, bwd = np.full_like(p, np.nan), np.full_like(p, np.nan)
    fwd[behind], bwd[ahead] = step, step
    use_fwd = ~(np.abs(bwd[..., 2]) < np.abs(fwd[..., 2])) & ~np.isnan(fwd[..., 2])
    return np.where(use_fwd[..., None], fwd, bwd)


def geom_extents_b(geoms: np.ndarray, model: mujoco.MjModel, pos_b: np.ndarray, rot_b: np.ndarray,
                   geom_size: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Tight box of each geom along a body's axes: ``lo``, ``hi`` (G, 3) m in the body frame.

    ``pos_b`` (G, 3) and ``rot_b`` (G, 3, 3) are the geoms' poses in that body's frame;
    ``geom_size`` (ngeom, 3) the sizes if randomized away from ``model``'s. Planes, height fields
    and SDFs use MuJoCo's ``geom_aabb`` corners.
    """
    types = model.geom_type[geoms]
    size = (model.geom_size if geom_size is None else geom_size)[geoms]
    a = np.abs(rot_b)
    half = np.einsum("gij,gj->gi", a, model.geom_aabb[geoms, 3:])  # generic: the local AABB turned
    center = pos_b + np.einsum("gij,gj->gi", rot_b, model.geom_aabb[geoms, :3])
    box = types == _G.mjGEOM_BOX
    half[box] = np.einsum("gij,gj->gi", a[box], size[box])
    sphere = types == _G.mjGEOM_SPHERE
    half[sphere] = size[sphere, :1]
    ell = types == _G.mjGEOM_ELLIPSOID
    half[ell] = np.sqrt(np.einsum("gij,gj->gi", rot_b[ell] ** 2, size[ell] ** 2))
    for kind, cap in ((_G.mjGEOM_CYLINDER, False), (_G.mjGEOM_CAPSULE, True)):
        sel = types == kind
        axis_z = a[sel][:, :, 2]  # |body axis i . geom z|
        radius, length = size[sel, :1], size[sel, 1:2]
        across = radius if cap else radius * np.sqrt(np.clip(1.0 - axis_z ** 2, 0.0, None))
        half[sel] = length * axis_z + across
    for k in np.flatnonzero(types == _G.mjGEOM_MESH):  # the vertices themselves: exact
        mesh = model.geom_dataid[geoms[k]]
        start, count = model.mesh_vertadr[mesh], model.mesh_vertnum[mesh]
        verts_b = model.mesh_vert[start:start + count] @ rot_b[k].T + pos_b[k]
        lo, hi = verts_b.min(0), verts_b.max(0)
        center[k], half[k] = (lo + hi) / 2, (hi - lo) / 2
    return center - half, center + half


def instance_extents_b(table, model: mujoco.MjModel, body_pos_w: np.ndarray, body_rot_w: np.ndarray,
                       geom_pos_w: np.ndarray, geom_rot_w: np.ndarray,
                       geom_size: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Tight box of each instance's geoms in its labelled body's frame: ``lo``, ``hi`` (K, 3) m
    (0 for an instance without geoms). ``table`` is ``annotators.InstanceTable``; poses are one
    world's: bodies (nbody, 3) / (nbody, 3, 3), geoms (ngeom, 3) / (ngeom, 3, 3)."""
    k = table.num_instances
    lo_k, hi_k = np.zeros((k, 3)), np.zeros((k, 3))
    geoms, owner = table.instance_geoms
    if len(geoms) == 0:
        return lo_k, hi_k
    bodies = table.body_ids[owner - 1]
    rot_t = np.swapaxes(body_rot_w[bodies], 1, 2)
    pos_b = np.einsum("gij,gj->gi", rot_t, geom_pos_w[geoms] - body_pos_w[bodies])
    lo, hi = geom_extents_b(geoms, model, pos_b, rot_t @ geom_rot_w[geoms], geom_size)
    starts = np.flatnonzero(np.r_[True, owner[1:] != owner[:-1]])
    idx = owner[starts] - 1
    lo_k[idx] = np.minimum.reduceat(lo, starts)
    hi_k[idx] = np.maximum.reduceat(hi, starts)
    return lo_k, hi_k
