"""Synthetic data on the GPU: annotated frames/s to disk and in memory, against the raw render.

The tutorial dataset (``replicator.example_config``, the warehouse bay) at ``--size``, with
``--num-worlds`` frames per launch, timed in one process after a warm-up:

- **warm-up** (reported, never timed into a rate): building the producer, then one batch, which
  compiles MuJoCo Warp's kinematics and render kernels (minutes with a cold cache, seconds from
  Warp's kernel cache), captures the render graph and warms every other path, while the
  ``--draw-workers`` processes start; progress lines are printed while it runs;
- **profile**: one batch stage by stage, each bracketed by device syncs, in ms a frame: the
  randomizers' draws and applies (on the host, ``HostWorlds``), reset and upload, kinematics,
  render, labels (instance ids, tight boxes, pixel counts), the copy to the host, the per-frame
  capture (loose and 3D boxes), and encoding and writing a frame's files on one thread;
- **raw** (the ceiling): ``TiledCamera.render`` alone (BVH refit, ray cast, unpack) of the batch
  just randomized, repeated: the renderer's own speed;
- **memory** (the in-memory mode): ``BatchedFrameProducer.batches(device_draws=True)``, what a
  training loop gets: every world randomized on the device (``device_draws``), rendered, instance
  ids, tight boxes and pixel counts on the device; nothing copied to the host, no host sync;
- **memory, host draws**: ``batches`` with the CPU path's draws (on ``--draw-workers`` processes,
  a batch ahead), the dataset's scenes: what the disk modes render;
- **disk** (``ambulo generate --device --draw-workers N [--image-format jpg]``):
  ``batched_disk.run_batched_frames`` with this producer's draw processes writing the files from
  shared memory and the records committed after a flush of the files, then the COCO merge and its
  file, as ``generate`` ends, ``--disk-frames`` frames into a fresh folder each, after one untimed
  batch (the run's shared blocks made and page-locked: once per dataset in ``generate``) (``DISK_RUNS``):
  the **headline** is the default annotation set (RGB, as JPEG encoded on the GPU where
  torchvision's nvjpeg runs, and the COCO records: boxes and RLE masks) flushed to ``--out``'s
  disk; then with the depth PNGs, with depth and the id PNGs, with PNG RGB, and two that locate the
  cost (no flushes; into ``/dev/shm``); the JPEG runs encode ``--cpu-jpeg-share`` of the frames on
  the draw processes' cores (``replicator.cpu_jpeg``; 0: nvjpeg alone). Each run prints its stages' ms a frame
  (``batched_disk.STAGES``: the main thread's, the commit thread's, and the processes' CPU);
- **disk ceiling**: the headline's file count and bytes written and flushed with nothing else
  (no render, no encode): the storage's own rate, the ceiling of every disk run;
- **CPU JPEG encoders**: ms to encode one rendered frame at the dataset's quality on one core, with
  Pillow (libjpeg-turbo, 4:4:4: what the CPU share uses) and torchvision's CPU ``encode_jpeg``
  (4:2:0) where it imports;
- **disk, threads** (``--threads-run``, the first disk mode, for comparison): ``run_frames`` with
  ``--writer-threads`` encoders in this process;
- **disk, processes** (``--processes``, default 0: skipped): that many producers on the same
  device (``ProducerPool``, what ``--num-gpus`` runs), each with cores / processes encoders.

    python benchmarks/generate_gpu.py --device cuda --size 640x480 --num-worlds 256 --frames 2048
    python benchmarks/generate_gpu.py --device cpu --size 64x48 --num-worlds 4 --frames 8 --disk-frames 12

``--device cpu`` is Warp's CPU device: a smoke test of the same code, not a measurement.
Ends with one ``RESULT {json}`` line: frames/s of each and its ratio to the raw render (and of the
disk runs to the disk ceiling), and the device's ms a frame of the in-memory mode's stages (device
draws, kinematics, render, labels): the render is the ceiling of every mode.
Issue 25's targets on one H100: >= 2,000 annotated 640x480 frames/s to disk, >= 50,000 in memory.
"""

from __future__ import annotations

