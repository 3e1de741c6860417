"""The mapping acceptance on a seeded apartment: walk the head camera along a sampled geodesic
(``sources.apartment_walk``, true poses), fuse every frame into a ``TsdfMap`` and score the body
band's occupancy slice against the apartment's exact occupancy (``occupancy_eval``): the test
(tests/perception/test_apartment_mapping.py) and ``benchmarks/mapping.py --apartment`` run this.

The map is fused at the true poses shifted by ``occupancy_eval.aligned_offset_xy_m`` (a change of map
frame, nothing else), so its voxel columns are the truth's cells and thickness is measured cell for cell.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field

import numpy as np
import torch

from ..scenes.apartment import Apartment, apartment
from ..scenes.apartment_geometry import rasterize
from ..scenes.apartment_layout import footprints
from .frames import RgbdFrame
from .occupancy_eval import SliceScore, VisibleCells, aligned_offset_xy_m, score_slice, slice_on_cells
from .slices import Slice2D, occupancy_slice
from .sources.apartment_walk import ApartmentWalk, ApartmentWalkCfg
from .tsdf.map import TsdfCfg, TsdfMap


@dataclass
class ApartmentMapRun:
    apt: Apartment
    tsdf: TsdfMap
    offset_m: np.ndarray
    """(3,) the world shift the map was fused with (map = world + offset)."""
    visible: VisibleCells
    frames: int
    path_m: float
    integrate_ms: list[float] = field(default_factory=list)

    def slice(self, band_m: tuple[float, float], slicer=occupancy_slice) -> Slice2D:
        return slicer(self.tsdf.dense(), *band_m)

    def score(self, band_m: tuple[float, float], slicer=occupancy_slice) -> SliceScore:
        """``occupancy_eval.score_slice`` of the band's slice (``slicer(grid, z_min, z_max)``), wall
        thickness over the apartment's walls only."""
        pred = slice_on_cells(self.slice(band_m, slicer), self.apt.occupancy, self.offset_m[:2])
        return score_slice(pred, self.apt.occupancy, self.visible.mask, walls=self.wall_cells())

    def wall_cells(self) -> np.ndarray:
        """(H, W) bool the cells of the apartment's walls (the truth's rule, walls only)."""
        occ, cfg = self.apt.occupancy, self.apt.cfg
        walls = footprints([s for s in self.apt.solids if s.look == "wall"], cfg.step_height_m, cfg.head_height_m)
        return rasterize(walls, occ.origin_xy_m, occ.resolution_m, occ.shape)


def walk_and_map(seed: int, *, episode_seed: int = 0, min_geodesic_m: float = 6.0, tsdf_cfg: TsdfCfg | None = None,
                 walk_cfg: ApartmentWalkCfg | None = None, band_m: tuple[float, float] = (0.05, 1.6),
                 width: int = 320, height: int = 240, num_frames: int | None = None,
                 device: str = "cpu") -> ApartmentMapRun:
    """Walk apartment ``seed`` start to goal (``Apartment.sample_start_goal(episode_seed, min_geodesic_m)``)
    and fuse every frame (``num_frames``: the walk's own by default); the seen cells are counted over
    the height ``band_m``."""
    apt = apartment(seed)
    episode = apt.sample_start_goal(episode_seed, min_geodesic_m=min_geodesic_m)
    cfg = tsdf_cfg or TsdfCfg()
    walk = ApartmentWalk(apt, episode, walk_cfg, width=width, height=height)
    tsdf = TsdfMap(cfg, device=device)
    offset = aligned_offset_xy_m(apt.occupancy, cfg.voxel_size_m)
    visible = VisibleCells(apt.occupancy, *band_m, depth_min_m=cfg.depth_min_m, depth_max_m=cfg.depth_max_m)
    n = num_frames or walk.num_frames
    run = ApartmentMapRun(apt, tsdf, offset, visible, n, walk.length_m)
    try:
        for i in range(n):
            frame = walk.frame(i)
            visible.add(frame)
            pose = frame.pose_wc.clone()
            pose[:3, 3] += torch.from_numpy(offset)
            t0 = time.perf_counter()
            tsdf.integrate(RgbdFrame(frame.depth_m.to(device), frame.rgb.to(device), frame.intrinsics, pose,
                                     frame.time_s))
            run.integrate_ms.append((time.perf_counter() - t0) * 1e3)
    finally:
        walk.close()
    return run


__all__ = ["ApartmentMapRun", "walk_and_map"]
