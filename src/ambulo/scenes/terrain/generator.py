"""The terrain grid: tiles of sub-terrains by difficulty level, as one MuJoCo heightfield.

Tiles are laid out legged_gym's way: row ``i`` (along x) is difficulty level ``i`` (0 the easiest,
``num_levels - 1`` the hardest), column ``j`` (along y) is sub-terrain kind ``cfg.kinds[j]``.
A flat border of ``border_m`` surrounds the grid. The grid is centred on the world origin.

One representation for physics and observation: the heights are one ``(nx, ny)`` array of
samples ``h`` metres apart; ``add_terrain`` builds it into the scene as a single ``hfield`` geom
(the CPU engine and MuJoCo Warp both collide an hfield with spheres, capsules, boxes and meshes:
``mujoco_warp/_src/collision_driver.py`` maps every hfield pair to its convex path), and
``terrain.heights.TerrainHeights`` interpolates the same array on the device for height scans,
fall checks and spawning. MuJoCo draws each cell as two triangles and the lookup is bilinear:
they agree at samples and wherever the cell is planar (treads, slopes, the border). With
``TerrainCfg.box_tiles`` the piecewise-flat tiles collide as static boxes built from the same
samples (``terrain.boxes``: one contact per resting sphere in both engines); ``box_kinds`` says
which kinds (flat and stairs by default; stepping stones too on request).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import mujoco
import numpy as np

from ...utils.validate import Checked, rule
from .boxes import BOX_KINDS, PIECEWISE_FLAT_KINDS, hfield_heights, terrain_boxes
from .subterrains import KINDS, TileGrid

TERRAIN_PRIM_PATH = "/World/terrain"
"""The terrain's body; its geom is ``/World/terrain/geom``."""


@dataclass(kw_only=True)
class TerrainCfg(Checked):
    """A grid of ``num_levels`` x ``len(kinds)`` square tiles. Ranges are (easiest, hardest)."""

    kinds: tuple[str, ...] = ("flat", "rough", "slope_up", "slope_down", "stairs_up", "stairs_down",
                              "stepping_stones")
    """One column of tiles per entry (repeat a kind for more of it); see ``subterrains.KINDS``."""
    num_levels: int = field(default=10, metadata=rule(minimum=1))
    tile_size_m: float = 8.0
    """Edge of one square tile, m (legged_gym's 8 m)."""
    spacing_m: float = 0.05
    """Heightfield sample spacing, m: a stair edge is a ramp one sample wide in MuJoCo's hfield, so
    5 cm keeps a 0.15 m riser 72 degrees steep (legged_gym's 0.1 m spacing makes it 56)."""
    border_m: float = 2.0
    """Flat ground around the grid, m."""
    platform_size_m: float = 2.0
    """Edge of the flat square at each tile's centre where robots start, m."""
    slope_grade_range: tuple[float, float] = (0.0, 0.3)
    """Rise per run of the slopes (0.3: 17 degrees)."""
    stair_riser_range_m: tuple[float, float] = (0.05, 0.15)
    """Step height; the hardest level has the issue's 0.15 m risers."""
    stair_tread_m: float = 0.30
    """Step depth, m (rounded to whole samples)."""
    rough_amplitude_range_m: tuple[float, float] = (0.01, 0.06)
    """Half-range of the random heights of rough tiles, m."""
    rough_cell_m: float = 0.25
    """Spacing of the random heights that rough tiles interpolate between, m."""
    stone_edge_m: tuple[float, float] = field(default=(0.8, 0.4), metadata=rule(signed=True))
    """Stepping-stone edge at the easiest and the hardest level, m (stones shrink)."""
    stone_gap_range_m: tuple[float, float] = (0.05, 0.20)
    """Gap between stones, m."""
    stone_pit_depth_m: float = field(default=0.5, metadata=rule(minimum=0.0))
    """How far below the stones the gaps go, m."""
    seed: int = 0
    """Seed of the random sub-terrains (rough heights, stone offsets)."""
    box_tiles: bool = True
    """Build the tiles of ``box_kinds`` and the border as static boxes, the other kinds in the
    hfield (``terrain.boxes``: MuJoCo C gives a sphere on a flat hfield one contact per prism it
    overlaps, MuJoCo Warp one, and a policy trained on Warp fell on MuJoCo C); False: everything
    in the hfield (before session 15), whatever ``box_kinds``."""
    box_kinds: tuple[str, ...] = BOX_KINDS
    """The kinds built as boxes with ``box_tiles``: some of ``boxes.PIECEWISE_FLAT_KINDS`` (add
    ``stepping_stones`` for stones as boxes; docs/terrain.md has the costs)."""

    def __post_init__(self):
        unknown = sorted(set(self.kinds) - set(KINDS))
        if unknown or not self.kinds:
            raise ValueError(f"TerrainCfg.kinds {list(self.kinds)}: unknown {unknown}; use some of {sorted(KINDS)}")
        not_flat = sorted(set(self.box_kinds) - set(PIECEWISE_FLAT_KINDS))
        if not_flat:
            raise ValueError(f"TerrainCfg.box_kinds {list(self.box_kinds)}: {not_flat} cannot be boxes (not "
                             f"piecewise flat); use some of {list(PIECEWISE_FLAT_KINDS)}")
        if self.platform_size_m > self.tile_size_m:
            raise ValueError(f"TerrainCfg.platform_size_m {self.platform_size_m} is larger than the tile "
                             f"({self.tile_size_m} m); make the platform smaller")
        super().__post_init__()

    @property
    def tile_samples(self) -> int:
        """Samples along a tile's edge."""
        return int(round(self.tile_size_m / self.spacing_m))

    @property
    def border_samples(self) -> int:
        """Samples of the flat border on each side of the tiles."""
        return int(round(self.border_m / self.spacing_m))

    def tile_slices(self, level: int, kind: int) -> tuple[slice, slice]:
        """The (x, y) sample slices of tile (``level``, ``kind`` column) in the heights array."""
        n, border = self.tile_samples, self.border_samples
        x0, y0 = border + level * n, border + kind * n
        return slice(x0, x0 + n), slice(y0, y0 + n)


