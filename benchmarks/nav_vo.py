"""The navigator's visual odometry, frame by frame: its wall time per frame against the ORB front
end's alone (the ceiling), and its accuracy, on head-camera frames recorded from full-mode episodes.

    python benchmarks/nav_vo.py [--seeds 201,202] [--data out/nav_vo] [--variants brute,default]
                                [--frames 0] [--repeat 1]

1. **Record** (once per seed; skipped when ``<data>/apt<seed>.npz`` exists): a full-mode navigation
   episode (``metrics.run_episode``, episode seed 0, the dev apartments: the benchmark's 0-99 are
   held out) runs with the current code, and every frame the odometry was given is saved: RGB,
   depth, the gyro's samples, the legs' camera motion since the previous frame (the odometry's
   motion prior, ``LegVoLocalizer``), the true camera pose, the intrinsics and the gyro's extrinsic.
2. **Replay** each ``--variants`` odometry config on those frames, open loop (the frames do not
   depend on the replayed estimate), one torch thread and one OpenCV thread, as a benchmark worker
   runs: per frame the wall time of ``RgbdOdometry.track``; tracked share; ATE (RMS camera position
   error over the tracked frames, m; the odometry starts at the true first pose, so no alignment);
   and the time of ``cv2.ORB.detectAndCompute`` alone on the same frames in the same process (the
   ceiling: no feature odometry with this front end can be faster). Times are CPU time of this
   process (``time.process_time``: one thread each, so it is the work, not the other processes'
   share of a busy machine) and wall time. ``ratio_to_ceiling`` = median ceiling CPU ms / median
   odometry CPU ms (1 would be an odometry that costs nothing but its features).

Variants: ``default`` (``head_camera_vo_cfg()``, the navigator's), ``brute`` (the same with
``match_window_px=None``: every keypoint against the whole local map, as before the guided
matching). Prints ``RESULT {json}`` with per-variant medians over all frames of all seeds.
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import os
import time
from pathlib import Path

import numpy as np

VARIANTS = ("default", "brute")


def variant_cfg(name: str):
    from ambulo.perception.vo.config import head_camera_vo_cfg

    cfg = head_camera_vo_cfg()
    if name == "default":
        return cfg
    if name == "brute":
        return dataclasses.replace(cfg, match_window_px=None)
    raise SystemExit(f"unknown variant {name!r}: use one of {', '.join(VARIANTS)}")


def record(seed: int, path: Path) -> dict:
    """Run a full-mode episode in ``apartment(seed)`` and save the odometry's inputs (module doc, 1)."""
    from ambulo.navigation.benchmark import EpisodeSpec, episode_cfg
    from ambulo.navigation.metrics import run_episode
    from ambulo.perception.vo.odometry import RgbdOdometry

    calls, truth, first = [], [], {}
    track = RgbdOdometry.track

    def recording_track(self, rgb, depth, gyro=None, motion_cam=None):
        if not first:
            first.update(initial_pose_wc=self.pose_wc.copy(),
                         pose_cam_imu=None if self.gyro is None else self.gyro.pose_cam_imu.copy(), k=self.k.copy())
        calls.append((np.array(rgb), np.array(depth, np.float32), gyro,
                      None if motion_cam is None else np.array(motion_cam, np.float64)))
        return track(self, rgb, depth, gyro=gyro, motion_cam=motion_cam)

    def observer(snap):
        truth.append(snap.frame.pose_wc.numpy().copy())

    RgbdOdometry.track = recording_track  # this process only records: restored below
    try:
        result = run_episode(seed, 0, episode_cfg(EpisodeSpec(seed, 0, "full")), observer=observer)
    finally:
        RgbdOdometry.track = track
    n = len(calls)
    gyro_counts = np.array([0 if g is None else len(g.time_s) for _, _, g, _ in calls])
    gyros = [g for _, _, g, _ in calls if g is not None]
    np.savez_compressed(
        path, rgb=np.stack([c[0] for c in calls]), depth_m=np.stack([c[1] for c in calls]),
        motion_cam=np.stack([np.full((4, 4), np.nan) if c[3] is None else c[3] for c in calls]),
        pose_wc_true=np.stack(truth[:n]), gyro_counts=gyro_counts,
        gyro_time_s=np.concatenate([g.time_s for g in gyros]) if gyros else np.zeros(0),
        gyro_rad_s=np.concatenate([g.ang_vel_rad_s for g in gyros]) if gyros else np.zeros((0, 3)),
        k=first["k"], initial_pose_wc=first["initial_pose_wc"],
        pose_cam_imu=np.full((4, 4), np.nan) if first["pose_cam_imu"] is None else first["pose_cam_imu"])
    return {"seed": seed, "frames": n, "status": result.status, "ate_m": result.ate_m}


