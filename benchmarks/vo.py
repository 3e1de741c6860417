"""Visual odometry on the humanoid's head camera: accuracy (evo ATE / RPE), frames per second and
recovery after a covered lens.

    python benchmarks/vo.py [--walk policy|kinematic] [--frames 600] [--speed 0.5] [--width 640 --height 480]
                            [--blackout-at 300] [--features orb|kornia] [--device cpu|cuda] [--pnp opencv|torch]
                            [--imu] [--no-cuda-graphs] [--out out/vo]

The bundled humanoid walks the seeded indoor scene's loop around the island at 0.5 m/s (``--speed``)
(``ambulo.perception.sources``). ``--walk policy`` (the default): it walks under the shipped walking
policy in an ``ambulo.sim.World`` (physics every 5 ms), steered along the loop by a pure-pursuit
path follower, so the head camera carries the real gait (foot impacts, sway, heading wobble);
``--walk kinematic``: it is played kinematically with a scripted head bob and sway. The head camera
renders every 1/30 s of simulated time; two boxes slide across the room. The estimate starts at
the true first pose. ATE = evo APE RMSE after SE(3) alignment; RPE = evo RPE RMSE over all pairs
1 m of travel apart, in % of that metre. The second run (the same walk again: the simulation is
deterministic) blacks out 1 s (30 frames: black colour, no depth) at ``--blackout-at`` and reports
how many frames after the lens clears tracking is back (position error < 5 cm); the third puts a
textureless wall (uniform grey, depth 0.5 m) before the lens for the same second. Then two fast
head turns on the kinematic walk at the same moment (``WalkCfg.look_away``): 90 deg away and back in
1 s (peak 283 deg/s) and 180 deg in 0.4 s (peak 1400 deg/s): frames lost, frames to recover after
the turn, largest position error.

``ratio`` = ATE / 2 cm (the acceptance's limit; <= 1 meets it). ATE and RPE score the tracked poses only
(``VoResult.tracked``; ``scored`` and ``untracked_frames`` say how many), so a loss shows in the
blackout figures, not in the ATE. The odometry runs its torch ops on one thread
(``ambulo.perception.torch_threads``); ``vo_ms`` is its median / p90 time a frame. The odometry's front end is
``--features``: ``orb`` (the default: OpenCV ORB and ``solvePnPRansac`` on the CPU) or ``kornia``
(``ambulo.perception.vo.kornia_vo_cfg``: kornia corners + RootSIFT, matching and RANSAC in torch on
``--device``); ``--pnp`` overrides the RANSAC (``opencv`` with kornia features: features and
matching on the device, PnP on the host). ``--imu`` gives the odometry the walk's gyro (EuRoC's
ADIS16448 noise, ``ambulo.perception.vo.imu``); losses then also report the heading error while
blind. The reported fps is the odometry alone (median of the
first run's frames), rendering and physics excluded; frames are rendered on the CPU, so on CUDA it
includes copying each frame to the GPU.
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import math
from pathlib import Path

import numpy as np
import torch

from ambulo.perception.sources import WALK_MODES, PolicyHeadCameraWalk, WalkCfg, make_walk
from ambulo.perception.vo import TrackState, VoCfg, kornia_vo_cfg
from ambulo.perception.vo.eval import run_walk_vo
from ambulo.scenes.indoor import build_indoor_scene


def main(argv=None) -> dict:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--walk", choices=WALK_MODES, default="policy")
    parser.add_argument("--frames", type=int, default=600)
    parser.add_argument("--speed", type=float, default=0.5, help="walking speed along the loop, m/s (policy: <= 1)")
    parser.add_argument("--width", type=int, default=640)
    parser.add_argument("--height", type=int, default=480)
    parser.add_argument("--blackout-at", type=int, default=300)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--features", choices=("orb", "kornia"), default="orb")
    parser.add_argument("--device", default="cpu", help="torch device of the kornia front end: cpu, cuda, cuda:1")
    parser.add_argument("--pnp", choices=("opencv", "torch"), default=None,
                        help="RANSAC (default: opencv for orb, torch for kornia)")
    parser.add_argument("--imu", action="store_true", help="fuse the head's gyro (loosely coupled)")
    parser.add_argument("--no-cuda-graphs", action="store_true", help="CUDA: refine eagerly, not from captured graphs")
    parser.add_argument("--out", type=Path, default=Path("out/vo"))
    args = parser.parse_args(argv)
    from ambulo.scenes.indoor import IndoorSceneCfg

    cfg = VoCfg(device=args.device) if args.features == "orb" else kornia_vo_cfg(args.device)
    if args.pnp is not None:
        cfg = dataclasses.replace(cfg, pnp=args.pnp)
    cfg = dataclasses.replace(cfg, cuda_graphs=not args.no_cuda_graphs)
    walk = make_walk(build_indoor_scene(IndoorSceneCfg(seed=args.seed)), WalkCfg(speed_mps=args.speed),
                     mode=args.walk, width=args.width, height=args.height)
    run = run_walk_vo(walk, args.frames, cfg, imu=args.imu)
    score = run.score(args.out)
    gait = None
    if isinstance(walk, PolicyHeadCameraWalk):
        walked_m = float(np.linalg.norm(np.diff(walk.root_xy_m, axis=0), axis=1).sum())
        gait = {"fell": bool(walk.fell), "root_path_m": round(walked_m, 2),
                "max_cross_track_m": round(max(walk.cross_track_m), 3),
                "min_pelvis_height_m": round(min(walk.pelvis_height_m), 3),
                "min_clearance_m": round(min(walk.clearance_m), 3)}
    blackout = (args.blackout_at, args.blackout_at + 30)
    dark = run_walk_vo(walk, args.frames, cfg, blackout=blackout, imu=args.imu)
    recovery = dark.recovery_frames(tolerance_m=0.05)
    wall = run_walk_vo(walk, args.frames, cfg, blackout=blackout, loss="textureless_wall",
                       imu=args.imu).recovery_frames(0.05)
    walk.close()
    turns = {}
    for name, (duration_s, angle_rad) in {"turn_90deg_in_1s": (1.0, math.pi / 2),
                                          "turn_180deg_in_0.4s": (0.4, math.pi)}.items():
        start_s = args.blackout_at / 30.0
        turning = make_walk(build_indoor_scene(IndoorSceneCfg(seed=args.seed)),
                            WalkCfg(speed_mps=args.speed, look_away=(start_s, duration_s, angle_rad)),
                            mode="kinematic", width=args.width, height=args.height)
        window = (args.blackout_at, args.blackout_at + int(round(duration_s * 30)))
        spun = run_walk_vo(turning, window[1] + 60, cfg, blackout=window, loss="motion", imu=args.imu)
        turning.close()
        turns[name] = {"peak_deg_per_s": round(math.degrees(math.pi * angle_rad / duration_s)),
                       "lost_frames": sum(s == TrackState.LOST for s in spun.states),
                       "recovery_frames": spun.recovery_frames(0.05), "max_error_cm": _max_over(spun.position_error_m(), 100.0),
                       "max_heading_error_deg": _max_over(spun.rotation_error_deg(), 1.0)}
    result = {
        "walk": args.walk, "speed_mps": args.speed, "gait": gait,
        "frames": args.frames, "resolution": [args.width, args.height], "path_m": round(score.path_length_m, 2),
        "ate_rmse_cm": _scaled(score.ate_rmse_m, 100, 3), "rpe_percent": _scaled(score.rpe_percent, 1, 3),
        "rpe_deg_per_m": _scaled(score.rpe_deg_per_m, 1, 4),
        "ate_unavailable": score.ate_unavailable, "rpe_unavailable": score.rpe_unavailable,
        "scored": f"tracked poses only ({len(run.times_s) - run.untracked_frames} of {len(run.times_s)})",
        "untracked_frames": run.untracked_frames, "blackout_untracked_frames": dark.untracked_frames,
        "torch_threads": torch.get_num_threads(),
        "vo_ms": {"median": round(float(np.median(run.vo_ms)), 2), "p90": round(float(np.percentile(run.vo_ms, 90)), 2)},
        "vo_fps": round(1e3 / float(np.median(run.vo_ms)), 1), "features": cfg.features, "pnp": cfg.pnp,
        "cuda_graphs": cfg.cuda_graphs and torch.device(cfg.device).type == "cuda",
        "device": _describe_device(cfg),
        "imu": args.imu, "blackout_frames": list(blackout), "recovery_frames": recovery,
        "blackout_max_error_cm": _max_over(dark.position_error_m()[slice(*blackout)], 100.0),
        "blackout_max_heading_error_deg": _max_over(dark.rotation_error_deg()[slice(*blackout)], 1.0),
        "recovery_s": None if recovery is None else round(recovery / 30.0, 3),
        "textureless_wall_recovery_frames": wall, "fast_turns_kinematic_walk": turns,
        "files": [str(args.out / "groundtruth.tum"), str(args.out / "estimate.tum")],
    }
    result["ratio"] = _scaled(score.ate_rmse_m, 1 / 0.02, 3)
    if gait is not None:
        print(f"policy walk: {gait['root_path_m']} m, {'FELL' if gait['fell'] else 'no fall'}, path error <= "
              f"{gait['max_cross_track_m']} m, pelvis >= {gait['min_pelvis_height_m']} m, clearance to walls, "
              f"furniture and boxes >= {gait['min_clearance_m']} m")
    print(f"VO ({args.walk} walk, {cfg.features} features, {cfg.pnp} RANSAC, {result['device']}) {args.frames} frames {args.width}x{args.height}, {score.path_length_m:.1f} m: "
          f"ATE {result['ate_rmse_cm']} cm, "
          f"RPE {result['rpe_percent']} % ({result['rpe_deg_per_m']} deg/m); {result['vo_fps']} fps (median "
          f"{result['vo_ms']['median']} ms)")
    print(f"1 s blackout at frame {blackout[0]}: tracking back {recovery} frames after the lens cleared (blind: "
          f"<= {result['blackout_max_error_cm']} cm, <= {result['blackout_max_heading_error_deg']} deg off); "
          f"1 s of a textureless wall: back {wall} frames after it")
    for name, turn in turns.items():
        print(f"{name} (peak {turn['peak_deg_per_s']} deg/s): {turn['lost_frames']} frames lost, back "
              f"{turn['recovery_frames']} frames after it, max error {turn['max_error_cm']} cm, "
              f"{turn['max_heading_error_deg']} deg")
    print(f"reproduce: evo_ape tum {args.out}/groundtruth.tum {args.out}/estimate.tum --align; "
          f"evo_rpe tum {args.out}/groundtruth.tum {args.out}/estimate.tum --align --delta 1 --delta_unit m --all_pairs")
    print("RESULT " + json.dumps(result))
    return result


def _scaled(value: float | None, scale: float, digits: int) -> float | None:
    """``value * scale`` rounded, or None for a score the run cannot give (too short or too still)."""
    return None if value is None else round(value * scale, digits)


def _max_over(values: np.ndarray, scale: float) -> float | None:
    """``max(values) * scale`` rounded, or None when the window holds no frame (a blackout past the run)."""
    return round(float(values.max()) * scale, 2) if len(values) else None


def _describe_device(cfg: VoCfg) -> str:
    device = torch.device(cfg.device)
    if device.type == "cuda":
        return f"{cfg.device} ({torch.cuda.get_device_name(device)})"
    return "cpu (OpenCV)" if cfg.features == "orb" else f"cpu ({torch.get_num_threads()} torch threads)"


if __name__ == "__main__":
    main()
