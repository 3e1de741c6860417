"""How well the navigator's visual odometry tracks its head camera in the apartments: tracked
fraction and ATE of a driven head-camera walk, per apartment, on the dev seeds (200-219; the
navigate benchmark's 0-99 are held out and never tuned on).

    python benchmarks/apartment_vo.py [--seeds 200-219] [--frames 150] [--pitch-deg 18] [--focal-px 262]
                                      [--noise] [--out out/apartment_vo] [--images]

The walk is the one the navigator makes at 10 Hz (``navigation.navigator``): the robot stands at a
sampled start (episode seed 0, geodesic 3-8 m with its clearance), turns on the spot towards the
next waypoint of the geodesic at 6 deg a frame (60 deg/s) and walks 5 cm a frame (0.5 m/s). It is
played kinematically in a ``NavWorld`` (its head camera, head lamp and image size), so the same
seed gives the same frames on every run and only the scene's look and the camera differ. The
odometry (``VoLocalizerCfg().vo``, no gyro) starts at the true first pose; ``tracked`` is the share
of frames whose pose it measured (``VoResult.tracked``), ``ate_m`` the RMS camera position error
over those frames (no alignment: the start is shared). ``--noise`` adds the randomized navigator's
sensor noise (``Randomizer.noisy_images``).

Image figures (over all frames): ``grey_mean`` (0-255), ``saturated`` (share of pixels with a
channel at 255: blown out), ``dark`` (grey < 20), and ``wall_contrast``: the grey standard deviation
of the frames' central 64x64 patch where all of it is wall (depth within 5 % of its median and the
patch's pixels belong to one wall geom), the view the odometry lost.

Before/after a change to the scenes, run it on each tree (e.g. ``git worktree add /tmp/before <sha>``,
then ``PYTHONPATH=/tmp/before/src python benchmarks/apartment_vo.py``): the walks are the same.
Prints ``RESULT {json}``.
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import math
import time
from pathlib import Path

import numpy as np
import torch

from ambulo.navigation.localization import VoLocalizerCfg, is_tracked
from ambulo.navigation.randomization import RandomizationCfg, Randomizer
from ambulo.navigation.world import NavWorld, NavWorldCfg
from ambulo.perception.vo.odometry import RgbdOdometry
from ambulo.robots import humanoid
from ambulo.scenes.apartment import apartment
from ambulo.scenes.apartment_paths import walk_poses
from ambulo.utils.rotations import mat_to_quat


def wall_patch_std(rgb: np.ndarray, depth_m: np.ndarray, geom_ids: np.ndarray) -> float | None:
    """Grey std of the central 64x64 patch if it is one flat surface (depth within 5 % of its
    median, one geom in ``geom_ids``); None otherwise."""
    h, w = depth_m.shape
    sl = np.s_[h // 2 - 32:h // 2 + 32, w // 2 - 32:w // 2 + 32]
    d = depth_m[sl]
    med = float(np.median(d))
    if not med > 0 or (np.abs(d - med) > 0.05 * med).any():
        return None
    if len(np.unique(geom_ids[sl])) > 1:
        return None
    return float(rgb[sl].astype(np.float32).mean(2).std())


def run_walk(seed: int, args, vo_cfg) -> dict:
    apt = apartment(seed)
    ep = apt.sample_start_goal(0, 3.0, 8.0, humanoid.BODY_RADIUS_M)
    cfg = NavWorldCfg(record_gyro=False)
    cfg = dataclasses.replace(cfg, camera_pitch_deg=args.pitch_deg, focal_length_px=args.focal_px)
    world = NavWorld.from_apartment(apt, ep.start_pose, cfg)
    noise = Randomizer(RandomizationCfg(enabled=True), seed) if args.noise else None
    walls = {world.model.geom(s.name + "/geom").id for s in apt.solids if s.look == "wall"}
    qpos = world.engine.field("qpos")
    z = float(qpos[0, 2])
    vo = None
    tracked, errors, grey, sat, dark, contrast, images = [], [], [], [], [], [], []
    try:
        for i, (x, y, yaw) in enumerate(walk_poses(np.asarray(ep.path_xy_m, float), ep.start_pose[2], args.frames)):
            c, s = math.cos(yaw), math.sin(yaw)
            qpos[0, 0:3] = qpos.new_tensor([x, y, z])
            qpos[0, 3:7] = qpos.new_tensor(mat_to_quat(np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])))
            out = world.camera.capture(0)
            rgb, depth, seg = out["rgb"], np.asarray(out["depth"], np.float32), out["geom_ids"]
            pose_wc = np.linalg.inv(out["camera"]["extrinsics_cw"])
            if noise is not None:
                rgb, depth = noise.noisy_images(rgb, depth.copy())
            if vo is None:
                vo = RgbdOdometry(out["camera"]["intrinsics"], vo_cfg, initial_pose_wc=pose_wc)
            result = vo.track(rgb, depth)
            tracked.append(is_tracked(result))
            if tracked[-1]:
                errors.append(float(np.linalg.norm(result.pose_wc[:3, 3] - pose_wc[:3, 3])))
            g = rgb.astype(np.float32).mean(2)
            grey.append(float(g.mean()))
            sat.append(float((rgb.max(2) >= 255).mean()))
            dark.append(float((g < 20).mean()))
            std = wall_patch_std(rgb, depth, seg)
            if std is not None and int(seg[seg.shape[0] // 2, seg.shape[1] // 2]) in walls:
                contrast.append(std)
            if args.images and i in (0, 10, 20, 40):
                images.append(rgb)
    finally:
        world.close()
    if images and args.out:
        import imageio.v3 as iio

        Path(args.out).mkdir(parents=True, exist_ok=True)
        iio.imwrite(Path(args.out) / f"apartment_{seed}.png", np.concatenate(images, 1))
    return {"seed": seed, "frames": len(tracked), "tracked": float(np.mean(tracked)),
            "ate_m": float(np.sqrt(np.mean(np.square(errors)))) if errors else None,
            "grey_mean": float(np.mean(grey)), "saturated": float(np.mean(sat)), "dark": float(np.mean(dark)),
            "wall_contrast": float(np.median(contrast)) if contrast else None, "wall_frames": len(contrast)}


def _seeds(text: str) -> list[int]:
    lo, _, hi = text.partition("-")
    return list(range(int(lo), int(hi or lo) + 1))


def main(argv=None) -> dict:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--seeds", default="200-219")
    p.add_argument("--frames", type=int, default=150, help="most frames per walk")
    p.add_argument("--pitch-deg", type=float, default=NavWorldCfg().camera_pitch_deg)
    p.add_argument("--focal-px", type=float, default=None, help="default: NavWorldCfg's")
    p.add_argument("--noise", action="store_true", help="the randomized navigator's sensor noise")
    p.add_argument("--images", action="store_true", help="save 4 frames per walk into --out")
    p.add_argument("--out", default="")
    p.add_argument("--label", default="")
    args = p.parse_args(argv)
    torch.set_num_threads(1)
    vo_cfg = VoLocalizerCfg().vo
    start = time.perf_counter()
    rows = []
    for seed in _seeds(args.seeds):
        rows.append(run_walk(seed, args, vo_cfg))
        r = rows[-1]
        print(f"apartment {seed}: {r['frames']} frames, tracked {r['tracked']:.0%}, ATE "
              f"{r['ate_m'] if r['ate_m'] is None else round(r['ate_m'], 3)} m, grey {r['grey_mean']:.0f}, "
              f"saturated {r['saturated']:.1%}, wall contrast {r['wall_contrast']}", flush=True)
    ates = [r["ate_m"] for r in rows if r["ate_m"] is not None]
    contrast = [r["wall_contrast"] for r in rows if r["wall_contrast"] is not None]
    summary = {"label": args.label, "seeds": args.seeds, "pitch_deg": args.pitch_deg, "focal_px": args.focal_px,
               "noise": args.noise, "walks": len(rows), "frames": sum(r["frames"] for r in rows),
               "tracked_mean": float(np.mean([r["tracked"] for r in rows])),
               "tracked_min": float(np.min([r["tracked"] for r in rows])),
               "walks_tracked_95": int(sum(r["tracked"] >= 0.95 for r in rows)),
               "ate_median_m": float(np.median(ates)) if ates else None,
               "ate_mean_m": float(np.mean(ates)) if ates else None,
               "walks_ate_under_10cm": int(sum(a < 0.1 for a in ates)),
               "grey_mean": float(np.mean([r["grey_mean"] for r in rows])),
               "saturated_mean": float(np.mean([r["saturated"] for r in rows])),
               "dark_mean": float(np.mean([r["dark"] for r in rows])),
               "wall_contrast_median": float(np.median(contrast)) if contrast else None,
               "wall_s": round(time.perf_counter() - start, 1), "per_walk": rows}
    if args.out:
        Path(args.out).mkdir(parents=True, exist_ok=True)
        (Path(args.out) / f"apartment_vo{('_' + args.label) if args.label else ''}.json").write_text(
            json.dumps(summary, indent=1))
    print("RESULT " + json.dumps({k: v for k, v in summary.items() if k != "per_walk"}))
    return summary


if __name__ == "__main__":
    main()
