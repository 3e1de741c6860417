"""Ground-truth occupancy of a user's world: the static geoms that meet the humanoid's body band,
rasterized on a 2-D grid (``maps.Grid2D``, ROS's cell convention).

The rule is the apartments' (``scenes.apartment``): a solid blocks the cells under it iff its top
is above ``step_height_m`` and its bottom below ``head_height_m``; a cell is OCCUPIED iff its
square (less 1 micrometre a side) meets the solid's footprint. How exact each footprint is:

- box (any orientation): the convex hull of its 8 corners seen from above: exact;
- sphere: a disc of its radius: exact when its centre lies in the band (a superset otherwise);
- capsule (any orientation): the segment between its end centres grown by the radius: exact;
- cylinder: upright, a disc: exact; tilted, the hull of 32 points on each rim circle: inside the
  true outline by at most r (1 - cos(pi / 32)) = 0.5 % of the radius;
- ellipsoid, mesh, height field, SDF: the hull of the corners of MuJoCo's oriented bounding box
  (``geom_aabb``): a superset of the true footprint.

Planes are the ground and never block. Geoms that collide with nothing (``contype`` and
``conaffinity`` both 0, visual-only) are left out: the robot cannot touch them. Bodies that move
(free joints, mocap) are taken where the compiled model puts them at its initial state.

**Extent.** The map covers the blocking solids and the points the caller names (the start, the
goal) grown by ``margin_m``, and the world's finite floor planes (up to ``floor_reach_m`` beyond
that box). When every floor plane is finite (a user's ``<geom type="plane" size="6 6 .1"/>``), a
cell over none of them is OCCUPIED: there is nothing to stand on, so no route or goal goes there.
A floor plane is a colliding plane facing up at or below ``step_height_m``.
"""

from __future__ import annotations

import math

import mujoco
import numpy as np

from ..maps import Grid2D
from ..robots import humanoid
from ..scenes.apartment_geometry import point_segment_distance
from ..utils.checks import InvalidValueError

_EPS_M = 1e-6
"""Cells shrink by this a side, so a face on a cell border occupies one cell, not two."""
_RIM_POINTS = 32


def static_geoms(model: mujoco.MjModel, data: mujoco.MjData, exclude_prefix: str) -> list[int]:
    """Ids of the geoms that can block: colliding, not planes, not under ``exclude_prefix`` (the robot)."""
    out = []
    for g in range(model.ngeom):
        if model.geom_type[g] == mujoco.mjtGeom.mjGEOM_PLANE:
            continue
        if model.geom_contype[g] == 0 and model.geom_conaffinity[g] == 0:
            continue
        body = model.geom_bodyid[g]
        if model.body(body).name.startswith(exclude_prefix + "/") or model.geom(g).name.startswith(exclude_prefix + "/"):
            continue
        out.append(g)
    return out


def floor_planes(model: mujoco.MjModel, data: mujoco.MjData, step_height_m: float) -> tuple[list[np.ndarray], bool]:
    """(outlines, infinite): the (4, 2) corners of each finite floor plane seen from above, and whether
    any floor plane is infinite (a size of 0 in x or y is MuJoCo's infinite plane)."""
    out, infinite = [], False
    for g in np.flatnonzero(model.geom_type == mujoco.mjtGeom.mjGEOM_PLANE):
        if model.geom_contype[g] == 0 and model.geom_conaffinity[g] == 0:
            continue
        rot = data.geom_xmat[g].reshape(3, 3)
        if rot[2, 2] < 1.0 - 1e-6 or data.geom_xpos[g, 2] > step_height_m:  # not a floor: tilted, facing down, high
            continue
        sx, sy = (float(v) for v in model.geom_size[g, :2])
        if sx <= 0 or sy <= 0:
            infinite = True
            continue
        corners = np.array([[-sx, -sy, 0], [sx, -sy, 0], [sx, sy, 0], [-sx, sy, 0]]) @ rot.T + data.geom_xpos[g]
        out.append(_hull_xy(corners))
    return out, infinite


def _hull_xy(points: np.ndarray) -> np.ndarray:
    from ..locomotion.balance import convex_hull

    return convex_hull(points[:, :2])


