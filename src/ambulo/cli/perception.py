"""``ambulo map <scene>``: walk the humanoid through a seeded scene, track its head camera with
visual odometry, fuse a TSDF map, and write the trajectory (TUM), the mesh (PLY), the occupancy
slice and the Nav2 costmap (PNG) for a person to look at."""

from __future__ import annotations

import argparse
from pathlib import Path

from .errors import CliError, check_output_file


def add_commands(subparsers) -> None:
    p = subparsers.add_parser("map", help="map a scene from the humanoid's head camera (VO + TSDF + costmap)",
                              description=__doc__.split("\n\n")[0].replace("\n", " "))
    p.add_argument("scene", help="scene name: indoor (a seeded room with furniture and moving boxes)")
    p.add_argument("--out", default="out/map", help="output folder (default out/map)")
    p.add_argument("--frames", type=int, default=600, help="frames to walk at 30 Hz (default 600 = 20 s)")
    p.add_argument("--width", type=int, default=640, help="camera width, px (default 640)")
    p.add_argument("--height", type=int, default=480, help="camera height, px (default 480)")
    p.add_argument("--seed", type=int, default=0, help="scene seed (default 0)")
    p.add_argument("--voxel", type=float, default=0.05, help="TSDF voxel size, m (default 0.05)")
    p.add_argument("--true-poses", action="store_true", help="fuse at the simulator's poses instead of VO's")
    p.add_argument("--walk", choices=("kinematic", "policy"), default="kinematic",
                   help="how the humanoid moves: kinematic (a scripted walk, default) or policy (it walks "
                        "under the shipped walking policy, simulated at 5 ms steps)")
    p.add_argument("--no-gyro", action="store_true", help="visual odometry from the images alone (by default it "
                   "also reads the head's gyro)")
    p.add_argument("--device", default="cpu", help="torch device of the map (cpu, cuda)")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    from ambulo.scenes.indoor import scene_names

    if args.scene not in scene_names():
        raise CliError(f"no scene named {args.scene!r}", f"choose one of: {', '.join(scene_names())}")
    for flag, value in (("--frames", args.frames), ("--width", args.width), ("--height", args.height)):
        if value < 2:
            raise CliError(f"{flag} {value} is too small", f"give {flag} of at least 2 (e.g. the default)")
    if not 0.005 <= args.voxel <= 1.0:
        raise CliError(f"--voxel {args.voxel} m is outside 0.005..1 m", "give e.g. --voxel 0.05")
    check_output_file(Path(args.out) / "summary.json", "--out")
    from tqdm import tqdm

    from ambulo.perception.pipeline import MapRunCfg, run_mapping
    from ambulo.perception.tsdf import TsdfCfg
    from ambulo.scenes.indoor import IndoorSceneCfg

    cfg = MapRunCfg(scene=IndoorSceneCfg(seed=args.seed), tsdf=TsdfCfg(voxel_size_m=args.voxel),
                    num_frames=args.frames, width=args.width, height=args.height,
                    use_true_poses=args.true_poses, device=args.device, walk_mode=args.walk, vo_gyro=not args.no_gyro)
    with tqdm(total=args.frames, desc="ambulo map", unit="frame", disable=None) as bar:
        summary = run_mapping(cfg, args.out, progress=lambda i: bar.update(1))
    t = summary["trajectory"]
    ate = "n/a" if t["ate_rmse_m"] is None else f"{t['ate_rmse_m'] * 100:.2f} cm"
    rpe = "n/a" if t["rpe_percent"] is None else f"{t['rpe_percent']:.2f} %"
    print(f"trajectory: ATE {ate}, RPE {rpe} over {t['path_length_m']:.1f} m ({summary['poses']} poses, "
          f"{args.walk} walk); map {summary['blocks']} blocks, mesh {summary['mesh']['vertices']} vertices")
    for name, key in (("ATE", "ate_unavailable"), ("RPE", "rpe_unavailable")):
        if t[key]:
            print(f"  {name} not available: {t[key]}")
    if not summary["vo_started"]:
        fix = ("the map used the true poses; for a VO score give larger --width/--height" if args.true_poses else
               "the map was fused at the start pose; give larger --width/--height (e.g. the default 640x480) "
               "or --true-poses")
        print(f"  visual odometry never started (too few features with depth in {args.width}x{args.height} images): "
              f"{fix}")
    print(f"wrote {args.out}/: estimate.tum groundtruth.tum mesh.ply occupancy.png costmap.png steppable.png "
          "costmap.npz summary.json")
    return 0
