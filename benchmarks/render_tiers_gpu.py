"""Issue 26's GPU figures in one run: pbr frames/s from several Filament contexts at once, the path
tier at 64 spp + denoise, both beside MuJoCo's rasterizer (the ceiling, ratio 1).

    python benchmarks/render_tiers_gpu.py --width 640 --height 480 --path-spp 64 --pbr-processes 4

The scene and frame sequence are ``render_tiers.py``'s (the tutorial dataset's warehouse: objects
scattered, recoloured and relit every frame, ``frame_view``):

- pbr: ``--pbr-processes`` P processes (several counts are measured in turn; ``pbr`` is the
  fastest, all are listed), each with its own Filament engine (one synchronous view per render
  call and one image read-back per call, so several engines are what keeps the GPU busy: while
  one process reads back or randomizes, another draws). Each process builds the scene,
  renders ``--warmup`` frames (shader compilation), waits at a barrier, then renders frames
  1..``--frames`` of the same sequence: randomize (poses, colours, lights written into its model),
  kinematics, render, read back. Aggregate frames/s = P x frames / (last end - first start), the
  wall time of the slowest. The same with one process is printed beside it (``pbr_1_process``).
  ``render_ms_p50`` is the render call alone; ``frame_view_ms_p50`` the randomizer and kinematics,
  which the aggregate includes (a dataset run pays them too);
- raster: MuJoCo's rasterizer (EGL on a GPU machine) in this process, the same frames, timed per
  frame as ``render_tiers.py`` times it (randomizing untimed);
- path: ``render/path.py`` at ``--path-spp`` with OIDN (on CUDA when Mitsuba runs ``cuda_ad_rgb``
  and torch has CUDA), poses and materials updated every frame, each frame timed (randomizing
  untimed); the first ``--warmup`` frames (JIT compilation, OIDN start) are left out.

Targets (issue 26): on a GPU (an NVIDIA device node here, and not ``--device cpu``) pbr >= 300
frames/s and path >= 5 frames/s at 640x480, 64 spp; on the CPU (2 cores) pbr >= 8 and path >= 1 at
320x240, 16 spp. ``target.settings_match`` says whether this run used the target's size and spp
(a small smoke run is judged against the numbers anyway, but does not count). ``--device cpu``
pins the path tracer to Mitsuba's LLVM variant and picks the CPU targets; Filament takes whatever
Vulkan driver the loader finds. Ends with one line ``RESULT {json}``.
"""

from __future__ import annotations

import argparse
import glob
import json
import multiprocessing as mp
import os
import queue
import time

import numpy as np
from render_tiers import _path_tracer, frame_view

from ambulo import replicator as rep
from ambulo.replicator.producer import FrameProducer

TARGETS = {
    "gpu": {"pbr_fps": 300.0, "path_fps": 5.0, "width": 640, "height": 480, "path_spp": 64},
    "cpu": {"pbr_fps": 8.0, "path_fps": 1.0, "width": 320, "height": 240, "path_spp": 16},
}
BARRIER_TIMEOUT_S = 900.0
"""How long a pbr process waits for the others to finish building and warming up (lavapipe compiles
Filament's shaders in ~9 s a process on an idle CPU; a loaded 2-core machine takes minutes)."""


def _pbr_process(rank: int, width: int, height: int, frames: int, warmup: int, barrier, results) -> None:
    """One pbr process: its own scene and Filament engine; warm up, barrier, render the sequence."""
    try:
        from ambulo.render.pbr import PbrRenderer

        producer = FrameProducer(rep.example_config(width, height))
        camera = producer.camera
        pbr = PbrRenderer(camera._model_buf, width, height)
        for k in range(warmup):  # shader compilation, first uploads
            glcam = frame_view(producer, k, width, height)[2]
            pbr.render(camera._data_buf, glcam)
        barrier.wait(BARRIER_TIMEOUT_S)
        render_s, view_s = [], []
        start = time.perf_counter()  # CLOCK_MONOTONIC: comparable across processes of one machine
        for k in range(1, frames + 1):
            t0 = time.perf_counter()
            glcam = frame_view(producer, k, width, height)[2]
            t1 = time.perf_counter()
            pbr.render(camera._data_buf, glcam)  # drawn and read back into host memory when it returns
            t2 = time.perf_counter()
            view_s.append(t1 - t0)
            render_s.append(t2 - t1)
        end = time.perf_counter()
    except BaseException as err:  # the others stop waiting; the parent gets one line, not a hang
        barrier.abort()
        results.put((rank, f"{type(err).__name__}: {err}"))
        raise
    results.put((rank, {"start": start, "end": end, "render_s": render_s, "view_s": view_s}))
    pbr.close()
    producer.close()


