"""Make a dataset: frames rendered, annotated and written atomically; resumable; on N processes or Ray.

Frame ``i`` depends only on (config, seed, i): the engine is reset, every
randomizer draws from ``default_rng([seed, randomizer index, i // every_n])``
and is applied, then the camera captures. So a killed run resumes by skipping
frames whose record exists, and N local processes (``processes.py``) or Ray
workers (``ray_workers.py``, for several machines) produce the same files as one.
"""

from __future__ import annotations

import concurrent.futures as cf
import os
import platform
import sys
from pathlib import Path

import mujoco
import numpy as np
from tqdm import tqdm

from ambulo.core import Simulation, compile_scene
from ambulo.sensors import Camera
from ambulo.utils.atomic import atomic_write_json, remove_partial_files

from .coco import merge_coco
from .config import DatasetConfig
from .io import PNG_DEFLATE
from .manifest import open_dataset
from .processes import default_workers, run_on_processes
from .randomizers import SceneContext
from .writers import FrameWriter, frame_is_complete, frame_subdirs, prepare_dirs

_MAX_PENDING_WRITES = 4  # frames queued for the writer thread; bounds memory


class FrameProducer:
    """Builds the scene once and renders any frame index of a seeded dataset."""

    def __init__(self, config: DatasetConfig):
        self.config = config
        names = [r.name or type(r).__name__ for r in config.randomizers]
        if len(set(names)) != len(names):
            raise ValueError(f"randomizer names must be unique (they key the frame log): {names}")
        annotators = tuple(config.camera.annotators)
        if config.visible_fraction and "visible_fraction" not in annotators:
            annotators += ("visible_fraction",)
        # the core lifecycle: randomizers and the camera are components of one Simulation;
        # one engine thread, since rendering (llvmpipe) already uses every core
        self.sim = Simulation(config.build_scene(), config.physics, num_worlds=1, num_threads=1)
        for name, r in zip(names, config.randomizers):
            r.name = name
            self.sim.add(r)
        self.camera = self.sim.add(Camera(_with_annotators(config.camera, annotators)))
        self.engine = self.sim.start()
        self.model = self.sim.model
        self.ctx = SceneContext(model=self.model, engine=self.engine, cameras={self.camera.name: self.camera})
        self._names = names
        self._cache: dict[int, tuple[int, dict]] = {}

    @property
    def table(self):
        return self.camera.table

    @property
    def gl_renderer(self) -> str:
        return self.camera.renderer.gl_renderer

    def randomize(self, seed: int, index: int) -> dict:
        """Reset world 0 and apply every randomizer for frame ``index``; returns the frame log.

        No kinematics pass here: the camera's capture runs the only one, on the final state.
        """
        self.sim.reset(forward=False)
        self.camera.reset_pose()
        log = {}
        for k, (name, r) in enumerate(zip(self._names, self.config.randomizers)):
            block = index // max(1, r.every_n_frames)
            cached = self._cache.get(k)
            if cached is None or cached[0] != (seed, block):
                params = r.sample(np.random.default_rng([seed, k, block]), self.ctx)
                self._cache[k] = ((seed, block), params)
            params = self._cache[k][1]
            r.apply(params, self.ctx)
            log[name] = params
        return log

    def replay(self, log: dict) -> None:
        """Apply a logged frame's parameters (no random draws): regenerates that frame alone."""
        self.sim.reset(forward=False)
        self.camera.reset_pose()
        for name, r in zip(self._names, self.config.randomizers):
            r.apply(log[name], self.ctx)

    def capture(self) -> dict:
        return self.camera.capture(0)

    def frames(self, seed: int, indices: list[int]):
        """Yield (index, log, capture) for ``indices``, randomizing frame i+1 while frame i's id pass rasterizes."""
        indices = list(indices)
        if not indices:
            return
        log = self.randomize(seed, indices[0])
        self.camera.begin_capture(0)
        for k, index in enumerate(indices):
            following = indices[k + 1] if k + 1 < len(indices) else None
            next_log = self.randomize(seed, following) if following is not None else None
            capture = self.camera.end_capture()
            if following is not None:
                self.camera.begin_capture(0)
            yield index, log, capture
            log = next_log

    def close(self) -> None:
        self.camera.close()


def _with_annotators(cfg, annotators):
    from dataclasses import replace

    return replace(cfg, annotators=tuple(dict.fromkeys(annotators)))


def done_frames(out: Path, num_frames: int) -> set[int]:
    """The frames of ``out`` that are complete: a record that parses, and every file it lists with its size."""
    out = Path(out)
    if not (out / "frames").is_dir():
        return set()
    return {i for i in range(num_frames) if frame_is_complete(out, i)}


