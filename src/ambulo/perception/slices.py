"""2-D maps cut from the 3-D map: an occupancy slice and a distance slice over a height band
(what nvblox hands Nav2), and a height / steppability map for a humanoid's feet.

``Slice2D`` is a torch view on the one cell convention of ``ambulo.maps`` (``CellGeometry``):
arrays are indexed [row = y, column = x] and ``origin_xy_m`` is the lower-left *corner* of cell
[0, 0], as in ROS. Cell [iy, ix] is the column of TSDF voxels (ix, iy) of the dense grid, whose
voxel centres lie at ``index * voxel_size``, so the corner is half a voxel below the first centre.
``to_grid2d`` turns an occupancy slice (and its costmap) into the ``maps.Grid2D`` files are made of.

Occupied means *the cell holds a surface* (``surface_voxels``), not "behind a surface": the
projective TSDF marks the truncation band behind every face negative, so counting those voxels made
walls ~2 truncations thick and closed doors. The inside of a solid seen from outside is UNKNOWN.

For a navigator: ``map_occupancy_slice(tsdf, z_min, z_max, region_xy_m)`` densifies only the blocks
around the robot (no colour), and ``costmap.inflate`` of it is the costmap; the whole map's
``occupancy_slice(tsdf.dense(), ...)`` works too (timings: ``benchmarks/mapping.py --apartment``).
"""

from __future__ import annotations

from dataclasses import dataclass

import torch

from ..maps import CellGeometry, Grid2D
from ..utils.checks import Described, InvalidValueError
from .esdf import Esdf
from .torch_threads import one_torch_thread
from .tsdf.map import DenseGrid, TsdfMap

UNKNOWN, FREE, OCCUPIED = -1, 0, 1
"""An occupancy slice's int8 codes (``maps.Grid2D`` stores ROS's -1 / 0 / 100; ``to_grid2d`` converts)."""


@dataclass
class Slice2D(CellGeometry):
    """A 2-D map in the world x-y plane (torch, on the map's device)."""

    data: torch.Tensor
    """(H, W) map values, rows = y, columns = x; dtype and meaning depend on the map."""
    origin_xy_m: tuple[float, float]
    """World (x, y) of the lower-left corner of cell [0, 0] (``OccupancyGrid.info.origin``), m."""
    resolution_m: float

    @property
    def shape(self) -> tuple[int, int]:
        """(H, W)."""
        return tuple(self.data.shape)


def to_grid2d(occupancy: Slice2D, cost: Slice2D | None = None) -> Grid2D:
    """The ``maps.Grid2D`` of an occupancy slice (``occupancy_slice``), with ``cost`` (a ``Costmap``
    of the same cells) as its cost layer: what ``ambulo map`` writes and ``ambulo plan`` reads."""
    if cost is not None and (cost.shape != occupancy.shape or tuple(cost.origin_xy_m) != tuple(occupancy.origin_xy_m)
                             or cost.resolution_m != occupancy.resolution_m):
        raise InvalidValueError("to_grid2d cost", Described("a costmap of other cells"),
                                "it must cover the occupancy slice's cells", "pass inflate(occupancy)")
    data = occupancy.data
    return Grid2D.from_masks(data == OCCUPIED, unknown=data == UNKNOWN, origin_xy_m=occupancy.origin_xy_m,
                             resolution_m=occupancy.resolution_m, cost=None if cost is None else cost.data)


def _band(grid_z0_index: int, voxel_size_m: float, nz: int, z_min_m: float, z_max_m: float,
          device) -> torch.Tensor:
    z = (torch.arange(nz, device=device) + grid_z0_index) * voxel_size_m
    return (z >= z_min_m) & (z <= z_max_m)


def _origin(grid_origin_index: torch.Tensor, voxel_size_m: float) -> tuple[float, float]:
    """Lower-left corner of the cell over voxel column [0, 0], m: half a voxel below its centre."""
    return ((float(grid_origin_index[0]) - 0.5) * voxel_size_m, (float(grid_origin_index[1]) - 0.5) * voxel_size_m)