import argparse
import collections
import concurrent.futures as cf
import contextlib
import dataclasses
import datetime
import functools
import gc
import json
import os
import shutil
import sys
import tempfile
import threading
import time
from pathlib import Path

import torch

from ambulo import replicator as rep
from ambulo.replicator.batched import BatchedFrameProducer
from ambulo.replicator.batched_disk import STAGES, run_batched_frames
from ambulo.replicator.coco_file import write_annotations
from ambulo.replicator.cpu_jpeg import DEFAULT_CPU_JPEG_SHARE, encode_jpeg_cpu, share_fraction
from ambulo.replicator.draw_pool import DrawPool
from ambulo.replicator.encode import JPEG_QUALITY, jpeg_available
from ambulo.replicator.processes import ProducerPool, usable_cpus
from ambulo.replicator.producer import run_frames
from ambulo.replicator.writers import FrameWriter, prepare_dirs, write_frame_files
from ambulo.sensors.annotators import instance_table
from ambulo.utils.atomic import atomic_write_bytes, can_sync_filesystem, sync_filesystem

ENCODE_SAMPLE = 32
"""Frames of the profiled batch encoded and written on one thread."""


def sync(device: str) -> None:
    if device.startswith("cuda"):
        torch.cuda.synchronize(device)


def say(message: str) -> None:
    print(f"[{time.strftime('%H:%M:%S')}] {message}", file=sys.stderr, flush=True)


@contextlib.contextmanager
def timed_randomizers(randomizers, totals: dict):
    """Add each randomizer's ``sample`` and ``apply`` seconds to ``totals`` while inside."""
    for r in randomizers:
        for method in ("sample", "apply"):
            bound = getattr(r, method)

            def wrapper(*args, _bound=bound, _key=method):
                start = time.perf_counter()
                try:
                    return _bound(*args)
                finally:
                    totals[_key] += time.perf_counter() - start

            setattr(r, method, wrapper)
    try:
        yield
    finally:
        for r in randomizers:
            for method in ("sample", "apply"):
                delattr(r, method)  # back to the class's methods


def profile_batch(producer: BatchedFrameProducer, device: str, seed: int, chunk: list[int], out: Path) -> dict:
    """One batch stage by stage, synced around each: ms a frame of every stage."""
    stages: dict[str, float] = {}

    def stage(name, fn):
        sync(device)
        start = time.perf_counter()
        result = fn()
        sync(device)
        stages[name] = time.perf_counter() - start
        return result

    totals: collections.Counter = collections.Counter()
    with timed_randomizers(producer.config.randomizers, totals):
        logs = stage("randomize", lambda: producer.randomize(seed, chunk))
    stages["draws"], stages["apply"] = totals["sample"], totals["apply"]
    stages["reset_upload"] = stages.pop("randomize") - stages["draws"] - stages["apply"]
    stage("kinematics", producer.kinematics)
    stage("render", producer.camera.render)
    labels = stage("labels", lambda: producer.labels(len(chunk)))
    host = stage("copy_to_host", lambda: producer.to_host(len(chunk), *labels))
    k_matrix = producer.camera.get_intrinsics_matrix()
    captures = stage("captures", lambda: [producer.capture(w, host, k_matrix) for w in range(len(chunk))])
    cfg = producer.config.writer
    prepare_dirs(out, cfg)
    fsync_files = FrameWriter(out, cfg).fsync_files
    # a sample of the batch (PNG encoding is the slowest stage on one thread)
    sample = min(len(chunk), ENCODE_SAMPLE)
    stage("encode_write_1_thread", lambda: [write_frame_files(out, i, c, producer.table, log, cfg, fsync_files)
                                            for i, c, log in list(zip(chunk, captures, logs))[:sample]])
    ms = {name: round(1e3 * s / len(chunk), 3) for name, s in stages.items()}
    ms["encode_write_1_thread"] = round(1e3 * stages["encode_write_1_thread"] / sample, 3)
    device_stages = ("kinematics", "render", "labels")
    ms["host_total"] = round(sum(v for k, v in ms.items() if k not in device_stages), 3)
    ms["device_total"] = round(sum(ms[k] for k in device_stages), 3)
    return ms