def run_frames(config: DatasetConfig, out: Path, seed: int, frames: list[int], progress=None,
               producer: FrameProducer | None = None) -> str:
    """Render and write ``frames`` (skipping none); returns the GL renderer string.

    The writer thread encodes and writes frame i while frame i+1 renders. On any exit
    (Ctrl-C included) the records of the frames already written are written too, so
    an interrupted run keeps them.
    """
    out = Path(out)
    owned = producer is None
    producer = producer or FrameProducer(config)
    writer = FrameWriter(out, config.writer)
    pending: list[cf.Future] = []
    try:
        with cf.ThreadPoolExecutor(max_workers=1, thread_name_prefix="ambulo-writer") as pool:
            try:
                for index, log, capture in producer.frames(seed, frames):
                    pending.append(pool.submit(writer.write, index, capture, producer.table, log))
                    if len(pending) >= _MAX_PENDING_WRITES:
                        pending.pop(0).result()
                        if progress is not None:
                            progress(1)
                for fut in pending:
                    fut.result()
                    if progress is not None:
                        progress(1)
            except BaseException:
                pool.submit(writer.flush)  # after the queued writes; the pool's exit waits for it
                raise
            pool.submit(writer.flush).result()
        return producer.gl_renderer
    finally:
        if owned:
            producer.close()


BACKENDS = ("auto", "processes", "ray")


def generate(config: DatasetConfig, out: str | Path, num_frames: int, seed: int = 0, workers: int | None = 1,
             show_progress: bool = True, backend: str = "auto", overwrite: bool = False) -> Path:
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
    """
    if backend not in BACKENDS:
        raise ValueError(f"backend must be one of {BACKENDS}, got {backend!r}")
    if num_frames < 1:
        raise ValueError(f"--frames must be >= 1, got {num_frames}")
    if workers is not None and workers < 1:
        raise ValueError(f"--workers must be >= 1, got {workers}")
    if seed < 0:
        raise ValueError(f"--seed must be >= 0 (numpy seeds are non-negative), got {seed}")
    out = Path(out)
    # the parent process may hold no producer (workers render): compile the scene as they do
    model = compile_scene(config.build_scene(), config.physics)
    open_dataset(out, config, seed, model, num_frames, overwrite)
    prepare_dirs(out, config.writer)
    remove_partial_files(out, *(out / sub for sub in frame_subdirs(config.writer)))
    todo = sorted(set(range(num_frames)) - done_frames(out, num_frames))
    workers = default_workers(len(todo)) if workers is None else min(workers, max(1, len(todo)))
    use_ray = backend == "ray" or (backend == "auto" and workers > 1 and _ray_requested())
    bar = tqdm(total=num_frames, initial=num_frames - len(todo), desc="frames", unit="frame",
               disable=not show_progress)
    try:
        if not todo:
            renderer = _read_metadata_renderer(out)
        elif use_ray:
            from .ray_workers import run_on_ray

            renderer = run_on_ray(config, out, seed, todo, workers, bar.update)
        elif workers > 1:
            renderer = run_on_processes(config, out, seed, todo, workers, bar.update)
        else:
            renderer = run_frames(config, out, seed, todo, bar.update)
    finally:
        bar.close()
    from ambulo.sensors.annotators import instance_table

    categories = instance_table(model).categories
    fsync = config.writer.fsync
    metadata = {"name": config.name, "seed": seed, "num_frames": num_frames, "gl_renderer": renderer,
                "mujoco_version": mujoco.__version__, "platform": platform.machine(), "png_deflate": PNG_DEFLATE,
                "categories": categories, "annotators": list(config.camera.annotators)}
    atomic_write_json(out / "metadata.json", metadata, fsync=fsync)
    info = {"description": config.name, "version": "1.0", "gl_renderer": renderer, "seed": seed}
    coco = merge_coco(out / "frames", num_frames, categories, info)
    path = out / "annotations.json"
    atomic_write_json(path, coco, fsync=fsync)
    return path


def _ray_requested() -> bool:
    """A Ray cluster to join: RAY_ADDRESS, or ``ray.init`` already called (without importing Ray to ask)."""
    ray = sys.modules.get("ray")
    return bool(os.environ.get("RAY_ADDRESS")) or (ray is not None and ray.is_initialized())


def _read_metadata_renderer(out: Path) -> str:
    import json

    meta = out / "metadata.json"
    return json.loads(meta.read_text())["gl_renderer"] if meta.is_file() else os.environ.get("MUJOCO_GL", "")