def surface_voxels(tsdf: torch.Tensor, weight: torch.Tensor, truncation_m: float, voxel_size_m: float,
                   min_weight: float = 1.0) -> tuple[torch.Tensor, torch.Tensor]:
    """(occupied, free), each (X, Y, Z) bool, of a dense block of voxels (``tsdf`` normalised by
    ``truncation_m``, ``weight``): what an occupancy map may claim of each voxel.

    occupied: the voxels whose cell holds the surface: observed, with the surface less than half a
    voxel in front of the centre or behind it (sdf < voxel / 2, so the cell meets the solid, as a
    ground-truth cell that meets a footprint is occupied) and not deep inside: within one voxel of the
    surface (sdf > -voxel) or next to a free voxel along x, y or z (the zero crossing, whatever angle it
    was seen at: the projective sdf overstates the distance at a grazing view). The voxels further
    behind (up to the truncation) are the inside of a solid seen from one side: counting them occupied
    made walls ~2 truncations thick in the slice and closed doors; they are neither occupied nor free
    (a wall seen from both sides is its two surface layers, which meet in a 10-15 cm wall).
    Also occupied (and not free): an observed voxel in front of the surface by the sdf (>= half a voxel)
    whose 6-neighbour behind it puts the zero crossing, interpolated between the two centres, within
    half a voxel of it (sdf + neighbour's sdf < 0, neither truncated). The projective sdf of a face seen
    at a grazing angle overstates both distances by the same factor (1 / cos of the incidence), so the
    threshold alone moved such faces a voxel back (a door jamb's end face, a wall seen along it: on
    apartment 11's walk 72 cells of walls read free) while the interpolated crossing is unbiased.
    free: observed voxels at least half a voxel in front of every surface."""
    observed = weight >= min_weight
    sdf_vox = tsdf * (truncation_m / voxel_size_m)  # in voxels
    free = observed & (sdf_vox >= 0.5)
    crossing = torch.zeros_like(free)
    # neighbour sdf behind a surface (observed, not truncated), +inf elsewhere: the interpolation test below
    behind = torch.where(observed & (sdf_vox < 0) & (tsdf > -1.0), sdf_vox, torch.full_like(sdf_vox, float("inf")))
    graze = torch.zeros_like(free)
    for axis in range(3):  # 6-neighbours: shifted by one voxel each way along each axis
        n = free.shape[axis]
        if n < 2:
            continue
        crossing.narrow(axis, 0, n - 1).logical_or_(free.narrow(axis, 1, n - 1))
        crossing.narrow(axis, 1, n - 1).logical_or_(free.narrow(axis, 0, n - 1))
        graze.narrow(axis, 0, n - 1).logical_or_(sdf_vox.narrow(axis, 0, n - 1) + behind.narrow(axis, 1, n - 1) < 0)
        graze.narrow(axis, 1, n - 1).logical_or_(sdf_vox.narrow(axis, 1, n - 1) + behind.narrow(axis, 0, n - 1) < 0)
    graze &= free & (tsdf < 1.0)
    occupied = (observed & (sdf_vox < 0.5) & ((sdf_vox > -1.0) | crossing)) | graze
    return occupied, free & ~graze


def occupancy_slice(grid: DenseGrid, z_min_m: float, z_max_m: float, min_weight: float = 1.0,
                    floor_seen_m: float | None = None) -> Slice2D:
    """(H, W) int8 over the voxel columns of ``grid``: OCCUPIED where a voxel centred in
    [z_min_m, z_max_m] holds a surface (``surface_voxels``: the surface layer, not the whole truncation
    band behind it, so a wall keeps its thickness), FREE where none does and a voxel of the band was
    seen free, UNKNOWN otherwise (never seen, or seen only from inside a solid).

    ``floor_seen_m``: FREE only where a voxel centred in [z_min_m, z_min_m + floor_seen_m] was seen
    free, so a low box hidden behind furniture while rays passed over it does not read free (stricter:
    on an apartment walk it left 35 % of the seen free cells unknown, against 1-3 % without)."""
    with one_torch_thread(grid.tsdf.device):  # ~20x faster than 2 threads on a busy 2-core machine
        return _occupancy_slice(grid, z_min_m, z_max_m, min_weight, floor_seen_m)


