"""The frame producer: one scene built once, any frame index of a seeded dataset rendered and written.

``FrameProducer`` owns a ``Simulation`` whose components are the config's
randomizers and its camera; ``run_frames`` renders a list of frame indices with
it and writes them through a ``FrameWriter`` on a thread. ``generate`` (one
process), ``processes`` (N local processes) and ``ray_workers`` (Ray actors) all
render through these two, which is why they live below all three: the workers
import this module, never ``generate``.
"""

from __future__ import annotations

import collections
import concurrent.futures as cf
import contextlib
import gc
from dataclasses import replace
from pathlib import Path

from ambulo.core import Simulation
from ambulo.sensors import Camera, box_kernel
from ambulo.sensors.camera import tight_box_output

from . import io
from .config import DatasetConfig
from .mask_kernel import instance_masks, warm_up
from .randomizers import CameraJitter, SceneContext
from .streams import frame_rng
from .writers import FrameWriter, write_frame_files

_MAX_PENDING_WRITES = 4  # frames queued for the writer thread; bounds memory


class FrameProducer:
    """Builds the scene once and renders any frame index of a seeded dataset."""

    def __init__(self, config: DatasetConfig, geom_ids: bool = False):
        """``geom_ids``: each capture also holds the (H, W) geom id map (``Camera.begin_capture``),
        for writers that tell unlabelled geoms from the background (Isaac's BasicWriter); an
        ``ambulo generate`` dataset reads none, and the lookup is ~2 % of a frame."""
        self.config = config
        self._geom_ids = geom_ids
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
        # a CameraJitter of this camera sets its whole pose from the configured offset every frame
        # (cached draws are applied again too): resetting the pose first would only be overwritten
        self._jitter_sets_pose = any(type(r) is CameraJitter and r.camera == self.camera.name
                                     for r in config.randomizers)
        # the tight boxes and the COCO masks read from one pass over the instance image (``mask_kernel``):
        # the camera is asked for everything but the tight boxes, which ``_finish`` adds from that pass
        # (the camera's own are found in row order, a second pass); not with visible_fraction, which the
        # camera computes from its tight boxes' pixel counts
        wanted = self.camera.annotators
        self._boxes_from_runs = ("instance_segmentation" in wanted and "bounding_box_2d_tight" in wanted
                                 and "visible_fraction" not in wanted)
        self._capture_annotators = tuple(a for a in wanted if a != "bounding_box_2d_tight") \
            if self._boxes_from_runs else None
        # the compiled passes (``mask_kernel``, ``io``'s PNG rows) loaded now, not in the first frame
        if self._boxes_from_runs:
            warm_up()
        if {"bounding_box_2d_loose", "bounding_box_3d", "visible_fraction"} & set(wanted):
            box_kernel.warm_up()
        io.warm_up()

    @property
    def table(self):
        return self.camera.table

    @property
    def gl_renderer(self) -> str:
        """What drew the frames: the GL renderer string, with the colour tier where not raster."""
        return self.camera.renderer_name if self.camera.cfg.renderer != "raster" else self.camera.renderer.gl_renderer

    def randomize(self, seed: int, index: int) -> dict:
        """Reset world 0 and apply every randomizer for frame ``index``; returns the frame log.

        No kinematics pass here: the camera's capture runs the only one, on the final state. The
        camera's pose is reset to its offset unless a ``CameraJitter`` of it sets the whole pose anyway.
        """
        self.sim.reset(forward=False)
        if not self._jitter_sets_pose:
            self.camera.reset_pose()
        return apply_randomizers(self.config.randomizers, self._names, self._cache, self.ctx, seed, index)

    def replay(self, log: dict) -> None:
        """Apply a logged frame's parameters (no random draws): regenerates that frame alone."""
        self.sim.reset(forward=False)
        self.camera.reset_pose()
        for name, r in zip(self._names, self.config.randomizers):
            r.apply(log[name], self.ctx)

    def capture(self) -> dict:
        self._begin_capture()
        return self._finish(self.camera.end_capture())

    def _begin_capture(self) -> None:
        """Render the colour image and queue the id pass, asking the camera for what ``_finish`` does not add."""
        self.camera.begin_capture(0, self._capture_annotators, geom_ids=self._geom_ids)

    def _finish(self, capture: dict) -> dict:
        """The camera's capture with the tight boxes from the instance image's column runs, and the
        COCO masks' RLEs from the same runs (``coco_rles``, read by ``coco.frame_annotations``): one
        compiled pass with numba, else NumPy's (``mask_kernel``)."""
        if self._boxes_from_runs:
            masks = instance_masks(capture["instance_segmentation"], self.table.num_instances)
            capture["bounding_box_2d_tight"] = tight_box_output(self.table, masks.boxes, masks.pixels)
            capture["coco_rles"] = masks.rles
        return capture

    def frames(self, seed: int, indices: list[int]):
        """Yield (index, log, capture) for ``indices``, randomizing frame i+1 while frame i's id pass rasterizes."""
        indices = list(indices)
        if not indices:
            return
        log = self.randomize(seed, indices[0])
        self._begin_capture()
        for k, index in enumerate(indices):
            following = indices[k + 1] if k + 1 < len(indices) else None
            next_log = self.randomize(seed, following) if following is not None else None
            capture = self._finish(self.camera.end_capture())
            if following is not None:
                self._begin_capture()
            yield index, log, capture
            log = next_log

    def close(self) -> None:
        self.camera.close()


