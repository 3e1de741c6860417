"""Isaac Gym's ``add_heightfield`` and ``add_triangle_mesh`` terrain as MuJoCo height fields.

MuJoCo collides with a mesh through its convex hull, so a terrain mesh cannot be a mesh geom;
a height field keeps its shape. ``add_heightfield`` samples map one to one. ``add_triangle_mesh``
is sampled onto a grid at the mesh's own vertex spacing: each sample takes the highest triangle
above it, so a terrain that is a height function (legged_gym's: one height per x, y) comes back
exactly at the vertices; what a height field cannot hold (overhangs, exactly vertical walls) is
approximated - a wall becomes a slope one sample wide.
"""

from __future__ import annotations

from dataclasses import dataclass

import mujoco
import numpy as np

from .types import HeightFieldParams, Transform, TriangleMeshParams

BASE_THICKNESS_M = 1.0
"""Depth of the solid below the lowest sample (MuJoCo's hfield base)."""
_CHUNK = 400_000
"""Triangles rasterized at once (bounds the temporary arrays to a few hundred MB)."""
_INSIDE = 1e-3
"""Barycentric slack: a sample on a shared edge or vertex (float32 vertices) counts as inside."""


@dataclass
class HeightField:
    """A terrain in the sim frame: ``heights_m[i, j]`` at ``origin + (i dx, j dy)``."""

    heights_m: np.ndarray
    """(nx, ny) float64, m above ``origin``'s z."""
    origin: np.ndarray
    """(3,) the sample [0, 0]'s position, m."""
    spacing_m: tuple[float, float]
    dynamic_friction: float
    """The surface's sliding friction (static friction and restitution are not applied)."""


def _position(transform: Transform) -> np.ndarray:
    r = transform.r
    if abs(r.x) + abs(r.y) + abs(r.z) > 1e-6:
        raise ValueError("isaacgym: a rotated terrain transform is not supported; place terrain with transform.p only")
    return transform.p.as_array()


def from_samples(samples: np.ndarray, params: HeightFieldParams) -> HeightField:
    """``add_heightfield``'s samples (``nbColumns`` x ``nbRows`` units, x first; see ``HeightFieldParams``)."""
    nx, ny = int(params.nbColumns), int(params.nbRows)
    samples = np.asarray(samples)
    if samples.size != nx * ny:
        raise ValueError(f"isaacgym: {samples.size} height samples for nbColumns x nbRows = {nx} x {ny}")
    heights = samples.reshape(nx, ny).astype(np.float64) * params.vertical_scale
    return HeightField(heights, _position(params.transform), (params.column_scale, params.row_scale),
                       params.dynamic_friction)


def from_mesh(vertices: np.ndarray, triangles: np.ndarray, params: TriangleMeshParams) -> HeightField:
    """``add_triangle_mesh``'s mesh (flat or (n, 3) vertices in m and vertex-index triples) sampled
    onto a grid at its median horizontal edge length (module docstring)."""
    v = np.asarray(vertices, np.float64).reshape(-1, 3)
    t = np.asarray(triangles, np.int64).reshape(-1, 3)
    # each triangle's shortest horizontal edge (a grid cell's side, not its diagonal)
    edges = np.stack([np.linalg.norm(v[t[:, k], :2] - v[t[:, (k + 1) % 3], :2], axis=1) for k in range(3)], 1)
    edges = np.where(edges > 1e-9, edges, np.inf).min(1)
    edges = edges[np.isfinite(edges)]
    edge = float(np.median(edges)) if len(edges) else 1.0
    lo, hi = v[:, :2].min(0), v[:, :2].max(0)
    counts = np.maximum(np.rint((hi - lo) / edge).astype(int), 1)
    step = (hi - lo) / counts  # the samples land on the vertices of a grid mesh (float32 meshes drift)
    nx, ny = (counts + 1).tolist()
    heights = np.full(nx * ny, -np.inf)
    for start in range(0, len(t), _CHUNK):
        _rasterize(v, t[start:start + _CHUNK], lo, step, nx, ny, heights)
    heights = heights.reshape(nx, ny)
    missing = ~np.isfinite(heights)
    if missing.all():
        raise ValueError("isaacgym: the terrain mesh covers no grid sample (a mesh without area?)")
    heights[missing] = heights[~missing].min()  # holes: the lowest terrain height
    origin = _position(params.transform) + np.array([lo[0], lo[1], 0.0])
    return HeightField(heights, origin, (float(step[0]), float(step[1])), params.dynamic_friction)