@dataclass(frozen=True)
class TerrainGrid:
    """The generated terrain: heights and where each tile is.

    Attributes:
      heights_m: (nx, ny) float64 sample heights, m, indexed [ix, iy]; sample (ix, iy) is at
        ``origin_xy_m + (ix, iy) * spacing_m`` in the world frame.
      origin_xy_m: (2,) world position of sample (0, 0), m.
      spacing_m: sample spacing, m.
      tile_centers_w: (num_levels, num_kinds, 3) world position of each tile's centre on its
        platform, m (where the robots of that tile start).
      difficulty: (num_levels,) difficulty in [0, 1] of each level.
    """

    cfg: TerrainCfg
    heights_m: np.ndarray
    origin_xy_m: np.ndarray
    spacing_m: float
    tile_centers_w: np.ndarray
    difficulty: np.ndarray

    @property
    def num_levels(self) -> int:
        return self.tile_centers_w.shape[0]

    @property
    def num_kinds(self) -> int:
        return self.tile_centers_w.shape[1]

    def height_at(self, x_m, y_m) -> np.ndarray:
        """Heights (m) at world points, bilinear between samples (host side: tests, spawning)."""
        fx = (np.asarray(x_m, np.float64) - self.origin_xy_m[0]) / self.spacing_m
        fy = (np.asarray(y_m, np.float64) - self.origin_xy_m[1]) / self.spacing_m
        nx, ny = self.heights_m.shape
        fx, fy = np.clip(fx, 0, nx - 1), np.clip(fy, 0, ny - 1)
        x0 = np.minimum(np.floor(fx).astype(int), nx - 2)
        y0 = np.minimum(np.floor(fy).astype(int), ny - 2)
        tx, ty = fx - x0, fy - y0
        h = self.heights_m
        return ((h[x0, y0] * (1 - tx) + h[x0 + 1, y0] * tx) * (1 - ty)
                + (h[x0, y0 + 1] * (1 - tx) + h[x0 + 1, y0 + 1] * tx) * ty)


def difficulties(num_levels: int) -> np.ndarray:
    """Level ``i``'s difficulty ``i / (num_levels - 1)``: the last level is the hardest setting."""
    return np.linspace(0.0, 1.0, num_levels) if num_levels > 1 else np.ones(1)


