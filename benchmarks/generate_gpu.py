"""Synthetic data on the GPU: annotated frames/s to disk and in memory, against the raw render.

Three timings of the same dataset (``replicator.example_config``, the warehouse tutorial, at
``--size``) in one process, with ``--worlds`` frames per launch:

- **raw** (the ceiling): ``TiledCamera.render`` alone (BVH refit, ray cast, unpack) of an
  already randomized batch, bracketed by device syncs: the renderer's own speed;
- **memory**: ``BatchedFrameProducer.batches``, what a training loop gets: every frame
  randomized (the CPU path's draws, on the host), rendered, instance ids, tight boxes and
  pixel counts on the device; nothing copied to the host;
- **disk**: ``generate(device=...)``, the whole ``ambulo generate --device``: the above plus one
  host copy per batch, loose and 3D boxes, COCO RLE masks, PNG encoding on ``--writer-threads``,
  atomic files and the COCO merge, into a fresh folder.

    python benchmarks/generate_gpu.py --device cuda --size 640x480 --worlds 256 --frames 2048
    python benchmarks/generate_gpu.py --device cpu --size 64x48 --worlds 4 --frames 8   # Warp's CPU device

Ends with one ``RESULT {json}`` line: frames/s of each, and ``memory_of_raw`` / ``disk_of_raw``.
Issue 25's targets on one H100: >= 2,000 frames/s to disk and >= 50,000 in memory at 640x480.
"""

from __future__ import annotations

import argparse
import datetime
import json
import os
import shutil
import tempfile
import time
from pathlib import Path

import torch

from ambulo import replicator as rep
from ambulo.replicator.batched import BatchedFrameProducer
from ambulo.replicator.generate import generate


def sync(device: str) -> None:
    if device.startswith("cuda"):
        torch.cuda.synchronize(device)


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("--device", default="cuda")
    p.add_argument("--size", default="640x480")
    p.add_argument("--worlds", type=int, default=256)
    p.add_argument("--frames", type=int, default=2048)
    p.add_argument("--writer-threads", type=int, default=None)
    p.add_argument("--out", default=None, help="dataset folder for the disk run (default: a temporary one)")
    args = p.parse_args()
    width, height = (int(v) for v in args.size.split("x"))
    config = rep.example_config(width, height)

    t0 = time.perf_counter()
    producer = BatchedFrameProducer(config, num_worlds=args.worlds, device=args.device)
    frames = list(range(args.frames))
    next(producer.batches(0, frames[:args.worlds]))  # compiles the kernels and warms the caches
    sync(args.device)
    setup_s = time.perf_counter() - t0

    # raw: the render alone, of the batch just randomized, repeated
    repeats = max(3, args.frames // args.worlds)
    producer.camera.render()
    sync(args.device)
    start = time.perf_counter()
    for _ in range(repeats):
        producer.camera.render()
    sync(args.device)
    raw_fps = repeats * args.worlds / (time.perf_counter() - start)

    # memory: the whole in-memory path
    start = time.perf_counter()
    count = 0
    for batch in producer.batches(1, frames):
        count += len(batch["index"])
    sync(args.device)
    memory_fps = count / (time.perf_counter() - start)
    del producer

    # disk: the whole `ambulo generate --device`, in a fresh folder
    out = Path(args.out) if args.out else Path(tempfile.mkdtemp(prefix="ambulo-gen-gpu-"))
    try:
        start = time.perf_counter()
        generate(config, out, args.frames, seed=2, device=args.device, num_worlds=args.worlds,
                 writer_threads=args.writer_threads, show_progress=False, overwrite=out.exists())
        disk_fps = args.frames / (time.perf_counter() - start)
        size_mb = sum(f.stat().st_size for f in out.rglob("*") if f.is_file()) / 1e6
    finally:
        if not args.out:
            shutil.rmtree(out, ignore_errors=True)

    result = {
        "benchmark": "generate_gpu", "date": datetime.date.today().isoformat(), "device": args.device,
        "gpu": torch.cuda.get_device_name(args.device) if args.device.startswith("cuda") else None,
        "cpus": os.cpu_count(), "size": [width, height], "worlds": args.worlds, "frames": args.frames,
        "writer_threads": args.writer_threads or os.cpu_count(), "setup_s": round(setup_s, 1),
        "raw_render_fps": round(raw_fps, 1), "memory_fps": round(memory_fps, 1), "disk_fps": round(disk_fps, 1),
        "memory_of_raw": round(memory_fps / raw_fps, 3), "disk_of_raw": round(disk_fps / raw_fps, 3),
        "dataset_mb": round(size_mb, 1), "targets": {"disk_fps": 2000, "memory_fps": 50000, "size": [640, 480]},
    }
    print("RESULT " + json.dumps(result))


if __name__ == "__main__":
    main()