def _rasterize(v, t, lo, step, nx, ny, heights) -> None:
    """Max into ``heights`` (flat nx * ny) the height of each triangle of ``t`` over the grid
    samples inside it (spacing ``step`` (2,) m; each triangle spans at most 3 x 3 samples)."""
    a, b, c = v[t[:, 0]], v[t[:, 1]], v[t[:, 2]]
    tri_lo = np.ceil((np.minimum(np.minimum(a, b), c)[:, :2] - lo) / step - 1e-4).astype(int)
    tri_hi = np.floor((np.maximum(np.maximum(a, b), c)[:, :2] - lo) / step + 1e-4).astype(int)
    d = (b[:, 1] - c[:, 1]) * (a[:, 0] - c[:, 0]) + (c[:, 0] - b[:, 0]) * (a[:, 1] - c[:, 1])
    flat = np.abs(d) < 1e-12  # a triangle seen edge-on from above (a vertical wall) covers no sample
    for di in range(3):
        for dj in range(3):
            i, j = tri_lo[:, 0] + di, tri_lo[:, 1] + dj
            ok = ~flat & (i <= tri_hi[:, 0]) & (j <= tri_hi[:, 1]) & (i >= 0) & (j >= 0) & (i < nx) & (j < ny)
            x, y = lo[0] + i * step[0], lo[1] + j * step[1]
            with np.errstate(divide="ignore", invalid="ignore"):  # edge-on triangles: masked by ``flat``
                w0 = ((b[:, 1] - c[:, 1]) * (x - c[:, 0]) + (c[:, 0] - b[:, 0]) * (y - c[:, 1])) / d
                w1 = ((c[:, 1] - a[:, 1]) * (x - c[:, 0]) + (a[:, 0] - c[:, 0]) * (y - c[:, 1])) / d
                w2 = 1.0 - w0 - w1
                ok &= (w0 >= -_INSIDE) & (w1 >= -_INSIDE) & (w2 >= -_INSIDE)
                z = w0 * a[:, 2] + w1 * b[:, 2] + w2 * c[:, 2]
            np.maximum.at(heights, (i * ny + j)[ok], z[ok])


def add_to_spec(spec: mujoco.MjSpec, terrain: HeightField, name: str) -> None:
    """The terrain as a static MuJoCo hfield geom of ``spec``'s world body."""
    h = terrain.heights_m
    nx, ny = h.shape
    low, elevation = float(h.min()), max(float(h.max() - h.min()), 1e-4)
    dx, dy = terrain.spacing_m
    half_x, half_y = 0.5 * (nx - 1) * dx, 0.5 * (ny - 1) * dy
    # MuJoCo's rows run along y and columns along x; data are fractions of the elevation
    spec.add_hfield(name=name, size=[half_x, half_y, elevation, BASE_THICKNESS_M], nrow=ny, ncol=nx,
                    userdata=((h - low) / elevation).T.reshape(-1).tolist())
    pos = terrain.origin + np.array([half_x, half_y, low])
    spec.worldbody.add_geom(name=name, type=mujoco.mjtGeom.mjGEOM_HFIELD, hfieldname=name, pos=pos.tolist(),
                            friction=[terrain.dynamic_friction, 0.005, 0.0001])


__all__ = ["BASE_THICKNESS_M", "HeightField", "add_to_spec", "from_mesh", "from_samples"]