def profile_device_draws(producer: BatchedFrameProducer, device: str, chunk: list[int]) -> dict:
    """The in-memory mode's batch stage by stage, synced around each: device ms a frame."""
    index = torch.as_tensor(chunk, dtype=torch.int64, device=producer.engine.device)
    stages = {}
    for name, fn in (("device_draws", lambda: producer.randomize_on_device(1, index)),
                     ("kinematics", producer.kinematics), ("render", producer.camera.render),
                     ("labels", lambda: producer.labels(len(chunk)))):
        sync(device)
        start = time.perf_counter()
        fn()
        sync(device)
        stages[name] = round(1e3 * (time.perf_counter() - start) / len(chunk), 4)
    stages["total"] = round(sum(stages.values()), 4)
    stages["render_fraction"] = round(stages["render"] / stages["total"], 3)
    return stages


def jpeg_check(producer: BatchedFrameProducer, out: Path, seed: int, frames: list[int], sample: int = 64,
               share=None) -> dict:
    """How far a sample of a run's JPEG files, decoded, is from the same frames rendered again in
    memory (the dataset's draws): mean absolute difference per frame, 0-255. A q95 JPEG of the frame
    is about one level off; one encoded from an unfinished or overwritten image (a stream-ordering
    fault in the JPEG thread, ``jpeg_stage``) tens, or it does not decode. ``chroma``: the files'
    chroma samplings (Pillow's ``get_sampling``: 0 is 4:4:4, 2 is 4:2:0), nvjpeg's and the CPU
    share's alike (``cpu_jpeg``), and the ms a frame off nvjpeg's and off the CPU's."""
    import numpy as np
    from PIL import Image, JpegImagePlugin

    from ambulo.replicator.cpu_jpeg import on_cpu

    # a seeded random sample: an even stride could miss every frame of the CPU's share (1/3: i % 3 == 2)
    picked = sorted(np.random.default_rng(0).choice(frames, min(sample, len(frames)), replace=False).tolist())
    diffs, broken, chroma, by_encoder = [], 0, set(), {"gpu": [], "cpu": []}
    for batch in producer.batches(seed, picked):
        rgb = batch["rgb"].cpu().numpy().astype(np.float64)
        for row, index in enumerate(batch["index"].tolist()):
            try:
                image = Image.open(out / "rgb" / f"{index:06d}.jpg")
                chroma.add(JpegImagePlugin.get_sampling(image))
                decoded = np.asarray(image.convert("RGB"), np.float64)
            except OSError:
                broken += 1
                continue
            diffs.append(float(np.abs(decoded - rgb[row]).mean()))
            by_encoder["cpu" if share and on_cpu(index, share) else "gpu"].append(diffs[-1])
    return {"frames": len(picked), "undecodable": broken, "mean_abs_diff": round(float(np.mean(diffs)), 3) if diffs
            else None, "max_abs_diff": round(max(diffs), 3) if diffs else None,
            "ok": broken == 0 and bool(diffs) and max(diffs) < 8.0, "chroma": sorted(chroma),
            **{f"mean_abs_diff_{k}": round(float(np.mean(v)), 3) for k, v in by_encoder.items() if v}}


def cpu_jpeg_encoders(rgb, repeats: int = 20) -> dict:
    """ms to encode ``rgb`` ((H, W, 3) uint8, a rendered frame) as JPEG on this thread: Pillow
    (``cpu_jpeg.encode_jpeg_cpu``, 4:4:4) and torchvision's CPU ``encode_jpeg`` (libjpeg's default
    4:2:0; absent where torchvision does not import), best of ``repeats``, with the files' bytes."""
    import numpy as np

    rgb = np.ascontiguousarray(rgb)
    encoders = {"pillow_444": lambda: encode_jpeg_cpu(rgb)}
    try:
        from torchvision.io import encode_jpeg

        chw = torch.from_numpy(rgb).permute(2, 0, 1).contiguous()
        encoders["torchvision_cpu_420"] = lambda: encode_jpeg(chw, quality=JPEG_QUALITY)
    except Exception:  # not installed or built for another torch
        pass
    result = {}
    for name, encode in encoders.items():
        best = float("inf")
        for _ in range(repeats):
            start = time.perf_counter()
            data = encode()
            best = min(best, time.perf_counter() - start)
        result[name] = {"ms": round(1e3 * best, 3), "bytes": len(data)}
    return result