def apply_randomizers(randomizers, names: list[str], cache: dict, ctx: SceneContext, seed: int, index: int) -> dict:
    """Draw and apply every randomizer of frame ``index`` to world ``ctx.world``; returns the frame log.

    Randomizer k of frame i draws from ``frame_rng(seed, k, i // every_n_frames)`` (Philox keyed by
    the three, ``streams``), so a frame's parameters depend on (config, seed, index) alone; ``cache``
    ({k: ((seed, block), params)}) keeps the last draw of each randomizer for the frames of the same block."""
    log = {}
    for k, (name, r) in enumerate(zip(names, randomizers)):
        block = index // max(1, r.every_n_frames)
        cached = cache.get(k)
        if cached is None or cached[0] != (seed, block):
            params = r.sample(frame_rng(seed, k, block), ctx)
            cache[k] = ((seed, block), params)
        params = cache[k][1]
        r.apply(params, ctx)
        log[name] = params
    return log


def _with_annotators(cfg, annotators):
    return replace(cfg, annotators=tuple(dict.fromkeys(annotators)))


def run_frames(config: DatasetConfig, out: Path, seed: int, frames: list[int], progress=None,
               producer: FrameProducer | None = None, writer_threads: int = 1) -> str:
    """Render and write ``frames`` (skipping none); returns the GL renderer string.

    The writer thread encodes and writes frame i while frame i+1 renders. On any exit
    (Ctrl-C included) the records of the frames already written are written too, so
    an interrupted run keeps them. ``writer_threads`` > 1 encodes that many frames at once
    (PNG deflate and file writes release the GIL): what a producer rendering many frames
    per call (``batched``) needs to keep up.
    """
    out = Path(out)
    owned = producer is None
    producer = producer or FrameProducer(config)
    writer = FrameWriter(out, config.writer)
    if writer_threads > 1:
        try:
            return _run_frames_threaded(config, out, seed, frames, progress, producer, writer, writer_threads)
        finally:
            if owned:
                producer.close()
    pending: list[cf.Future] = []
    try:
        with _heap_frozen(), cf.ThreadPoolExecutor(max_workers=1, thread_name_prefix="ambulo-writer") as pool:
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


def _run_frames_threaded(config, out, seed, frames, progress, producer, writer, threads: int) -> str:
    """``run_frames`` with ``threads`` encoders: files written on the pool, records kept in frame
    order on this thread (``FrameWriter.add``), so the batch flushes work as with one thread."""
    pending: collections.deque = collections.deque()

    def settle(future_pair) -> None:
        index, future = future_pair
        writer.add(index, future.result())
        if progress is not None:
            progress(1)

    with _heap_frozen(), cf.ThreadPoolExecutor(max_workers=threads, thread_name_prefix="ambulo-writer") as pool:
        try:
            for index, log, capture in producer.frames(seed, frames):
                pending.append((index, pool.submit(write_frame_files, out, index, capture, producer.table, log,
                                                   config.writer, writer.fsync_files)))
                while len(pending) > 2 * threads:  # bounds the frames held in memory
                    settle(pending.popleft())
            while pending:
                settle(pending.popleft())
        except BaseException:
            for index, future in pending:  # keep every frame whose files were written
                if not future.cancel():
                    with contextlib.suppress(Exception):
                        writer.add(index, future.result())
            writer.flush()
            raise
        writer.flush()
    return producer.gl_renderer


@contextlib.contextmanager
def _heap_frozen():
    """Leave the objects alive before the run out of the cyclic garbage collector's scans.

    A producer process holds ~225,000 tracked objects (torch, mujoco, numpy), and every frame
    makes thousands of small ones (records, logs), so full collections kept re-scanning the
    whole heap: ~0.9 ms CPU a frame, ~4 % of it at 320x240 (measured with ``gc.callbacks``).
    Frozen objects are still freed by reference counting, and the run's own objects are
    collected as usual; on exit they are handed back (``gc.unfreeze``), unless someone else
    had frozen the heap already, which is then left as it was.
    """
    if gc.get_freeze_count():
        yield
        return
    gc.freeze()
    try:
        yield
    finally:
        gc.unfreeze()

