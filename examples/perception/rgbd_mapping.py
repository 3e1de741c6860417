"""Perception on any RGB-D stream: the humanoid's head camera walks the seeded indoor scene,
visual odometry tracks it, a 5 cm TSDF fuses its depth at the tracked poses, and the map turns
into a mesh, an occupancy slice and a Nav2 costmap for the humanoid's footprint.

    python examples/perception/rgbd_mapping.py [--frames 120] [--out out/rgbd_mapping]

Each step is one call, and each takes plain tensors, so a recorded stream works the same:
``RgbdOdometry.track(rgb, depth)`` -> pose; ``TsdfMap.integrate(RgbdFrame(depth, rgb, K, pose))``;
``occupancy_slice`` / ``inflate`` / ``extract_mesh`` on ``tsdf.dense()``.
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np
import torch

from ambulo.perception import InflationCfg, RgbdFrame, RgbdOdometry, TsdfCfg, TsdfMap, inflate, occupancy_slice
from ambulo.perception.images import costmap_rgb, draw_path, write_png
from ambulo.perception.mesh import extract_mesh, write_ply
from ambulo.perception.sources import HeadCameraWalk
from ambulo.scenes.indoor import IndoorSceneCfg, build_indoor_scene


def main(argv: list[str] | None = None) -> dict:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--frames", type=int, default=120)
    parser.add_argument("--width", type=int, default=320)
    parser.add_argument("--height", type=int, default=240)
    parser.add_argument("--out", default="out/rgbd_mapping")
    args = parser.parse_args(argv)
    out = Path(args.out)

    walk = HeadCameraWalk(build_indoor_scene(IndoorSceneCfg(seed=0)), width=args.width, height=args.height)
    tsdf = TsdfMap(TsdfCfg(voxel_size_m=0.05), device="cuda" if torch.cuda.is_available() else "cpu")
    vo, errors, path = None, [], []
    for i in range(args.frames):
        frame = walk.frame(i)  # rgb (H, W, 3) uint8, depth (H, W) m, K, true pose
        if vo is None:
            vo = RgbdOdometry(frame.intrinsics.numpy(), initial_pose_wc=frame.pose_wc.numpy())
        pose_wc = vo.track(frame.rgb.numpy(), frame.depth_m.numpy()).pose_wc
        tsdf.integrate(RgbdFrame(frame.depth_m, frame.rgb, frame.intrinsics, torch.from_numpy(pose_wc)))
        errors.append(float(np.linalg.norm(pose_wc[:3, 3] - frame.pose_wc.numpy()[:3, 3])))
        path.append(pose_wc[:2, 3])
    walk.close()

    grid = tsdf.dense()
    mesh = extract_mesh(grid)
    write_ply(out / "mesh.ply", mesh)
    occupancy = occupancy_slice(grid, z_min_m=0.1, z_max_m=1.6)  # the humanoid's height band
    costmap = inflate(occupancy, InflationCfg())  # Nav2's defaults, humanoid inscribed radius
    write_png(out / "costmap.png", draw_path(costmap_rgb(costmap), costmap, np.array(path)))
    print(f"{args.frames} frames: VO position error max {max(errors) * 100:.1f} cm; map {tsdf.num_blocks} blocks, "
          f"mesh {len(mesh.vertices)} vertices; wrote {out}/mesh.ply and {out}/costmap.png")
    return {"max_position_error_m": max(errors), "blocks": tsdf.num_blocks, "vertices": len(mesh.vertices),
            "costmap": costmap, "out": out}


if __name__ == "__main__":
    main()