def disk_run(config, out: Path, frames: list[int], categories, write, check=None) -> dict:
    """``write(out, stats)`` into a fresh dataset folder, then the COCO merge and its file as
    ``generate`` writes them: frames/s, MB and files a frame, and the write's stage seconds.
    ``check(out)``, untimed, before the folder is deleted: its result is the run's ``check``."""
    prepare_dirs(out, config.writer)
    stats: dict = {}
    pieces: dict = {}  # the COCO pieces of the frames committed, as generate gathers them
    start = time.perf_counter()
    write(out, stats=stats, pieces=pieces)
    written = time.perf_counter()
    write_annotations(out / "annotations.json", out / "frames", len(frames), categories, {"seed": 2},
                      pieces=pieces, fsync=config.writer.fsync)
    seconds = time.perf_counter() - start
    checked = None if check is None else check(out)
    files = [f for f in out.rglob("*") if f.is_file()]
    size_mb = sum(f.stat().st_size for f in files) / 1e6
    shutil.rmtree(out, ignore_errors=True)
    per_frame = {name: round(1e3 * stats.get(name, 0.0) / len(frames), 3) for name in STAGES}
    per_frame["coco_merge"] = round(1e3 * (start + seconds - written) / len(frames), 3)
    return {"fps": round(len(frames) / seconds, 1), "fps_before_merge": round(len(frames) / (written - start), 1), "mb_per_frame": round(size_mb / len(frames), 4),
            "files_per_frame": round(len(files) / len(frames), 2), "commits": stats.get("commits", 0),
            "coco_pieces": len(pieces),  # frames whose annotations came as pieces, not from the records
            "ms_per_frame": per_frame, **({"check": checked} if check is not None else {})}


def disk_ceiling(out: Path, frames: int, files_per_frame: float, mb_per_frame: float, threads: int) -> float:
    """Frames/s of the disk alone: as many files of the same mean size as ``frames`` frames make,
    written atomically from ``threads`` threads (the writes release the GIL) and flushed with one
    ``syncfs``, as the disk mode's commits do. No encode, no render: the storage's ceiling."""
    count = max(1, round(frames * files_per_frame))
    size = max(1, int(mb_per_frame * 1e6 / files_per_frame))
    payload = os.urandom(size)  # incompressible, as encoded images are
    out.mkdir(parents=True, exist_ok=True)
    start = time.perf_counter()
    with cf.ThreadPoolExecutor(threads) as pool:
        list(pool.map(lambda i: atomic_write_bytes(os.path.join(out, f"{i:07d}.bin"), payload), range(count)))
    if can_sync_filesystem():
        sync_filesystem(out)
    fps = frames / (time.perf_counter() - start)
    shutil.rmtree(out, ignore_errors=True)
    return fps


DISK_RUNS = {
    "headline": (("coco",), True, "disk"),
    "headline_no_fsync": (("coco",), False, "disk"),
    "headline_shm": (("coco",), True, "shm"),
    "with_depth": (("coco", "depth"), True, "disk"),
    "with_depth_masks": (("coco", "depth", "masks"), True, "disk"),
    "png": (("coco",), True, "disk"),
}
"""Each disk run: (writers, fsync, where). The headline is the default annotation set (RGB and the
COCO records: boxes and RLE masks) flushed to ``--out``'s disk; depth (uint16 PNG) and the id PNGs
(masks) are measured on top of it; ``png`` is the headline with lossless RGB (the RGB format of
the others is JPEG where nvjpeg runs); the two after the headline locate its cost: without the
flushes, and into ``/dev/shm`` (memory: the CPU's rate with no storage under it). Each run prints a
``RUN {json}`` line as it ends (a run cut short by a time limit still leaves the ones before)."""