def pbr_aggregate(processes: int, width: int, height: int, frames: int, warmup: int) -> dict:
    """pbr frames/s of ``processes`` processes rendering the sequence at once (see the module doc)."""
    ctx = mp.get_context("spawn")  # a fresh interpreter each: no Vulkan/EGL/CUDA state inherited
    barrier, results = ctx.Barrier(processes), ctx.Queue()
    procs = [ctx.Process(target=_pbr_process, args=(r, width, height, frames, warmup, barrier, results))
             for r in range(processes)]
    for p in procs:
        p.start()
    rows: dict = {}
    while len(rows) < processes:
        try:
            rank, row = results.get(timeout=5.0)
            rows[rank] = row
        except queue.Empty:  # a process killed outright (a crash inside Filament) puts nothing
            for r, p in enumerate(procs):
                if r not in rows and p.exitcode not in (None, 0):
                    barrier.abort()
                    rows[r] = f"exited with code {p.exitcode}"
    for p in procs:
        p.join(60)
    errors = {r: row for r, row in rows.items() if isinstance(row, str)}
    if errors:  # reported in the RESULT (the other tiers still measured): a GPU run is not repeated lightly
        print(f"pbr with {processes} processes failed: {errors}")
        return {"processes": processes, "error": str(errors)}
    wall_s = max(r["end"] for r in rows.values()) - min(r["start"] for r in rows.values())
    render = np.concatenate([r["render_s"] for r in rows.values()])
    view = np.concatenate([r["view_s"] for r in rows.values()])
    return {"processes": processes, "frames": processes * frames, "wall_s": round(wall_s, 3),
            "fps": round(processes * frames / wall_s, 2),
            "render_ms_p50": round(1e3 * float(np.median(render)), 2),
            "render_ms_p90": round(1e3 * float(np.percentile(render, 90)), 2),
            "frame_view_ms_p50": round(1e3 * float(np.median(view)), 2),
            "slowest_process_s": round(max(r["end"] - r["start"] for r in rows.values()), 3)}


def raster_and_path(width: int, height: int, frames: int, path_frames: int, path_spp: int, warmup: int,
                    variant: str) -> tuple[dict, dict | None]:
    """Raster over ``frames`` frames and the path tier over ``path_frames``, this process, per frame."""
    producer = FrameProducer(rep.example_config(width, height))
    camera = producer.camera
    model, data, raster = camera._model_buf, camera._data_buf, camera.renderer
    path_error = None
    try:
        tracer = _path_tracer(model, width, height, spp=path_spp, variant=variant)
    except RuntimeError as err:  # NoPathTracerError: no CUDA/LLVM for Mitsuba, no OIDN
        tracer, path_error = None, f"{type(err).__name__}: {err}"
    raster_s, path_s = [], []
    # warm up on frames 0.. like each pbr process, then time frames 1..n of the same sequence
    for i, k in enumerate([*range(warmup), *range(1, max(frames, path_frames) + 1)]):
        pos, rot_gl, _ = frame_view(producer, k, width, height)  # untimed
        timed = i >= warmup
        if i < frames + warmup:
            t0 = time.perf_counter()
            raster.update(model, data, camera.cam_id, pos, rot_gl, camera.cfg.clipping_range_m)
            raster.render_rgb()
            if timed:
                raster_s.append(time.perf_counter() - t0)
        if tracer is not None and i < path_frames + warmup:
            t0 = time.perf_counter()
            try:
                tracer.render(data, camera.cam_id, pose=(pos, rot_gl))  # uint8 on the host: denoised, encoded
            except RuntimeError as err:  # e.g. OIDN's CUDA device: reported, raster still measured
                tracer, path_error = None, f"{type(err).__name__}: {err}"
                continue
            if timed:
                path_s.append(time.perf_counter() - t0)
    raster_row = _per_frame(raster_s)
    path_row = None if path_error is None else {"error": path_error}
    if tracer is not None:
        from ambulo.render.path import _torch_has_cuda

        path_row = {**_per_frame(path_s), "spp": path_spp, "denoise": True, "variant": tracer.variant,
                    "denoiser_on": "cuda" if tracer.variant.startswith("cuda") and _torch_has_cuda() else "cpu"}
    producer.close()
    return raster_row, path_row


