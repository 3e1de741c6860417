"""Path-traced frames/s of the warehouse on this CPU, beside the rasterizer in the same run (issue 26).

    python benchmarks/render_path.py [--frames 5] [--size 320x240] [--spp 16] [--image docs/images/warehouse_path.png]
                                     [--image-size 640x480] [--image-spp 64]

The warehouse of ``ambulo generate`` (``scenes.warehouse``) with its ten objects set out on the
floor, seen from one overview camera (``VIEW``). Every frame the objects turn a little, so each
path-traced frame pays the per-frame pose update (vertex positions through ``mi.traverse``, an
acceleration-structure refit), not a static scene. Measured, alternating, best of the frames:

- raster: ``OffscreenRenderer.render_rgb`` of the same view (lit pass only);
- path: ``PathTracer.render`` at ``--spp`` with denoising (update, path tracing, 4-spp albedo/normal
  guides, Open Image Denoise, sRGB);
- ceiling: Mitsuba's ``mi.render`` of the same scene at ``--spp`` alone (no update, guides or
  denoise): the fastest this tier can be with this integrator.

Each row gives wall frames/s and CPU seconds per frame (all threads; other load barely moves it):
``cores / cpu_s`` is the rate the cores would give if nothing else ran. Ends with one line
``RESULT {json}``: "ratio" is path / ceiling; the target is path >= 1 frame/s on 2 cores at 320x240
(``meets_target``: ``2 / cpu_s`` of the path row, as the machine is shared). The first frame (Mitsuba's
kernel compilation, ~2-5 s) is left out and reported as ``first_frame_s``.
"""

from __future__ import annotations

import argparse
import json
import os
import time
from pathlib import Path

import mujoco
import numpy as np

from ambulo.render import OffscreenRenderer
from ambulo.render.path import PathTracer, PathTracerCfg
from ambulo.scenes.warehouse import OBJECTS, build_warehouse_scene

VIEW = {"pos": [-5.0, -4.0, 2.6], "xyaxes": [0.6, -0.8, 0.0, 0.3, 0.22, 0.93], "fovy": 70.0}
"""The overview camera: from the (-x, -y) corner, 2.6 m up, over the humanoid towards the racks."""


def warehouse() -> tuple[mujoco.MjModel, mujoco.MjData]:
    spec = build_warehouse_scene()
    spec.worldbody.add_camera(name="overview", **VIEW)
    model = spec.compile()
    data = mujoco.MjData(model)
    for i, (label, kind, size) in enumerate(OBJECTS):
        body = model.body(f"/World/objects/{label}_{i}")
        adr = model.jnt_qposadr[body.jntadr[0]]
        # resting on the floor: the half height of each shape (box/ellipsoid z, cylinder half-length, radius)
        half_height_m = size[1] if kind == "cylinder" else size[-1]
        data.qpos[adr:adr + 3] = [-2.5 + 0.9 * (i % 5), -2.2 + 1.1 * (i // 5), half_height_m]
    mujoco.mj_forward(model, data)
    return model, data


def turn_objects(model: mujoco.MjModel, data: mujoco.MjData, angle_rad: float) -> None:
    """Yaw every object by ``angle_rad`` about z (a moved pose for the next frame)."""
    for i in range(len(OBJECTS)):
        body = model.body(f"/World/objects/{OBJECTS[i][0]}_{i}")
        adr = model.jnt_qposadr[body.jntadr[0]] + 3
        half = 0.5 * angle_rad * (i + 1)
        data.qpos[adr:adr + 4] = [np.cos(half), 0.0, 0.0, np.sin(half)]
    mujoco.mj_forward(model, data)


def _timed(fn) -> tuple[float, float]:
    wall, cpu = time.perf_counter(), time.process_time()
    fn()
    return time.perf_counter() - wall, time.process_time() - cpu


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--frames", type=int, default=5)
    parser.add_argument("--size", default="320x240")
    parser.add_argument("--spp", type=int, default=16)
    parser.add_argument("--image", default="docs/images/warehouse_path.png", help="'' to skip the picture")
    parser.add_argument("--image-size", default="640x480")
    parser.add_argument("--image-spp", type=int, default=64)
    args = parser.parse_args()
    width, height = (int(v) for v in args.size.split("x"))
    model, data = warehouse()
    cam = model.camera("overview").id

    raster = OffscreenRenderer(model, width, height)

    def raster_frame():
        raster.update(model, data, cam, data.cam_xpos[cam], data.cam_xmat[cam].reshape(3, 3))
        raster.render_rgb()

    t0 = time.perf_counter()
    tracer = PathTracer(model, PathTracerCfg(width=width, height=height, spp=args.spp))
    build_s = time.perf_counter() - t0
    first_s, _ = _timed(lambda: tracer.render(data, "overview"))
    mi = tracer.mi

    rows = {"raster": [], "path": [], "ceiling": []}
    for frame in range(args.frames):
        turn_objects(model, data, 0.05 * (frame + 1))
        rows["raster"].append(_timed(raster_frame))
        rows["path"].append(_timed(lambda: tracer.render(data, "overview")))
        rows["ceiling"].append(_timed(lambda: np.asarray(mi.render(tracer._scene, spp=args.spp, seed=frame))))
    cores = len(os.sched_getaffinity(0))
    summary = {}
    for name, times in rows.items():
        wall = min(t for t, _ in times)
        cpu = min(c for _, c in times)
        summary[name] = {"fps": round(1.0 / wall, 3), "cpu_s_per_frame": round(cpu, 4),
                         "fps_if_idle": round(cores / cpu, 3)}
        print(f"{name:8s} {1.0 / wall:8.2f} frames/s wall  {cpu:7.3f} CPU-s/frame  "
              f"{cores / cpu:8.2f} frames/s on {cores} idle cores")

    if args.image:
        image_w, image_h = (int(v) for v in args.image_size.split("x"))
        big = PathTracer(model, PathTracerCfg(width=image_w, height=image_h, spp=args.image_spp,
                                              denoise_quality="high"))
        from PIL import Image

        Path(args.image).parent.mkdir(parents=True, exist_ok=True)
        Image.fromarray(big.render(data, "overview")).save(args.image)
        print(f"wrote {args.image} ({image_w}x{image_h}, {args.image_spp} spp, denoised)")

    result = {
        "benchmark": "render_path", "scene": "warehouse", "size": args.size, "spp": args.spp,
        "variant": tracer.variant, "denoiser": "pyoidn (Open Image Denoise, quality=fast, albedo+normal guides)",
        "cores": cores, "load_avg_1min": round(os.getloadavg()[0], 2), "build_s": round(build_s, 2),
        "first_frame_s": round(first_s, 2), **summary,
        "ratio": round(summary["path"]["fps"] / summary["ceiling"]["fps"], 3),
        "path_vs_raster_fps": round(summary["path"]["fps"] / summary["raster"]["fps"], 5),
        "path_fps_on_2_cores": round(2.0 / summary["path"]["cpu_s_per_frame"], 3),
        "meets_target": 2.0 / summary["path"]["cpu_s_per_frame"] >= 1.0,
    }
    print("RESULT " + json.dumps(result))


if __name__ == "__main__":
    main()