def disk_runs(args, jpeg_ok: bool, root: Path) -> list[tuple]:
    """(name, image format, outputs, fsync, folder) of each of ``--runs``."""
    fmt = "jpg" if jpeg_ok else "png"
    runs = []
    for name in args.runs.split(","):
        outputs, fsync, where = DISK_RUNS[name]
        if name == "png" and not jpeg_ok:
            continue  # the headline is PNG already
        folder = root
        if where == "shm":
            if not os.path.isdir("/dev/shm"):
                continue
            folder = Path("/dev/shm")
        runs.append((name, "png" if name == "png" else fmt, outputs, fsync, folder))
    return runs


def _threads_run(config, out, stats=None, pieces=None, **kwargs):
    """``run_frames`` as ``disk_run`` calls a writer (it keeps no stage times and makes no COCO
    pieces: the merge reads its records)."""
    return run_frames(config, out, **kwargs)


def warm_process(producer, count: int) -> float:
    """In a pool process: one batch, so its kernels are loaded and its graphs captured."""
    start = time.perf_counter()
    next(producer.batches(0, list(range(count))))
    sync(str(producer.engine.device))
    return time.perf_counter() - start


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("--device", default="cuda", help="cuda, cuda:N, or cpu (Warp's CPU device: a smoke test)")
    p.add_argument("--size", default="640x480", help="WIDTHxHEIGHT")
    p.add_argument("--num-worlds", "--worlds", dest="num_worlds", type=int, default=256, help="frames per launch")
    p.add_argument("--frames", type=int, default=2048, help="frames of each timed run")
    p.add_argument("--writer-threads", type=int, default=None, help="encoders of the disk run (default: cores)")
    p.add_argument("--draw-workers", type=int, default=None,
                   help="processes drawing the randomizations (and writing the disk modes' files) (default: "
                        "cores - 2 on CUDA, 1 on Warp's CPU device)")
    p.add_argument("--processes", type=int, default=0,
                   help="producers on the device for a disk run of several processes (default 0: skipped)")
    p.add_argument("--threads-run", action="store_true", help="also the first disk mode (writer threads, PNG)")
    p.add_argument("--disk-frames", type=int, default=4096, help="frames of each disk run")
    p.add_argument("--runs", default=",".join(DISK_RUNS),
                   help=f"disk runs, comma-separated, of {', '.join(DISK_RUNS)} (default: all)")
    p.add_argument("--memory-only", action="store_true",
                   help="raw render and the in-memory modes only (no disk run): e.g. many worlds a launch")
    p.add_argument("--process-frames", type=int, default=None,
                   help="frames of the processes' disk run (default: 2 x --frames, two launches each at the defaults)")
    p.add_argument("--cpu-jpeg-share", default=str(DEFAULT_CPU_JPEG_SHARE),
                   help="share of the JPEG runs' frames (0 to 1, e.g. 1/3; by index) encoded on the draw processes' "
                        f"cores instead of nvjpeg (default {DEFAULT_CPU_JPEG_SHARE}; 0: nvjpeg alone)")
    p.add_argument("--out", default=None, help="parent folder of the disk runs' datasets (default: a temporary one)")
    args = p.parse_args()
    width, height = (int(v) for v in args.size.lower().split("x"))
    cpus = usable_cpus()
    writer_threads = args.writer_threads or cpus
    processes = args.processes
    draw_workers = args.draw_workers
    if draw_workers is None:  # the disk modes write on these processes: at least one
        draw_workers = max(1, cpus - 2) if args.device.startswith("cuda") else 1
    if draw_workers < 1:
        p.error("--draw-workers must be >= 1: the disk modes write on the draw processes")
    args.process_frames = args.process_frames or 2 * args.frames
    try:
        share = share_fraction(args.cpu_jpeg_share)
    except (ValueError, ZeroDivisionError):
        p.error(f"--cpu-jpeg-share {args.cpu_jpeg_share}: give a share from 0 to 1, e.g. 1/3 or 0")
    unknown = set(args.runs.split(",")) - set(DISK_RUNS)
    if unknown:
        p.error(f"unknown --runs {sorted(unknown)}: choose from {', '.join(DISK_RUNS)}")
    config = rep.example_config(width, height)
    n, dev = args.num_worlds, args.device
    frames = list(range(args.frames))
    root = Path(tempfile.mkdtemp(prefix="ambulo-gen-gpu-", dir=args.out))
    gpu = torch.cuda.get_device_name(dev) if dev.startswith("cuda") else None
    say(f"generate_gpu: {width}x{height}, {n} worlds a launch, {args.frames} frames, device {dev} ({gpu}), "
        f"{cpus} cores, CPU JPEG share {share}")

    try:
        # -- warm-up: not in any rate ------------------------------------------------------
        start = time.perf_counter()
        say("building the producer (scene, MuJoCo Warp model, render context)")
        draws = DrawPool(config, draw_workers) if draw_workers else None
        warming = None
        if draws is not None:  # the draw processes start while this one builds and compiles
            say(f"starting {draw_workers} draw processes (the first compiles Warp's CPU render-context kernels "
                "if the cache is cold)")
            warming = threading.Thread(target=draws.warm, daemon=True)
            warming.start()
        producer = BatchedFrameProducer(config, num_worlds=n, device=dev)
        setup_s = time.perf_counter() - start
        say(f"producer ready after {setup_s:.1f} s; first batch: compiles or loads the kernels "
            "(minutes with a cold cache)")
        start = time.perf_counter()
        next(producer.batches(0, frames[:n]))  # drawn in this process: the pool may still be starting
        sync(dev)
        first_batch_s = time.perf_counter() - start
        if warming is not None:
            warming.join()
            producer.draws = draws
        pool_ready_s = time.perf_counter() - start
        say(f"first batch after {first_batch_s:.1f} s, draw processes ready after {pool_ready_s:.1f} s; "
            "warming the capture and writer paths")
        start = time.perf_counter()
        draws, producer.draws = producer.draws, None  # the profile draws in this process
        profile_batch(producer, dev, 0, frames[:n], root / "warm")  # first use of every other path
        shutil.rmtree(root / "warm", ignore_errors=True)
        warm_paths_s = time.perf_counter() - start

        # -- profile: one batch stage by stage, the draws in this process -----------------------
        say("profiling one batch stage by stage (draws in this process)")
        profile = profile_batch(producer, dev, 1, frames[:n], root / "profile")
        producer.draws = draws
        shutil.rmtree(root / "profile", ignore_errors=True)
        say("ms a frame: " + ", ".join(f"{k} {v}" for k, v in profile.items()))

        # -- raw: the render alone (the ceiling) -------------------------------------------------
        repeats = max(3, args.frames // n)
        sync(dev)
        start = time.perf_counter()
        for _ in range(repeats):
            producer.camera.render()
        sync(dev)
        raw_fps = repeats * n / (time.perf_counter() - start)
        say(f"raw render: {raw_fps:.0f} frames/s")

        # -- memory: the in-memory mode, draws on the device -----------------------------------
        say("in-memory mode (device draws): first batch builds the draws' tensors")
        memory_error, device_ms, memory_fps = None, None, 0.0
        try:
            next(producer.batches(1, frames[:n], device_draws=True))
            device_ms = profile_device_draws(producer, dev, frames[:n])
            say("device ms a frame: " + ", ".join(f"{k} {v}" for k, v in device_ms.items()))
            sync(dev)
            start = time.perf_counter()
            count = 0
            for batch in producer.batches(1, frames, device_draws=True):
                count += len(batch["index"])
            sync(dev)
            memory_fps = count / (time.perf_counter() - start)
            say(f"in memory: {memory_fps:.0f} frames/s ({memory_fps / raw_fps:.3f} of raw)")
        except Exception as err:  # reported; the other modes still run
            memory_error = f"{type(err).__name__}: {err}"[:500]
            say(f"in memory (device draws): FAILED {memory_error}")

        # -- memory with the CPU path's draws (what the disk modes render) -----------------------
        start = time.perf_counter()
        count = 0
        for batch in producer.batches(1, frames):
            count += len(batch["index"])
        sync(dev)
        memory_host_fps = count / (time.perf_counter() - start)
        say(f"in memory, host draws: {memory_host_fps:.0f} frames/s ({memory_host_fps / raw_fps:.3f} of raw)")

        # -- disk: the draw processes write from shared memory -------------------------------------
        categories = instance_table(producer.model).categories
        jpeg_ok = jpeg_available(dev)
        disk, disk_ceiling_fps = {}, None
        disk_frames = list(range(args.disk_frames))
        for name, fmt, outputs, fsync, folder in [] if args.memory_only else disk_runs(args, jpeg_ok, root):
            writer_cfg = dataclasses.replace(config.writer, outputs=outputs, fsync=fsync)
            run_config = dataclasses.replace(config, writer=writer_cfg)
            where = Path(tempfile.mkdtemp(prefix=f"ambulo-gen-{name}-", dir=folder))
            try:
                # one batch first, not timed: the run's shared blocks are made and page-locked once
                # per producer and layout (what a long generate pays once), the processes map them
                prepare_dirs(where / "warm", writer_cfg)
                run_batched_frames(run_config, where / "warm", 2, frames[:n], producer, image_format=fmt,
                                   cpu_jpeg_share=share)
                check = functools.partial(jpeg_check, producer, seed=2, frames=disk_frames,
                                          share=share) if fmt == "jpg" else None
                disk[name] = disk_run(run_config, where / "d", disk_frames, categories,
                                      functools.partial(run_batched_frames, run_config, seed=2, frames=disk_frames,
                                                        producer=producer, image_format=fmt, cpu_jpeg_share=share),
                                      check=check)
            except Exception as err:  # one mode's failure is reported, and the others still run
                disk[name] = {"fps": 0.0, "error": f"{type(err).__name__}: {err}"[:500]}
                say(f"to disk, {name}: FAILED {disk[name]['error']}")
                continue
            finally:
                shutil.rmtree(where, ignore_errors=True)
            held = producer.disk_blocks[1] if producer.disk_blocks else []
            disk[name].update(format=fmt, outputs=list(outputs), fsync=fsync, folder=str(folder),
                              cpu_jpeg_share=str(share) if fmt == "jpg" else None,
                              blocks={"count": len(held), "folder": os.path.dirname(held[0].path) if held else None,
                                      "pinned": all(b._pinned is not None for b in held) if held else False})
            say(f"to disk, {name} ({fmt}, {'+'.join(outputs)}, fsync {fsync}, in {folder}): {disk[name]['fps']:.0f} "
                f"frames/s ({disk[name]['fps'] / raw_fps:.3f} of raw), {disk[name]['mb_per_frame']:.3f} MB and "
                f"{disk[name]['files_per_frame']} files a frame, {disk[name]['commits']} commits")
            say("  ms a frame: " + ", ".join(f"{k} {v}" for k, v in disk[name]["ms_per_frame"].items()) +
                f" (part_* are CPU ms summed over {draw_workers} processes)")
            if "check" in disk[name]:
                say(f"  JPEG files vs the frames rendered again: {disk[name]['check']}")
            if name == "headline":  # the storage alone, with the headline's files
                disk_ceiling_fps = disk_ceiling(root / "ceiling", args.disk_frames, disk[name]["files_per_frame"],
                                                disk[name]["mb_per_frame"], cpus)
                say(f"disk ceiling (the headline's files, written and flushed, no encode): "
                    f"{disk_ceiling_fps:.0f} frames/s")
                print("RUN " + json.dumps({"disk_ceiling_fps": round(disk_ceiling_fps, 1)}), flush=True)
            print("RUN " + json.dumps({name: disk[name], "raw_render_fps": round(raw_fps, 1)}), flush=True)
        head = disk.get("headline")
        if args.threads_run and not args.memory_only:  # the first disk mode: encoders on threads of this process
            disk["png_threads"] = disk_run(config, root / "disk_threads", frames, categories,
                                           functools.partial(_threads_run, config, seed=2, frames=frames,
                                                             producer=producer, writer_threads=writer_threads))
            say(f"to disk, png, {writer_threads} threads: {disk['png_threads']['fps']:.0f} frames/s")
        for entry in disk.values():
            entry["of_raw"] = round(entry["fps"] / raw_fps, 3)
            if disk_ceiling_fps:
                entry["of_disk_ceiling"] = round(entry["fps"] / disk_ceiling_fps, 3)
        disk_fps = head["fps"] if head else None
        # one rendered frame encoded on this thread by each CPU JPEG encoder
        rendered = next(producer.batches(1, frames[:n]))["rgb"][0].cpu().numpy()
        cpu_jpeg_ms = cpu_jpeg_encoders(rendered)
        say(f"CPU JPEG encoders, one {width}x{height} frame on one core: {cpu_jpeg_ms}")
        producer.close()
        del producer
        if dev.startswith("cuda"):  # give the device memory back before the processes take theirs
            gc.collect()
            torch.cuda.empty_cache()

        # -- disk on several producer processes sharing the device -------------------------------
        procs = None
        if processes:
            out = root / "disk_processes"
            prepare_dirs(out, config.writer)
            say(f"starting {processes} producer processes on {dev} (each builds its producer and loads the "
                "kernels: not timed)")
            start = time.perf_counter()
            with ProducerPool(config, out, 3, processes, devices=[dev] * processes, num_worlds=n) as pool:
                warm = pool.run_on_each(warm_process, n)
                procs_warm_s = time.perf_counter() - start
                say(f"processes warm after {procs_warm_s:.1f} s (first batch each: {max(warm):.1f} s at most)")
                start = time.perf_counter()
                pool.run(list(range(args.process_frames)))
                procs_fps = args.process_frames / (time.perf_counter() - start)
            shutil.rmtree(out, ignore_errors=True)
            say(f"to disk, {processes} processes: {procs_fps:.0f} frames/s ({procs_fps / raw_fps:.3f} of raw)")
            procs = {"processes": processes, "frames": args.process_frames, "writer_threads_each": max(1, cpus // processes),
                     "warmup_s": round(procs_warm_s, 1), "fps": round(procs_fps, 1),
                     "of_raw": round(procs_fps / raw_fps, 3)}
    finally:
        shutil.rmtree(root, ignore_errors=True)

    best_disk = max(disk_fps or 0.0, procs["fps"] if procs else 0.0)
    jpg_note = None if jpeg_ok or args.memory_only else \
        "torchvision's JPEG encoder did not run on this device: PNG only"
    result = {
        "benchmark": "generate_gpu", "date": datetime.date.today().isoformat(), "device": dev, "gpu": gpu,
        "cpus": cpus, "size": [width, height], "num_worlds": n, "frames": args.frames,
        "warmup": {"setup_s": round(setup_s, 1), "first_batch_s": round(first_batch_s, 1),
                   "draw_processes_ready_s": round(pool_ready_s, 1),
                   "other_paths_s": round(warm_paths_s, 1)},
        "profile_ms_per_frame": profile,
        "raw_render_fps": round(raw_fps, 1),
        "device_ms_per_frame": device_ms,
        "memory_fps": round(memory_fps, 1), "memory_of_raw": round(memory_fps / raw_fps, 3),
        "memory_draws": "device", "memory_error": memory_error,
        "memory_host_draws_fps": round(memory_host_fps, 1), "memory_host_draws_of_raw": round(memory_host_fps / raw_fps, 3),
        "disk_fps": disk_fps and round(disk_fps, 1), "disk_of_raw": disk_fps and round(disk_fps / raw_fps, 3),
        "disk_jpeg_check": head.get("check") if head else None,
        "disk_headline": "RGB (JPEG where nvjpeg runs) + COCO boxes and RLE masks, fsync, on --out's disk, "
                         "the COCO merge included (fps_before_merge without it)",
        "disk_ceiling_fps": disk_ceiling_fps and round(disk_ceiling_fps, 1), "disk_frames": args.disk_frames,
        "disk": disk, "jpeg_note": jpg_note, "jpeg_available": jpeg_ok,
        "cpu_jpeg_share": str(share), "cpu_jpeg_encoders": cpu_jpeg_ms,
        "writer_threads": writer_threads,
        "draw_workers": draw_workers, "disk_processes": procs,
        "targets": {"disk_fps": 2000, "memory_fps": 50000, "size": [640, 480]},
        "meets_targets": {"disk": None if args.memory_only else best_disk >= 2000, "memory": memory_fps >= 50000} if (width, height) == (640, 480)
        else None,
    }
    print("RESULT " + json.dumps(result), flush=True)


if __name__ == "__main__":
    main()