def generate(cfg: TerrainCfg) -> TerrainGrid:
    """The terrain of ``cfg``: each tile's heights from its kind's function at its level's
    difficulty, seeded per tile (a tile is the same whatever the grid's other tiles)."""
    h = cfg.spacing_m
    n, border = cfg.tile_samples, cfg.border_samples
    tile = TileGrid(num=n, spacing_m=h, platform_half=int(round(cfg.platform_size_m / (2 * h))))
    num_kinds = len(cfg.kinds)
    # one sample more than the tiles span: the far border's last sample closes the grid
    heights = np.zeros((2 * border + cfg.num_levels * n + 1, 2 * border + num_kinds * n + 1))
    level_d = difficulties(cfg.num_levels)
    for i, d in enumerate(level_d):
        for j, kind in enumerate(cfg.kinds):
            rng = np.random.default_rng([cfg.seed, i, j])
            heights[cfg.tile_slices(i, j)] = KINDS[kind](tile, float(d), cfg, rng)
    size = (np.array(heights.shape) - 1) * h
    origin = -size / 2.0
    centers = np.zeros((cfg.num_levels, num_kinds, 3))
    centers[..., 0] = origin[0] + (border + (np.arange(cfg.num_levels)[:, None] + 0.5) * n) * h
    centers[..., 1] = origin[1] + (border + (np.arange(num_kinds)[None, :] + 0.5) * n) * h
    centers[..., 2] = heights[border + (np.arange(cfg.num_levels)[:, None]) * n + n // 2,
                              border + (np.arange(num_kinds)[None, :]) * n + n // 2]
    return TerrainGrid(cfg, heights, origin, h, centers, level_d)


_MIN_ELEVATION_M = 1.0e-3
"""A flat terrain still needs an hfield elevation > 0 (MuJoCo's rule); its data is all 0."""


def add_terrain(spec: mujoco.MjSpec, grid: TerrainGrid, *, friction: float = 1.0,
                prim_path: str = TERRAIN_PRIM_PATH, base_depth_m: float = 1.0,
                color=(0.45, 0.47, 0.50)) -> mujoco.MjsGeom:
    """Add ``grid`` to ``spec`` as the static body ``<prim_path>``: one hfield geom
    ``<prim_path>/geom`` (returned) and, with ``grid.cfg.box_tiles``, the ``box_kinds`` tiles' boxes
    ``<prim_path>/box<i>`` (``terrain.boxes``; the hfield sinks under them).

    MuJoCo stores heights normalized to [0, 1] times the elevation ``size[2]``, above the geom's
    z, rows along y: the geom sits at the lowest height, the elevation is the height range, and the
    data is the transposed, normalized array (so MuJoCo's own normalization leaves it unchanged).
    ``base_depth_m``: thickness of the solid under the lowest point (MuJoCo's ``size[3]``)."""
    boxes = terrain_boxes(grid) if grid.cfg.box_tiles else None
    heights = grid.heights_m if boxes is None else hfield_heights(grid, boxes.mask)
    low, high = float(heights.min()), float(heights.max())
    span = high - low
    data = (heights - low) / span if span > _MIN_ELEVATION_M else np.zeros_like(heights)
    nx, ny = heights.shape
    half = (np.array([nx, ny]) - 1) * grid.spacing_m / 2.0
    hfield = spec.add_hfield(name=prim_path + "/hfield", nrow=ny, ncol=nx,
                             size=[half[0], half[1], max(span, _MIN_ELEVATION_M), base_depth_m])
    hfield.userdata = data.T.astype(np.float32).ravel().tolist()
    center = grid.origin_xy_m + half
    body_pos = np.array([center[0], center[1], low])
    body = spec.worldbody.add_body(name=prim_path, pos=body_pos)
    material = prim_path + "/material"
    spec.add_material(name=material, rgba=[*color, 1.0])
    friction3 = [friction, 0.005, 0.0001]
    geom = body.add_geom(name=prim_path + "/geom", type=mujoco.mjtGeom.mjGEOM_HFIELD,
                         hfieldname=prim_path + "/hfield", material=material, friction=friction3)
    if boxes is not None:
        for i, (c, s) in enumerate(zip(boxes.center_w - body_pos, boxes.half_size_m)):
            body.add_geom(name=f"{prim_path}/box{i}", type=mujoco.mjtGeom.mjGEOM_BOX, pos=c, size=s,
                          material=material, friction=friction3)
    return geom


__all__ = ["TERRAIN_PRIM_PATH", "TerrainCfg", "TerrainGrid", "add_terrain", "difficulties", "generate"]