def _vulkan_drivers() -> list[str]:
    """The Vulkan drivers Filament can pick (the variables naming them, else the ICD manifests
    installed): on a GPU machine an NVIDIA one must be among them, or pbr ran on lavapipe (CPU)."""
    from ambulo.render.pbr import _ICD_DIRS

    named = os.environ.get("VK_DRIVER_FILES") or os.environ.get("VK_ICD_FILENAMES")
    if named:
        return named.split(os.pathsep)
    return sorted(os.path.basename(f) for d in _ICD_DIRS for f in glob.glob(os.path.join(d, "*.json")))


def _per_frame(seconds: list[float]) -> dict:
    s = np.asarray(seconds)
    return {"frames": len(s), "fps": round(1.0 / float(np.median(s)), 2),
            "wall_ms_p50": round(1e3 * float(np.median(s)), 2), "wall_ms_p90": round(1e3 * float(np.percentile(s, 90)), 2)}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--width", type=int, default=640)
    parser.add_argument("--height", type=int, default=480)
    parser.add_argument("--frames", type=int, default=200, help="pbr frames per process, and raster frames")
    parser.add_argument("--pbr-processes", type=int, nargs="+", default=[4],
                        help="process counts to measure in turn (e.g. 4 8); 'pbr' is the fastest, all are listed")
    parser.add_argument("--path-frames", type=int, default=20)
    parser.add_argument("--path-spp", type=int, default=64)
    parser.add_argument("--warmup", type=int, default=3, help="untimed first frames of each tier and process")
    parser.add_argument("--device", choices=("auto", "cpu"), default="auto",
                        help="cpu: Mitsuba's LLVM variant and the CPU targets")
    args = parser.parse_args()
    w, h = args.width, args.height
    gpu = args.device == "auto" and bool(glob.glob("/dev/nvidia[0-9]*"))
    target = TARGETS["gpu" if gpu else "cpu"]

    # pbr first, with nothing else of this run alive; the single process, then P at once
    pbr_1 = pbr_aggregate(1, w, h, args.frames, args.warmup)
    pbr_by_processes = {1: pbr_1} | {p: pbr_aggregate(p, w, h, args.frames, args.warmup)
                                     for p in args.pbr_processes if p > 1}
    pbr_p = max(pbr_by_processes.values(), key=lambda row: row.get("fps", 0.0))
    raster, path = raster_and_path(w, h, args.frames, args.path_frames, args.path_spp, args.warmup,
                                   "auto" if args.device == "auto" else "llvm_ad_rgb")
    for row in (*pbr_by_processes.values(), path):
        if row is not None and "fps" in row:
            row["ratio_to_raster"] = round(row["fps"] / raster["fps"], 4)
    raster["ratio_to_raster"] = 1.0

    result = {"width": w, "height": h, "cpus": os.cpu_count(), "load_avg_1min": round(os.getloadavg()[0], 2),
              "gpu": gpu, "vulkan_drivers": _vulkan_drivers(),
              "tiers": {"raster": raster, "pbr": pbr_p, "pbr_1_process": pbr_1, "path": path},
              "pbr_by_processes": pbr_by_processes,
              "target": {**target, "settings_match": (w, h, args.path_spp) == (target["width"], target["height"],
                                                                                 target["path_spp"])},
              "meets_pbr": pbr_p.get("fps", 0.0) >= target["pbr_fps"],
              "meets_path": path is not None and path.get("fps", 0.0) >= target["path_fps"]}
    print(f"{'tier':<16} {'fps':>9} {'ratio':>8}  detail")
    shown = {**result["tiers"], **{f"pbr_{p}_processes": row for p, row in pbr_by_processes.items() if p > 1}}
    for name, row in shown.items():
        if row is None or "fps" not in row:
            print(f"{name:<16} {'-':>9} {'-':>8}  {'not importable here' if row is None else row['error']}")
            continue
        detail = {k: v for k, v in row.items() if k not in ("fps", "ratio_to_raster")}
        print(f"{name:<16} {row['fps']:>9} {row['ratio_to_raster']:>8}  {detail}")
    print(f"targets ({'GPU' if gpu else 'CPU'}): pbr >= {target['pbr_fps']} -> {result['meets_pbr']}, "
          f"path >= {target['path_fps']} -> {result['meets_path']} (settings match: {result['target']['settings_match']})")
    print("RESULT " + json.dumps(result))


if __name__ == "__main__":
    main()