def replay(data: dict, cfg, frames: int = 0) -> dict:
    """Track the recorded frames with ``cfg``; per-frame times (ms), tracked share, ATE (m)."""
    import cv2

    from ambulo.navigation.localization import is_tracked
    from ambulo.perception.vo.imu import GyroSamples
    from ambulo.perception.vo.odometry import RgbdOdometry

    n = len(data["rgb"]) if frames <= 0 else min(frames, len(data["rgb"]))
    ext = None if np.isnan(data["pose_cam_imu"]).any() else data["pose_cam_imu"]
    vo = RgbdOdometry(data["k"], cfg, initial_pose_wc=data["initial_pose_wc"], pose_cam_imu=ext)
    ends = np.cumsum(data["gyro_counts"])
    times, errors, ceiling = [], [], []
    orb = cv2.ORB_create(nfeatures=cfg.num_features, fastThreshold=cfg.fast_threshold, patchSize=cfg.orb_patch_px,
                         edgeThreshold=cfg.orb_edge_px)
    for i in range(n):
        count = int(data["gyro_counts"][i])
        gyro = None if count == 0 else GyroSamples(data["gyro_time_s"][ends[i] - count:ends[i]],
                                                   data["gyro_rad_s"][ends[i] - count:ends[i]])
        motion = data["motion_cam"][i]
        prior = {} if np.isnan(motion).any() else {"motion_cam": motion}
        rgb, depth = data["rgb"][i], data["depth_m"][i]
        t0, c0 = time.perf_counter(), time.process_time()
        result = vo.track(rgb, depth, gyro=gyro if ext is not None else None, **prior)
        times.append((time.perf_counter() - t0, time.process_time() - c0))
        t0, c0 = time.perf_counter(), time.process_time()
        orb.detectAndCompute(cv2.cvtColor(rgb, cv2.COLOR_RGB2GRAY), None)
        ceiling.append((time.perf_counter() - t0, time.process_time() - c0))
        if is_tracked(result):
            errors.append(float(np.linalg.norm(result.pose_wc[:3, 3] - data["pose_wc_true"][i][:3, 3])))
    times, ceiling = 1e3 * np.asarray(times), 1e3 * np.asarray(ceiling)
    return {"frames": n, "vo_ms": times[:, 0], "vo_cpu_ms": times[:, 1], "ceiling_ms": ceiling[:, 0],
            "ceiling_cpu_ms": ceiling[:, 1],
            "tracked": len(errors) / max(n, 1),
            "ate_m": float(np.sqrt(np.mean(np.square(errors)))) if errors else None}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--seeds", default="201,202")
    ap.add_argument("--data", default="out/nav_vo")
    ap.add_argument("--variants", default="brute,default")
    ap.add_argument("--frames", type=int, default=0, help="replay only the first N frames of each episode (0: all)")
    ap.add_argument("--repeat", type=int, default=1, help="replay each variant this many times (timings pooled)")
    args = ap.parse_args()
    import cv2
    import torch

    torch.set_num_threads(1)  # as a benchmark worker runs (navigation.benchmark)
    cv2.setNumThreads(1)
    out = Path(args.data)
    out.mkdir(parents=True, exist_ok=True)
    seeds = [int(s) for s in args.seeds.split(",")]
    recorded = []
    for seed in seeds:
        path = out / f"apt{seed:04d}.npz"
        if not path.is_file():
            recorded.append(record(seed, path))
            print("recorded", recorded[-1], flush=True)
    episodes = {seed: dict(np.load(out / f"apt{seed:04d}.npz")) for seed in seeds}
    load_start = os.getloadavg()[0]
    rows = {}
    for name in args.variants.split(","):
        cfg = variant_cfg(name)
        per_seed, runs = {}, []
        for seed, data in episodes.items():
            for _ in range(args.repeat):
                r = replay(data, cfg, args.frames)
                runs.append(r)
            per_seed[seed] = {"frames": r["frames"], "tracked": r["tracked"], "ate_m": r["ate_m"],
                              "vo_cpu_ms_median": float(np.median(r["vo_cpu_ms"]))}
        pooled = {key: np.concatenate([r[key] for r in runs]) for key in ("vo_ms", "vo_cpu_ms", "ceiling_ms",
                                                                          "ceiling_cpu_ms")}
        rows[name] = {**{f"{key}_median": float(np.median(v)) for key, v in pooled.items()},
                      "vo_cpu_ms_mean": float(pooled["vo_cpu_ms"].mean()),
                      "vo_cpu_ms_p90": float(np.percentile(pooled["vo_cpu_ms"], 90)),
                      "ratio_to_ceiling": float(np.median(pooled["ceiling_cpu_ms"]) / np.median(pooled["vo_cpu_ms"])),
                      "seeds": per_seed}
        print(name, json.dumps({k: round(v, 3) for k, v in rows[name].items() if k != "seeds"}),
              {s: (round(v["tracked"], 3), v["ate_m"]) for s, v in per_seed.items()}, flush=True)
    print("RESULT " + json.dumps({"benchmark": "nav_vo", "seeds": seeds, "recorded": recorded, "variants": rows,
                                  "ratio_to_ceiling": {k: v["ratio_to_ceiling"] for k, v in rows.items()},
                                  "load_start": load_start, "load_end": os.getloadavg()[0],
                                  "cpus": os.cpu_count()}))


if __name__ == "__main__":
    main()
