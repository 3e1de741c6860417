"""Mappers: the 2-D occupancy of the body band the navigator plans on (``maps.Grid2D``: -1 unknown,
0 free, 100 occupied), with a ``version`` that changes when its contents do.

- ``OracleMapper``: the world's ground-truth occupancy; never changes.
- ``OnlineMapper``: a TSDF (``perception.tsdf.TsdfMap``) fused from tracked frames at their
  estimated poses; every ``1 / update_hz`` s of simulated time its occupancy slice of the body band
  (``perception.slices.occupancy_slice``) is cut and written into a fixed map covering the world
  (cells aligned with the TSDF's voxel columns, so the slice lands cell for cell). Cells the robot's
  body stood on (a disc of ``body_free_radius_m`` around each estimated pose) are free when the
  slice has not seen them: the robot was there. Optionally (``start_seen_low_m``), near the start a cell
  reads free only where the band was seen free low, so furniture beside the start, seen only by rays
  passing over it at head height, is unknown, not free. Each refresh re-slices only the voxel columns the
  frames fused since the last one changed (the box of the TSDF blocks they updated, and one column
  around it, whose surface test looks at its neighbours), densifying the blocks that meet that box
  grown by a column more: so the map is, cell for cell, the slice of the whole TSDF (the tests
  check it), at the cost of the view's few metres (on the recorded refreshes of a full-mode
  episode, apartment 200: ``refresh_wall_s``).

``costmap()`` gives the humanoid's Nav2-style costmap of the current map (``perception.costmap``),
for displays and the ROS node; the planners use exact clearances (``planning``).
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field

import numpy as np
import torch

from ..maps import FREE, OCCUPIED, UNKNOWN, Grid2D
from ..perception.costmap import Costmap, InflationCfg, inflate
from ..perception.frames import RgbdFrame
from ..perception.slices import OCCUPIED as SLICE_OCCUPIED
from ..perception.slices import UNKNOWN as SLICE_UNKNOWN
from ..perception.slices import Slice2D, occupancy_slice
from ..perception.tsdf.map import TsdfCfg, TsdfMap
from ..robots import humanoid
from ..utils.validate import Checked


def costmap_of(grid: Grid2D, cfg: InflationCfg | None = None) -> Costmap:
    """The humanoid costmap (Nav2 inflation) of a ``Grid2D``."""
    occ = grid.occupancy
    data = np.where(occ >= OCCUPIED, SLICE_OCCUPIED, np.where(occ == UNKNOWN, SLICE_UNKNOWN, 0)).astype(np.int8)
    return inflate(Slice2D(torch.from_numpy(data), tuple(grid.origin_xy_m), grid.resolution_m), cfg)


class OracleMapper:
    """The ground truth (module docstring)."""

    name = "oracle"
    needs_images = False
    optimistic = True
    """No unknown cells: footsteps may use every free cell."""

    def reset(self, world) -> None:
        self.grid = world.occupancy
        self.version = 0
        self.frames_fused = 0

    def fuse(self, frame: RgbdFrame, pose_wc: np.ndarray) -> None:
        self.frames_fused += 1

    def mark_body(self, xy) -> None:
        pass

    def mark_obstacle(self, xy) -> None:
        pass

    def refresh(self, time_s: float, xy=None) -> bool:
        return False

    def costmap(self) -> Costmap:
        return costmap_of(self.grid)


@dataclass(kw_only=True)
class OnlineMapperCfg(Checked):
    tsdf: TsdfCfg = field(default_factory=lambda: TsdfCfg(depth_max_m=4.0))
    """5 cm voxels; depth beyond 4 m is left out (the head camera's far floor is noisy and its
    rays graze it)."""
    band_m: tuple[float, float] = (0.04, humanoid.HEAD_HEIGHT_M)
    """Height band of the occupancy slice, m: from the first voxel centre above the floor (5 cm, so
    a 5-15 cm box of shoes or pile of books is in it: the apartments' clutter, which the robot
    fell over with the band starting at 0.1 m) to the head."""
    floor_seen_m: float | None = None
    """None: a cell reads free where any band voxel over it was seen free. A height: only where a band
    voxel within this of the band's bottom was seen free (``slices.occupancy_slice``), so rays passing
    over a low box do not make it free; 0.3 m left the robot turning to look at ground its head camera
    cannot see within ~1.3 m (0 of 5 full-mode episodes moved on), so it is off by default, m."""
    start_blind_radius_m: float = 1.5
    """Within this of the start, where the head camera (floor in view from ~1.6 m ahead) cannot see
    the floor before the robot moves, a cell reads free when any band voxel over it was seen free
    (rays passed over it), as if ``floor_seen_m`` were None, m."""
    start_seen_low_m: float | None = None
    """Within ``start_seen_low_radius_m`` of the start, a cell reads free only where a band voxel within
    this of the band's bottom (0.9: centres up to 0.94 m) was seen free (``floor_seen_m`` there); None:
    off, the default. On the device's 100 full-mode apartments 0.9 took contacts from 14 to 12 (72's
    bed and 11's table gone) but success from 96 to 94 % and stuck from 3 to 4 % (0 and 9 stuck near
    their starts; results/navigate-2026-11-29-s8/), so it is an option, not the default.
    Furniture beside or behind the start is what the head camera never sees at its own height (it
    sees that height from ~0.7 m ahead), and rays passing over it at head height made it free: a bed
    (0.45-0.6 m) and a table top (0.7-0.78 m) met 0.1-0.4 m into the walk (device, full mode:
    apartment 72, a thigh on a bed seen free only at 1.35-1.55 m; 11, a forearm on a table top seen
    free only from 1.05 m up; VM: both walks without a contact). Everywhere (``floor_seen_m`` 0.9) it
    left more floor unknown ahead and cost look turns (VM: apartment 0 stuck, 8's SPL 0.72 -> 0.50), m."""
    start_seen_low_radius_m: float = 0.6
    """See ``start_seen_low_m``; 0: off. 1.0 m sent apartment 0's robot round its start's unknown
    cells (VM: SPL 0.82 -> 0.64, 9.6 -> 12.3 m walked); 0.6 m kept 0.83 and still covered the
    contacts of 72 and 11 (benchmarks/results/vm-2026-11-29-s8-nav-seen-low.md), m."""
    update_hz: float = 2.0
    """Slices per second of simulated time."""
    body_free_radius_m: float = 0.4
    """Cells within this of a pose the robot stood at are free unless seen otherwise, m: the body's
    0.265 m radius and what the arms sweep; the footstep planner needs 0.25 m of clearance from
    unknown cells around its start stance. The head camera cannot see the floor within ~1.6 m
    ahead, so without this the footstep planner (0.25 m body clearance from unknown cells) could
    never start."""
    margin_m: float = 1.0
    """The map covers the world's ground-truth extent grown by this, m."""
    device: str = "cpu"
    """Torch device of the TSDF (its Warp kernels run on CUDA too): ``"cuda"`` takes its integration
    (~30 ms a frame on a busy CPU core) off the episode's core; the slices come back to the host."""


class OnlineMapper:
    """TSDF -> occupancy slice -> the navigator's map (module docstring)."""

    name = "online"
    needs_images = True
    optimistic = False

    def __init__(self, cfg: OnlineMapperCfg | None = None, device: str | None = None):
        self.cfg = cfg or OnlineMapperCfg()
        self.device = self.cfg.device if device is None else device

    def reset(self, world) -> None:
        c = self.cfg
        vs = c.tsdf.voxel_size_m
        x0, y0, x1, y1 = world.occupancy.extent_xy_m()
        # cell corners at (k - 1/2) voxels: cell k is voxel column k (perception.slices)
        self._k0 = (int(math.floor((x0 - c.margin_m) / vs)), int(math.floor((y0 - c.margin_m) / vs)))
        nx = int(math.ceil((x1 + c.margin_m) / vs)) - self._k0[0] + 1
        ny = int(math.ceil((y1 + c.margin_m) / vs)) - self._k0[1] + 1
        origin = ((self._k0[0] - 0.5) * vs, (self._k0[1] - 0.5) * vs)
        self._occ = np.full((ny, nx), UNKNOWN, np.int8)
        self._body_free = np.zeros((ny, nx), bool)
        self._felt = np.zeros((ny, nx), bool)
        """Cells where the walker's feet or shins touched something the camera never showed
        (``PolicyWalker.felt_xy_m``): occupied whatever the slice says."""
        self.grid = Grid2D(occupancy=self._occ.copy(), origin_xy_m=origin, resolution_m=vs)
        self.tsdf = TsdfMap(c.tsdf, device=self.device)
        self._start_xy = np.asarray(world.start_pose[:2], float)
        self.version = 0
        self.frames_fused = 0
        self._last_refresh_s = -math.inf
        self._dirty = False
        self.refresh_wall_s: list[float] = []
        """Wall time of each slice (dense grid + slice + paste), s."""
        self.fuse_wall_s: list[float] = []

    def fuse(self, frame: RgbdFrame, pose_wc: np.ndarray) -> None:
        """Integrate ``frame`` at the camera pose ``pose_wc`` (4, 4): call only with tracked poses."""
        t0 = time.perf_counter()
        self.tsdf.integrate(RgbdFrame(frame.depth_m, frame.rgb, frame.intrinsics,
                                      torch.as_tensor(pose_wc, dtype=torch.float64), frame.time_s))
        self.fuse_wall_s.append(time.perf_counter() - t0)
        self.frames_fused += 1
        self._dirty = True

    def mark_body(self, xy) -> None:
        """The robot stands at ``xy`` (estimated): its body's cells are free unless seen occupied."""
        g = self.grid
        r = self.cfg.body_free_radius_m
        iy, ix = g.cell_of(xy)
        k = int(math.ceil(r / g.resolution_m))
        ny, nx = g.shape
        y0, y1, x0, x1 = max(0, iy - k), min(ny, iy + k + 1), max(0, ix - k), min(nx, ix + k + 1)
        if y0 >= y1 or x0 >= x1:  # the pose is off the map (a drifted estimate): none of its cells to mark
            return
        ys, xs = np.mgrid[y0:y1, x0:x1]
        cx, cy = g.cell_center_xy_m(ys, xs)
        inside = np.hypot(cx - xy[0], cy - xy[1]) <= r
        if inside.any() and not self._body_free[ys[inside], xs[inside]].all():
            self._body_free[ys[inside], xs[inside]] = True
            self._dirty = True

    def mark_obstacle(self, xy) -> None:
        """Something was felt at ``xy`` (estimated frame, m): its cell is occupied from the next refresh."""
        iy, ix = self.grid.cell_of(xy)
        ny, nx = self.grid.shape
        if 0 <= iy < ny and 0 <= ix < nx and not self._felt[iy, ix]:
            self._felt[iy, ix] = True
            self._dirty = True

    def refresh(self, time_s: float, xy=None) -> bool:
        """Re-slice what the frames fused since the last refresh changed (module docstring), if a
        refresh is due and anything changed; True when the map changed. ``xy`` (the robot) is not
        needed: the TSDF knows which blocks changed."""
        if not self._dirty or time_s - self._last_refresh_s < 1.0 / self.cfg.update_hz:
            return False
        t0 = time.perf_counter()
        self._last_refresh_s = time_s
        self._dirty = False
        occ = self._occ.copy()
        columns = self._changed_columns()
        if columns is not None:
            self._paste(occ, columns)
        occ[(occ == UNKNOWN) & self._body_free] = FREE
        occ[self._felt] = OCCUPIED
        changed = not np.array_equal(occ, self._occ)
        if changed:
            self._occ = occ
            self.grid = Grid2D(occupancy=occ.copy(), origin_xy_m=self.grid.origin_xy_m,
                               resolution_m=self.grid.resolution_m)
            self.version += 1
        self.refresh_wall_s.append(time.perf_counter() - t0)
        return changed

    def costmap(self) -> Costmap:
        return costmap_of(self.grid)

    def _changed_columns(self) -> tuple[int, int, int, int] | None:
        """(ix0, iy0, ix1, iy1), world voxel column indices, inclusive: the box of the band's blocks
        updated since the last call, grown by the one column whose slice reads its neighbours; None
        when no block of the band changed."""
        slots = self.tsdf.clear_updated()
        if not len(slots):
            return None
        b, vs = self.cfg.tsdf.block_voxels, self.cfg.tsdf.voxel_size_m
        coords = self.tsdf.block_coords()[slots]
        z0, z1 = self.cfg.band_m
        # a block's voxel centres span [c b, (c + 1) b - 1] voxels; the slice reads the band and a voxel either side
        kz0, kz1 = math.floor(z0 / vs) - 1, math.ceil(z1 / vs) + 1
        coords = coords[(coords[:, 2] * b <= kz1) & ((coords[:, 2] + 1) * b - 1 >= kz0)]
        if not len(coords):
            return None
        lo, hi = coords[:, :2].min(0).values * b - 1, (coords[:, :2].max(0).values + 1) * b
        return int(lo[0]), int(lo[1]), int(hi[0]), int(hi[1])

    def _paste(self, occ: np.ndarray, columns: tuple[int, int, int, int]) -> None:
        """Slice the TSDF over ``columns`` (``_changed_columns``) and write it into ``occ`` (this map's
        cells) in place."""
        c = self.cfg
        vs = c.tsdf.voxel_size_m
        ix0, iy0, ix1, iy1 = columns
        z0, z1 = c.band_m
        # the blocks that hold the columns' neighbours too: every pasted column is cut as from the whole map
        region = ((ix0 - 1) * vs, (iy0 - 1) * vs, (ix1 + 1) * vs, (iy1 + 1) * vs)
        dense = self.tsdf.dense(region_xy_m=region, z_range_m=(z0 - vs, z1 + vs), color=False)
        sl = occupancy_slice(dense, z0, z1, floor_seen_m=c.floor_seen_m)
        data = sl.data.cpu().numpy()
        if c.floor_seen_m is not None and c.start_blind_radius_m > 0:
            loose = occupancy_slice(dense, z0, z1).data.cpu().numpy()
            centres = sl.cell_centers_xy_m()
            near = np.hypot(centres[..., 0] - self._start_xy[0],
                            centres[..., 1] - self._start_xy[1]) <= c.start_blind_radius_m
            data = np.where(near & (data == SLICE_UNKNOWN) & (loose != SLICE_UNKNOWN), loose, data)
        if c.start_seen_low_m is not None and c.start_seen_low_radius_m > 0:
            data = self._seen_low_near_start(dense, sl, data)
        sx, sy = int(dense.origin_index[0]), int(dense.origin_index[1])  # the slice's cell [0, 0] is this column
        ny, nx = occ.shape
        # the changed columns, clipped to the slice and to this map, in this map's cells
        gx0, gy0 = max(ix0, sx) - self._k0[0], max(iy0, sy) - self._k0[1]
        gx1, gy1 = min(ix1, sx + data.shape[1] - 1) - self._k0[0], min(iy1, sy + data.shape[0] - 1) - self._k0[1]
        gx0, gy0, gx1, gy1 = max(gx0, 0), max(gy0, 0), min(gx1, nx - 1), min(gy1, ny - 1)
        if gx1 < gx0 or gy1 < gy0:
            return
        part = data[gy0 + self._k0[1] - sy:gy1 + self._k0[1] - sy + 1, gx0 + self._k0[0] - sx:gx1 + self._k0[0] - sx + 1]
        occ[gy0:gy1 + 1, gx0:gx1 + 1] = np.where(part == SLICE_OCCUPIED, OCCUPIED,
                                                 np.where(part == SLICE_UNKNOWN, UNKNOWN, FREE))

    def _seen_low_near_start(self, dense, sl: Slice2D, data: np.ndarray) -> np.ndarray:
        """``data`` (the slice ``sl`` of ``dense``, (H, W) slice codes) with the free cells within
        ``start_seen_low_radius_m`` of the start that were not seen free low (``start_seen_low_m``)
        made unknown."""
        c = self.cfg
        centres = sl.cell_centers_xy_m()
        near = np.hypot(centres[..., 0] - self._start_xy[0],
                        centres[..., 1] - self._start_xy[1]) <= c.start_seen_low_radius_m
        if not near.any():
            return data
        low = occupancy_slice(dense, *c.band_m, floor_seen_m=c.start_seen_low_m).data.cpu().numpy()
        return np.where(near & (data != SLICE_OCCUPIED) & (low == SLICE_UNKNOWN), SLICE_UNKNOWN, data)


__all__ = ["OnlineMapper", "OnlineMapperCfg", "OracleMapper", "costmap_of"]
