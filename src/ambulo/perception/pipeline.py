"""The whole perception stack on one scene: the humanoid walks, visual odometry tracks its head
camera, the TSDF fuses depth at the tracked poses, and the results are written as files a person
can open (what ``ambulo map <scene>`` runs)."""

from __future__ import annotations

import json
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import torch

from ..maps import save_npz
from ..scenes.indoor import IndoorSceneCfg, build_indoor_scene
from ..utils.validate import Checked
from .costmap import InflationCfg, inflate
from .esdf import esdf_from_grid
from .frames import RgbdFrame
from .images import costmap_rgb, draw_path, occupancy_rgb, write_png
from .mesh import IncrementalMesher, write_ply
from .slices import distance_slice, height_map, occupancy_slice, to_grid2d
from .sources.head_camera_walk import WalkCfg, make_walk
from .trajectory import score_tum, write_tum
from .tsdf.map import TsdfCfg, TsdfMap
from .vo.config import VoCfg
from .vo.odometry import RgbdOdometry


@dataclass(kw_only=True)
class MapRunCfg(Checked):
    """What ``run_mapping`` does."""

    scene: IndoorSceneCfg = field(default_factory=IndoorSceneCfg)
    walk: WalkCfg = field(default_factory=WalkCfg)
    walk_mode: str = "kinematic"
    """How the humanoid moves (``ambulo.perception.sources.head_camera_walk.WALK_MODES``): ``"policy"`` walks it with the
    shipped walking policy in a World; ``"kinematic"`` plays a scripted walk."""
    tsdf: TsdfCfg = field(default_factory=TsdfCfg)
    vo: VoCfg = field(default_factory=VoCfg)
    vo_gyro: bool = True
    """Give the odometry the head's gyro (``walk.imu_noise``): it keeps the heading through a loss."""
    inflation: InflationCfg = field(default_factory=InflationCfg)
    num_frames: int = 600
    width: int = 640
    height: int = 480
    use_true_poses: bool = False
    """Fuse depth at the simulator's camera poses instead of the visual odometry's."""
    band_m: tuple[float, float] = (0.1, 1.6)
    """Height band of the occupancy slice: from above the floor to the humanoid's head, m."""
    mesh_every: int = 30
    """Update the incremental mesh every this many frames."""
    device: str = "cpu"


def run_mapping(cfg: MapRunCfg, out_dir: str | Path, progress=None) -> dict:
    """Walk, track, map; write ``estimate.tum``, ``groundtruth.tum``, ``mesh.ply``,
    ``occupancy.png``, ``costmap.png``, ``steppable.png``, ``costmap.npz`` (the occupancy and
    costmap as one ``maps.Grid2D``) and ``summary.json`` into ``out_dir``; return the summary. A run
    too short or too still to score has ``summary["trajectory"]`` metrics of None with their reasons
    (``trajectory.score_tum``); its map is written all the same."""
    if cfg.num_frames < 1:
        raise ValueError(f"MapRunCfg.num_frames is {cfg.num_frames}: a map needs at least 1 frame; pass e.g. "
                         "num_frames=600")
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    scene = build_indoor_scene(cfg.scene)
    walk = make_walk(scene, cfg.walk, mode=cfg.walk_mode, width=cfg.width, height=cfg.height)
    tsdf = TsdfMap(cfg.tsdf, device=cfg.device)
    mesher = IncrementalMesher(tsdf)
    vo = None
    times, est, truth, vo_ms, tsdf_ms = [], [], [], [], []
    try:
        for i in range(cfg.num_frames):
            frame = walk.frame(i)
            if vo is None:
                vo = RgbdOdometry(frame.intrinsics.numpy(), cfg.vo, initial_pose_wc=frame.pose_wc.numpy(),
                                  pose_cam_imu=walk.pose_cam_imu if cfg.vo_gyro else None)
            t0 = time.perf_counter()
            result = vo.track(frame.rgb.numpy(), frame.depth_m.numpy(), gyro=frame.gyro if cfg.vo_gyro else None)
            vo_ms.append((time.perf_counter() - t0) * 1e3)
            pose = frame.pose_wc if cfg.use_true_poses else torch.from_numpy(result.pose_wc)
            t0 = time.perf_counter()
            tsdf.integrate(RgbdFrame(frame.depth_m, frame.rgb, frame.intrinsics, pose, frame.time_s))
            tsdf_ms.append((time.perf_counter() - t0) * 1e3)
            if (i + 1) % cfg.mesh_every == 0:
                mesher.update()
            times.append(frame.time_s)
            est.append(result.pose_wc)
            truth.append(frame.pose_wc.numpy())
            if progress is not None:
                progress(i)
    finally:
        walk.close()
    mesh = mesher.update()
    write_ply(out / "mesh.ply", mesh)
    gt_file = write_tum(out / "groundtruth.tum", times, truth)
    est_file = write_tum(out / "estimate.tum", times, est)
    score = score_tum(gt_file, est_file)
    grid = tsdf.dense()
    occupancy = occupancy_slice(grid, *cfg.band_m)
    costmap = inflate(occupancy, cfg.inflation)
    esdf = esdf_from_grid(grid, max_distance_m=2.0)
    distance = distance_slice(esdf, *cfg.band_m)
    heights = height_map(grid)
    path_xy = np.array(est)[:, :2, 3]
    write_png(out / "occupancy.png", draw_path(occupancy_rgb(occupancy), occupancy, path_xy))
    write_png(out / "costmap.png", draw_path(costmap_rgb(costmap), costmap, path_xy))
    step = heights.steppable.data.cpu().numpy()
    step_rgb = np.where(step[..., None], np.array([60, 170, 80], np.uint8), np.array([200, 200, 205], np.uint8))
    write_png(out / "steppable.png", step_rgb.astype(np.uint8))
    save_npz(out / "costmap.npz", to_grid2d(occupancy, costmap))  # the one map file: ambulo plan --map reads it
    summary = {
        "frames": cfg.num_frames, "resolution": [cfg.width, cfg.height], "poses": "true" if cfg.use_true_poses else "vo",
        "vo_gyro": cfg.vo_gyro,
        "walk": cfg.walk_mode,
        "vo_started": result.num_keyframes > 0,
        "trajectory": score.as_dict(),
        "evo_commands": [f"evo_ape tum {gt_file.name} {est_file.name} --align",
                         f"evo_rpe tum {gt_file.name} {est_file.name} --align --delta 1 --delta_unit m --all_pairs"],
        "vo_ms_median": float(np.median(vo_ms)), "tsdf_ms_median": float(np.median(tsdf_ms)),
        "blocks": tsdf.num_blocks, "map_mb": tsdf.memory_bytes() / 2**20,
        "mesh": {"vertices": len(mesh.vertices), "faces": len(mesh.faces)},
        "occupancy_cells": {k: int((occupancy.data == v).sum()) for k, v in (("unknown", -1), ("free", 0), ("occupied", 1))},
        "min_distance_on_path_m": _min_distance_on_path(distance, path_xy),
        "steppable_fraction": float(step.mean()),
    }
    (out / "summary.json").write_text(json.dumps(summary, indent=2))
    return summary


def _min_distance_on_path(distance, path_xy: np.ndarray) -> float:
    d = distance.data.cpu().numpy()
    values = []
    for x, y in path_xy:
        iy, ix = distance.cell_of((x, y))
        if 0 <= iy < d.shape[0] and 0 <= ix < d.shape[1] and np.isfinite(d[iy, ix]):
            values.append(d[iy, ix])
    return float(min(values)) if values else float("nan")


__all__ = ["MapRunCfg", "run_mapping"]
