"""Make a dataset: frames rendered, annotated and written atomically; resumable; on N processes or Ray.

Frame ``i`` depends only on (config, seed, i): the engine is reset, every
randomizer draws from ``frame_rng(seed, randomizer index, i // every_n)`` (``streams``)
and is applied, then the camera captures. So a killed run resumes by skipping
frames whose record counts (``records``: a line of a journal in ``frames/``), and N local processes (``processes.py``) or Ray
workers (``ray_workers.py``, for several machines) produce the same files as one.
"""

from __future__ import annotations

import os
import platform
import sys
from collections.abc import Callable
from pathlib import Path
from typing import Any

import mujoco
from tqdm import tqdm

from ambulo.core import compile_scene
from ambulo.utils.atomic import atomic_write_json, remove_partial_files

from .batched import IMAGE_SOURCE, BatchedFrameProducer
from .batched_disk import SUPPORTED_OUTPUTS, run_batched_frames, supports
from .coco_file import write_annotations
from .config import DatasetConfig
from .cpu_jpeg import DEFAULT_CPU_JPEG_SHARE, share_fraction
from .encode import IMAGE_FORMATS, JPEG_QUALITY, jpeg_available
from .io import PNG_DEFLATE
from .manifest import open_dataset
from .processes import default_workers, run_on_processes, usable_cpus
from .producer import FrameProducer, run_frames
from .ray_workers import run_on_ray
from .records import prune_records
from .writers import frame_subdirs, prepare_dirs

BACKENDS = ("auto", "processes", "ray")