def _outline(model: mujoco.MjModel, data: mujoco.MjData, g: int) -> tuple[str, object, float, float]:
    """(kind, shape, z_min, z_max): kind 'poly' (hull (M, 2)), 'disc' ((cx, cy, r)) or 'stadium'
    ((x0, y0, x1, y1, r)), and the geom's vertical extent, m."""
    kind = model.geom_type[g]
    pos, rot, size = data.geom_xpos[g], data.geom_xmat[g].reshape(3, 3), model.geom_size[g]
    if kind == mujoco.mjtGeom.mjGEOM_BOX:
        corners = np.array([[sx, sy, sz] for sx in (-1, 1) for sy in (-1, 1) for sz in (-1, 1)]) * size
        pts = pos + corners @ rot.T
        return "poly", _hull_xy(pts), float(pts[:, 2].min()), float(pts[:, 2].max())
    if kind == mujoco.mjtGeom.mjGEOM_SPHERE:
        r = float(size[0])
        return "disc", (float(pos[0]), float(pos[1]), r), float(pos[2] - r), float(pos[2] + r)
    if kind == mujoco.mjtGeom.mjGEOM_CAPSULE:
        r, half = float(size[0]), float(size[1])
        a, b = pos - rot[:, 2] * half, pos + rot[:, 2] * half
        return "stadium", (a[0], a[1], b[0], b[1], r), float(min(a[2], b[2]) - r), float(max(a[2], b[2]) + r)
    if kind == mujoco.mjtGeom.mjGEOM_CYLINDER:
        r, half = float(size[0]), float(size[1])
        axis = rot[:, 2]
        # vertical extent: the rims' lowest and highest points
        reach = r * math.sqrt(max(0.0, 1.0 - axis[2] ** 2))
        z_lo = float(pos[2] - abs(axis[2]) * half - reach)
        z_hi = float(pos[2] + abs(axis[2]) * half + reach)
        if abs(axis[2]) > 1.0 - 1e-9:
            return "disc", (float(pos[0]), float(pos[1]), r), z_lo, z_hi
        ang = np.linspace(0.0, 2 * math.pi, _RIM_POINTS, endpoint=False)
        rim = np.stack([np.cos(ang), np.sin(ang), np.zeros_like(ang)], -1) * r
        pts = np.concatenate([pos + (rim + [0, 0, s * half]) @ rot.T for s in (-1, 1)])
        return "poly", _hull_xy(pts), z_lo, z_hi
    centre, half = model.geom_aabb[g, :3], model.geom_aabb[g, 3:]
    corners = centre + np.array([[sx, sy, sz] for sx in (-1, 1) for sy in (-1, 1) for sz in (-1, 1)]) * half
    pts = pos + corners @ rot.T
    return "poly", _hull_xy(pts), float(pts[:, 2].min()), float(pts[:, 2].max())


def _cells_meeting(kind: str, shape, grid_origin, r: float, grid_shape) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(iy, ix, hit): the cells in the shape's bounding box and whether each meets it."""
    ox, oy = grid_origin
    if kind == "poly":
        lo, hi = shape.min(0), shape.max(0)
    elif kind == "disc":
        cx, cy, rad = shape
        lo, hi = np.array([cx - rad, cy - rad]), np.array([cx + rad, cy + rad])
    else:
        x0, y0, x1, y1, rad = shape
        lo = np.array([min(x0, x1) - rad, min(y0, y1) - rad])
        hi = np.array([max(x0, x1) + rad, max(y0, y1) + rad])
    ix0, iy0 = (max(0, int(math.floor((lo[k] - o) / r))) for k, o in ((0, ox), (1, oy)))
    ix1 = min(grid_shape[1] - 1, int(math.floor((hi[0] - ox) / r)))
    iy1 = min(grid_shape[0] - 1, int(math.floor((hi[1] - oy) / r)))
    if ix1 < ix0 or iy1 < iy0:
        empty = np.zeros(0, np.int64)
        return empty, empty, np.zeros(0, bool)
    iy, ix = np.meshgrid(np.arange(iy0, iy1 + 1), np.arange(ix0, ix1 + 1), indexing="ij")
    iy, ix = iy.ravel(), ix.ravel()
    cmin = np.stack([ox + ix * r + _EPS_M, oy + iy * r + _EPS_M], -1)  # (K, 2) square corners
    cmax = cmin + (r - 2 * _EPS_M)
    if kind == "disc":
        cx, cy, rad = shape
        near = np.clip(np.array([cx, cy]), cmin, cmax)
        return iy, ix, np.hypot(near[:, 0] - cx, near[:, 1] - cy) <= rad
    if kind == "poly":
        return iy, ix, _square_meets_polygon(cmin, cmax, shape)
    x0, y0, x1, y1, rad = shape
    return iy, ix, _square_segment_distance(cmin, cmax, np.array([x0, y0]), np.array([x1, y1])) <= rad


def _square_meets_polygon(cmin: np.ndarray, cmax: np.ndarray, poly: np.ndarray) -> np.ndarray:
    """(K,) bool: axis-aligned squares [cmin, cmax] meet the convex polygon (separating axes)."""
    hit = (cmax[:, 0] >= poly[:, 0].min()) & (cmin[:, 0] <= poly[:, 0].max())
    hit &= (cmax[:, 1] >= poly[:, 1].min()) & (cmin[:, 1] <= poly[:, 1].max())
    if len(poly) < 3:
        return hit
    edges = np.roll(poly, -1, 0) - poly
    normals = np.stack([-edges[:, 1], edges[:, 0]], -1)
    corners = np.stack([cmin, np.stack([cmax[:, 0], cmin[:, 1]], -1), cmax,
                        np.stack([cmin[:, 0], cmax[:, 1]], -1)], 1)  # (K, 4, 2)
    for n in normals:
        if not np.any(n):
            continue
        proj_poly = poly @ n
        proj_sq = corners @ n
        hit &= (proj_sq.max(1) >= proj_poly.min()) & (proj_sq.min(1) <= proj_poly.max())
    return hit