def _occupancy_slice(grid: DenseGrid, z_min_m: float, z_max_m: float, min_weight: float,
                     floor_seen_m: float | None) -> Slice2D:
    band = _band(int(grid.origin_index[2]), grid.voxel_size_m, grid.tsdf.shape[2], z_min_m, z_max_m,
                 grid.tsdf.device)
    idx = torch.nonzero(band, as_tuple=True)[0]
    if len(idx) == 0:
        raise InvalidValueError("occupancy_slice z band", (z_min_m, z_max_m), "it holds no voxel centre of the map",
                                "pass z_min_m < z_max_m within the mapped heights, e.g. 0.1, 1.6")
    # the band and one voxel either side (the zero-crossing test looks at the neighbours)
    lo, hi = max(int(idx[0]) - 1, 0), min(int(idx[-1]) + 2, grid.tsdf.shape[2])
    occupied, free = surface_voxels(grid.tsdf[:, :, lo:hi], grid.weight[:, :, lo:hi], grid.truncation_m,
                                    grid.voxel_size_m, min_weight)
    inner = band[lo:hi]
    bottom = inner if floor_seen_m is None else inner & _band(
        int(grid.origin_index[2]) + lo, grid.voxel_size_m, hi - lo, z_min_m, z_min_m + floor_seen_m, grid.tsdf.device)
    occupied = occupied[:, :, inner].any(-1)
    free = free[:, :, bottom].any(-1)
    data = torch.full(occupied.shape, UNKNOWN, dtype=torch.int8, device=occupied.device)
    data[free] = FREE
    data[occupied] = OCCUPIED
    return Slice2D(data.T.contiguous(), _origin(grid.origin_index, grid.voxel_size_m), grid.voxel_size_m)


def map_occupancy_slice(tsdf: TsdfMap, z_min_m: float, z_max_m: float,
                        region_xy_m: tuple[float, float, float, float] | None = None, min_weight: float = 1.0,
                        floor_seen_m: float | None = None) -> Slice2D:
    """``occupancy_slice`` of a ``TsdfMap`` over the blocks that meet ``region_xy_m`` (x_min, y_min, x_max,
    y_max, world m; None: the whole map) and the band (with a voxel either side), densified without colour
    (``TsdfMap.dense(region_xy_m=, z_range_m=, color=False)``): what a navigator reads at every replan, the
    costmap being ``costmap.inflate`` of it. Its cells are the voxel columns (those of the whole map's
    slice), covering whole blocks, so it may reach up to a block beyond the region. Measured on an
    apartment after a 12 s walk (benchmarks/mapping.py --apartment): see the benchmark's navigator_ms."""
    vs = tsdf.cfg.voxel_size_m
    with one_torch_thread(tsdf.device):
        grid = tsdf.dense(region_xy_m=region_xy_m, z_range_m=(z_min_m - vs, z_max_m + vs), color=False)
        return occupancy_slice(grid, z_min_m, z_max_m, min_weight, floor_seen_m)


def distance_slice(esdf: Esdf, z_min_m: float, z_max_m: float) -> Slice2D:
    """(H, W) float32: the smallest ESDF value over the band's observed voxels (nvblox's 2-D
    distance map), m; ``nan`` where the band was never observed."""
    band = _band(int(esdf.origin_index[2]), esdf.voxel_size_m, esdf.distance_m.shape[2], z_min_m, z_max_m,
                 esdf.distance_m.device)
    dist = esdf.distance_m[:, :, band]
    seen = esdf.observed[:, :, band]
    value = torch.where(seen, dist, torch.full_like(dist, float("inf"))).amin(-1)
    value = torch.where(seen.any(-1), value, torch.full_like(value, float("nan")))
    return Slice2D(value.T.contiguous(), _origin(esdf.origin_index, esdf.voxel_size_m), esdf.voxel_size_m)


