"""The whole perception stack on one scene: the humanoid walks, visual odometry tracks its head
camera, the TSDF fuses depth at the tracked poses, and the results are written as files a person
can open (what ``ambulo map <scene>`` runs).

An untracked frame (``VoResult.tracked`` False: tracking lost, the pose coasted) is never fused:
its depth at a guessed pose would put walls where they are not. The trajectory is scored on the
tracked poses only (``estimate.tum``); all poses, coasted ones included, are in
``estimate_all.tum``, and the summary counts the untracked frames and their largest position error.
With ``use_true_poses`` every frame is fused at its true pose (the odometry still runs and is
scored the same way)."""

from __future__ import annotations

import json
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import torch

from ..maps import save_npz
from ..scenes.indoor import IndoorSceneCfg, build_indoor_scene
from ..utils.checks import Described, InvalidValueError
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
    times, est, truth, tracked, vo_ms, tsdf_ms = [], [], [], [], [], []
    try:
        for i in range(cfg.num_frames):
            frame = walk.frame(i)
            if vo is None:
                vo = RgbdOdometry(frame.intrinsics.numpy(), cfg.vo, initial_pose_wc=frame.pose_wc.numpy(),
                                  pose_cam_imu=walk.pose_cam_imu if cfg.vo_gyro else None)
            t0 = time.perf_counter()
            result = vo.track(frame.rgb.numpy(), frame.depth_m.numpy(), gyro=frame.gyro if cfg.vo_gyro else None)
            vo_ms.append((time.perf_counter() - t0) * 1e3)
            if cfg.use_true_poses or result.tracked:  # never fuse at a coasted pose
                pose = frame.pose_wc if cfg.use_true_poses else torch.from_numpy(result.pose_wc)
                t0 = time.perf_counter()
                tsdf.integrate(RgbdFrame(frame.depth_m, frame.rgb, frame.intrinsics, pose, frame.time_s))
                tsdf_ms.append((time.perf_counter() - t0) * 1e3)
            if (i + 1) % cfg.mesh_every == 0:
                mesher.update()
            times.append(frame.time_s)
            est.append(result.pose_wc)
            truth.append(frame.pose_wc.numpy())
            tracked.append(result.tracked)
            if progress is not None:
                progress(i)
    finally:
        walk.close()
    mesh = mesher.update()
    write_ply(out / "mesh.ply", mesh)
    gt_file = write_tum(out / "groundtruth.tum", times, truth)
    keep = np.array(tracked, bool)
    est_file = write_tum(out / "estimate.tum", np.asarray(times)[keep], np.asarray(est)[keep])
    write_tum(out / "estimate_all.tum", times, est)
    score = score_tum(gt_file, est_file)
    if not tsdf.num_blocks:
        raise InvalidValueError("the image size", Described(f"{cfg.width}x{cfg.height}"),
                                f"the odometry tracked none of the {cfg.num_frames} frames (too few features with "
                                "depth), so none was fused and the map is empty",
                                "give a larger --width/--height (e.g. the default 640x480) or --true-poses")
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
        "trajectory_scored": f"tracked poses only ({int(keep.sum())} of {len(keep)})",
        "untracked_frames": int((~keep).sum()),
        "fused_frames": len(tsdf_ms),
        "untracked_max_position_error_m": _max_error_m(np.asarray(est)[~keep], np.asarray(truth)[~keep]),
        "evo_commands": [f"evo_ape tum {gt_file.name} {est_file.name} --align",
                         f"evo_rpe tum {gt_file.name} {est_file.name} --align --delta 1 --delta_unit m --all_pairs"],
        "vo_ms_median": float(np.median(vo_ms)), "tsdf_ms_median": float(np.median(tsdf_ms)) if tsdf_ms else None,
        "blocks": tsdf.num_blocks, "map_mb": tsdf.memory_bytes() / 2**20,
        "mesh": {"vertices": len(mesh.vertices), "faces": len(mesh.faces)},
        "occupancy_cells": {k: int((occupancy.data == v).sum()) for k, v in (("unknown", -1), ("free", 0), ("occupied", 1))},
        "min_distance_on_path_m": _min_distance_on_path(distance, path_xy),
        "steppable_fraction": float(step.mean()),
    }
    (out / "summary.json").write_text(json.dumps(summary, indent=2))
    return summary


def _max_error_m(est_wc: np.ndarray, truth_wc: np.ndarray) -> float | None:
    """Largest distance between estimated and true camera positions (unaligned), m; None for no poses."""
    if len(est_wc) == 0:
        return None
    return float(np.linalg.norm(est_wc[:, :3, 3] - truth_wc[:, :3, 3], axis=1).max())


def _min_distance_on_path(distance, path_xy: np.ndarray) -> float:
    d = distance.data.cpu().numpy()
    values = []
    for x, y in path_xy:
        iy, ix = distance.cell_of((x, y))
        if 0 <= iy < d.shape[0] and 0 <= ix < d.shape[1] and np.isfinite(d[iy, ix]):
            values.append(d[iy, ix])
    return float(min(values)) if values else float("nan")


__all__ = ["MapRunCfg", "run_mapping"]