def _square_segment_distance(cmin: np.ndarray, cmax: np.ndarray, a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """(K,) exact distance between squares and the segment ab (0 where they meet)."""
    corners = np.stack([cmin, np.stack([cmax[:, 0], cmin[:, 1]], -1), cmax, np.stack([cmin[:, 0], cmax[:, 1]], -1)], 1)
    d = point_segment_distance(corners, a, b).min(1)
    for end in (a, b):
        near = np.clip(end, cmin, cmax)
        d = np.minimum(d, np.linalg.norm(near - end, axis=-1))
    meets = _square_meets_polygon(cmin, cmax, np.stack([a, b]))
    n = np.array([-(b - a)[1], (b - a)[0]])
    if np.any(n):
        proj = corners @ n
        meets &= (proj.max(1) >= a @ n) & (proj.min(1) <= a @ n)
    return np.where(meets, 0.0, d)


def world_occupancy(model: mujoco.MjModel, data: mujoco.MjData, *, resolution_m: float = 0.05,
                    step_height_m: float = 0.03, head_height_m: float = humanoid.HEAD_HEIGHT_M,
                    margin_m: float = 1.0, floor_reach_m: float = 5.0, exclude_prefix: str = humanoid.PRIM_PATH,
                    include_xy_m: np.ndarray | None = None) -> Grid2D:
    """The body band's occupancy of ``model``'s static geoms (module docstring) at ``data``'s
    state (after ``mj_forward``). Extent (module docstring): the solids' and the points
    ``include_xy_m``'s (K, 2) (the start and the goal) bounding box plus ``margin_m`` (1 m: a route
    around a solid on the box's edge keeps the robot's 0.25 m clearance with room to spare), joined
    with the finite floor planes up to ``floor_reach_m`` beyond that box (``add_ground``'s 100 m
    plane would be 4 M cells)."""
    if not resolution_m > 0:
        raise InvalidValueError("resolution_m", resolution_m, "a cell side must be > 0", "pass e.g. 0.05")
    outlines = []
    for g in static_geoms(model, data, exclude_prefix):
        kind, shape, z_lo, z_hi = _outline(model, data, g)
        if z_hi > step_height_m and z_lo < head_height_m:
            outlines.append((kind, shape))
    pts = [] if include_xy_m is None else [np.asarray(include_xy_m, float).reshape(-1, 2)]
    for kind, shape in outlines:
        pts.append(_bounds(kind, shape))
    allp = np.concatenate(pts) if pts else np.zeros((1, 2))
    lo, hi = allp.min(0) - margin_m, allp.max(0) + margin_m
    floors, infinite_floor = floor_planes(model, data, step_height_m)
    if floors:
        plane_pts = np.concatenate(floors)
        lo = np.minimum(lo, np.maximum(plane_pts.min(0), lo - floor_reach_m))
        hi = np.maximum(hi, np.minimum(plane_pts.max(0), hi + floor_reach_m))
    lo = np.floor(lo / resolution_m) * resolution_m
    shape_yx = (int(math.ceil((hi[1] - lo[1]) / resolution_m)), int(math.ceil((hi[0] - lo[0]) / resolution_m)))
    origin = (float(lo[0]), float(lo[1]))
    occupied = np.zeros(shape_yx, bool)
    for kind, shape in outlines:
        iy, ix, hit = _cells_meeting(kind, shape, origin, resolution_m, shape_yx)
        occupied[iy[hit], ix[hit]] = True
    if floors and not infinite_floor:  # nothing to stand on off the floor planes
        on_floor = np.zeros(shape_yx, bool)
        for poly in floors:
            iy, ix, hit = _cells_meeting("poly", poly, origin, resolution_m, shape_yx)
            on_floor[iy[hit], ix[hit]] = True
        occupied |= ~on_floor
    return Grid2D.from_masks(occupied, origin_xy_m=origin, resolution_m=resolution_m)


def _bounds(kind: str, shape) -> np.ndarray:
    """(2, 2) or (M, 2) points whose bounding box is the outline's."""
    if kind == "poly":
        return shape
    if kind == "disc":
        cx, cy, rad = shape
        return np.array([[cx - rad, cy - rad], [cx + rad, cy + rad]])
    x0, y0, x1, y1, rad = shape
    return np.array([[min(x0, x1) - rad, min(y0, y1) - rad], [max(x0, x1) + rad, max(y0, y1) + rad]])


__all__ = ["floor_planes", "static_geoms", "world_occupancy"]