@dataclass
class HeightMap:
    """Where a foot can stand: the top surface under each column and whether it is steppable."""

    height_m: Slice2D
    """(H, W) float32 world z of the highest surface at most ``max_height_m`` high; nan if unseen."""
    steppable: Slice2D
    """(H, W) bool: a surface is known, flat enough over a foot and free above up to the body."""


def height_map(grid: DenseGrid, *, max_height_m: float = 0.5, foot_half_cells: int = 2,
               max_roughness_m: float = 0.03, clearance_m: float = 1.6, min_weight: float = 1.0) -> HeightMap:
    """Height and steppability (elevation_mapping_cupy's use case for legged robots).

    The surface of a column is the zero crossing above its highest occupied voxel centred at or
    below ``max_height_m`` (interpolated from the TSDF, so sub-voxel). A cell is steppable when
    every cell within ``foot_half_cells`` has a known surface within ``max_roughness_m`` of its
    own (a step or an edge under the foot is not), and no occupied voxel lies between the
    surface + ``max_roughness_m`` and the surface + ``clearance_m`` (nothing to hit the body on).
    """
    vs = grid.voxel_size_m
    nx, ny, nz = grid.tsdf.shape
    z = (torch.arange(nz, device=grid.tsdf.device) + int(grid.origin_index[2])) * vs
    occupied = grid.occupied(min_weight)
    low = occupied & (z <= max_height_m)
    idx = torch.arange(nz, device=z.device).expand(nx, ny, nz)
    top = torch.where(low, idx, torch.full_like(idx, -1)).amax(-1)  # (X, Y) highest occupied index
    have = top >= 0
    t0 = grid.tsdf.gather(2, top.clamp(min=0)[..., None])[..., 0]
    above = (top + 1).clamp(max=nz - 1)
    t1 = grid.tsdf.gather(2, above[..., None])[..., 0]
    seen_above = grid.weight.gather(2, above[..., None])[..., 0] >= min_weight
    frac = torch.where(seen_above & (t1 > 0), t0 / (t0 - t1), torch.full_like(t0, 0.5)).clamp(0, 1)
    height = torch.where(have, z[top.clamp(min=0)] + frac * vs, torch.full_like(t0, float("nan")))
    # roughness over the foot window (nan neighbours count as unknown -> not steppable)
    pad = foot_half_cells
    hp = torch.nn.functional.pad(height[None, None], (pad, pad, pad, pad), value=float("nan"))[0, 0]
    known = torch.isfinite(hp)
    big = torch.tensor(1e9, device=z.device)
    hmax = torch.where(known, hp, -big).unfold(0, 2 * pad + 1, 1).unfold(1, 2 * pad + 1, 1).amax((-1, -2))
    hmin = torch.where(known, hp, big).unfold(0, 2 * pad + 1, 1).unfold(1, 2 * pad + 1, 1).amin((-1, -2))
    all_known = known.unfold(0, 2 * pad + 1, 1).unfold(1, 2 * pad + 1, 1).all(-1).all(-1)
    flat = all_known & (hmax - hmin <= max_roughness_m)
    rel = z[None, None, :] - height[..., None]
    blocked = (occupied & (rel > max_roughness_m + 0.5 * vs) & (rel < clearance_m)).any(-1)
    steppable = have & flat & ~blocked
    origin = _origin(grid.origin_index, vs)
    return HeightMap(Slice2D(height.T.contiguous(), origin, vs), Slice2D(steppable.T.contiguous(), origin, vs))


__all__ = ["FREE", "OCCUPIED", "UNKNOWN", "HeightMap", "Slice2D", "distance_slice", "height_map", "map_occupancy_slice",
           "occupancy_slice", "surface_voxels", "to_grid2d"]