def generate(config: DatasetConfig, out: str | Path, num_frames: int, seed: int = 0, workers: int | None = 1,
             show_progress: bool = True, backend: str = "auto", overwrite: bool = False,
             device: str | None = None, num_worlds: int = 64, writer_threads: int | None = None,
             num_gpus: int = 1, watch: Callable[[Any], Any] | None = None, draw_workers: int = 0,
             image_format: str = "png", cpu_jpeg_share=DEFAULT_CPU_JPEG_SHARE) -> Path:
    """Write (or finish) a dataset of ``num_frames`` frames in ``out``; returns annotations.json.

    ``out`` must be new, empty, or a dataset of the same config and seed (``dataset.json``):
    its complete frames are kept (more frames extend it), damaged ones made again, and the
    temporaries of a killed run removed. ``overwrite`` deletes an ambulo dataset's own files
    first. Any other folder raises ``manifest.DatasetFolderError`` before anything is written.
    ``workers`` > 1 renders chunks of frames in that many processes; None picks one per CPU
    (fewer for short runs). ``backend``: 'processes' (local, spawned), 'ray' (actors on a Ray
    cluster, which needs ``out`` on shared storage; a local one unless ``ray.init`` was called
    or RAY_ADDRESS is set), or 'auto': Ray when RAY_ADDRESS is set or Ray is initialized, else
    processes. The files do not depend on any of this.

    ``device`` ("cuda", "cuda:1", or "cpu" for Warp's CPU device) renders ``num_worlds`` frames per
    launch with MuJoCo Warp instead (``batched.BatchedFrameProducer``): the same frames' scenes,
    labels within a pixel of the CPU path's, colours from MuJoCo Warp's ray caster; one process,
    ``writer_threads`` encoding frames (default: one per CPU). ``num_gpus`` > 1 splits the frames
    over that many processes, one per GPU (``cuda:0`` ... of ``device``'s type), whole launches each.
    ``draw_workers`` > 0 (one GPU) samples the randomizers' draws in that many processes, a batch ahead
    of the render (``draw_pool.DrawPool``; the same numbers): the host-side draws otherwise bound a
    GPU's rate; those processes then also write the files (``batched_disk``: the same files).
    ``image_format`` 'jpg' (``--device``, one GPU) writes the RGB images as JPEG encoded on the GPU
    (nvjpeg through torchvision, which must be installed), on ``draw_workers`` processes (default:
    one per CPU but two); the fingerprint records it. ``cpu_jpeg_share`` (0 to 1, default 1/3): the
    share of those frames, by index, that the draw processes encode on the CPU instead (libjpeg-turbo,
    same quality and chroma: ``cpu_jpeg``) while nvjpeg encodes the rest, whose one-at-a-time encode
    otherwise bounds the rate; 0: nvjpeg alone. A resumed run writes the same bytes as a straight one
    with the same share; another share changes which encoder wrote a frame, not its picture (the
    fingerprint does not record it).

    ``watch`` (``ambulo generate --viewer web``) is called with the producer, in this process (so
    one worker, one GPU), before the first frame; what it returns joins the producer's
    ``Simulation`` as a component (the web viewer does). Generation never steps physics (a frame
    is a reset, the randomizers and a capture), so that component's ``update(0.0)`` runs after
    each frame is written instead, and ``close()`` at the end.
    """
    if backend not in BACKENDS:
        raise ValueError(f"backend must be one of {BACKENDS}, got {backend!r}")
    if num_frames < 1:
        raise ValueError(f"--frames must be >= 1, got {num_frames}")
    if workers is not None and workers < 1:
        raise ValueError(f"--workers must be >= 1, got {workers}")
    if seed < 0:
        raise ValueError(f"--seed must be >= 0 (numpy seeds are non-negative), got {seed}")
    if num_gpus < 1 or (num_gpus > 1 and device is None):
        raise ValueError(f"--num-gpus {num_gpus} needs a positive count and --device (cuda)")
    if device is not None and workers not in (None, 1):
        raise ValueError(f"--device {device} renders every frame of a batch in one launch on one GPU; drop "
                         f"--workers {workers} (or generate on the CPU without --device)")
    if num_worlds < 1:
        raise ValueError(f"--num-worlds must be >= 1, got {num_worlds}")
    if draw_workers < 0 or (draw_workers and (device is None or num_gpus > 1)):
        raise ValueError(f"--draw-workers {draw_workers} feeds the one-GPU batched path: give --device and one GPU, "
                         "or drop it")
    if image_format not in IMAGE_FORMATS:
        raise ValueError(f"--image-format must be one of {IMAGE_FORMATS}, got {image_format!r}")
    share = share_fraction(cpu_jpeg_share)  # raises out of range
    if image_format == "jpg":
        if device is None or num_gpus > 1 or watch is not None:
            raise ValueError("--image-format jpg encodes on the GPU of the batched path: give --device and one GPU "
                             "(and no viewer)")
        if not supports(config.writer):
            raise ValueError(f"--image-format jpg writes {sorted(SUPPORTED_OUTPUTS)} with png16 depth, not "
                             f"{list(config.writer.outputs)}")
        if not jpeg_available(device):
            raise ValueError(f"--image-format jpg needs torchvision built for this torch with JPEG encoding on "
                             f"{device}; install it or write PNG")
        draw_workers = draw_workers or max(1, usable_cpus() - 2)
    if watch is not None and (workers not in (None, 1) or num_gpus > 1 or backend == "ray"):
        raise ValueError("watching a dataset's generation needs its producer in this process: one worker, "
                         "one GPU, no Ray")
    writer_threads = writer_threads or os.cpu_count() or 1
    out = Path(out)
    # the parent process may hold no producer (workers render): compile the scene as they do
    model = compile_scene(config.build_scene(), config.physics)
    producer = None
    if device is not None and num_gpus == 1:
        draws = None
        if draw_workers:
            from .draw_pool import DrawPool

            draws = DrawPool(config, draw_workers)
        producer = BatchedFrameProducer(config, num_worlds, device, draws=draws)
    source = None if device is None else IMAGE_SOURCE if image_format == "png" else f"{IMAGE_SOURCE}, rgb jpeg " \
        f"q{JPEG_QUALITY}"
    open_dataset(out, config, seed, model, num_frames, overwrite, image_source=source)
    prepare_dirs(out, config.writer, config.camera.annotators)
    remove_partial_files(out, *(out / sub for sub in frame_subdirs(config.writer, config.camera.annotators)))
    # the records that do not count are dropped before any frame is written again (records module doc)
    todo = sorted(set(range(num_frames)) - prune_records(out, fsync=config.writer.fsync))
    batched = producer is not None
    workers = 1 if batched or watch is not None else (
        default_workers(len(todo)) if workers is None else min(workers, max(1, len(todo))))
    use_ray = backend == "ray" or (backend == "auto" and workers > 1 and _ray_requested())
    bar = tqdm(total=num_frames, initial=num_frames - len(todo), desc="frames", unit="frame",
               disable=not show_progress)
    progress, watcher = bar.update, None
    pieces: dict = {}  # annotations.json's parts of the frames this run commits, where its path makes them
    if watch is not None and todo:
        producer = producer or FrameProducer(config)
        watcher = watch(producer)

        def progress(frames_written: int) -> None:
            bar.update(frames_written)
            watcher.update(0.0)
    try:
        if not todo:
            renderer = _read_metadata_renderer(out)
        elif device is not None and num_gpus > 1:
            kind = "cpu" if device == "cpu" else "cuda"
            devices = [kind if kind == "cpu" else f"cuda:{i}" for i in range(num_gpus)]
            renderer = run_on_processes(config, out, seed, todo, num_gpus, bar.update, devices=devices,
                                        num_worlds=num_worlds)
        elif use_ray:
            renderer = run_on_ray(config, out, seed, todo, workers, bar.update)
        elif workers > 1:
            renderer = run_on_processes(config, out, seed, todo, workers, bar.update)
        elif batched and producer.draws is not None and watch is None and supports(config.writer):
            renderer = run_batched_frames(config, out, seed, todo, producer, bar.update, image_format,
                                          pieces=pieces, cpu_jpeg_share=share)
        else:
            renderer = run_frames(config, out, seed, todo, progress, producer=producer,
                                  writer_threads=writer_threads if batched else 1)
    finally:
        bar.close()
        if watcher is not None:
            watcher.close()
        if producer is not None and (watcher is not None or batched):
            producer.close()  # a batched producer holds the device's buffers and any draw processes
    from ambulo.sensors.annotators import instance_table

    categories = instance_table(model).categories
    fsync = config.writer.fsync
    metadata = {"name": config.name, "seed": seed, "num_frames": num_frames, "gl_renderer": renderer,
                "mujoco_version": mujoco.__version__, "platform": platform.machine(), "png_deflate": PNG_DEFLATE,
                "categories": categories, "annotators": list(config.camera.annotators)}
    atomic_write_json(out / "metadata.json", metadata, fsync=fsync)
    info = {"description": config.name, "version": "1.0", "gl_renderer": renderer, "seed": seed}
    path = out / "annotations.json"
    write_annotations(path, out / "frames", num_frames, categories, info, pieces=pieces, fsync=fsync)
    return path


def _ray_requested() -> bool:
    """A Ray cluster to join: RAY_ADDRESS, or ``ray.init`` already called (without importing Ray to ask)."""
    ray = sys.modules.get("ray")
    return bool(os.environ.get("RAY_ADDRESS")) or (ray is not None and ray.is_initialized())


def _read_metadata_renderer(out: Path) -> str:
    import json

    meta = out / "metadata.json"
    return json.loads(meta.read_text())["gl_renderer"] if meta.is_file() else os.environ.get("MUJOCO_GL", "")
