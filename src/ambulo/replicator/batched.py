"""Dataset frames rendered many at a time: world w of a MuJoCo Warp engine shows frame ``indices[w]``.

``BatchedFrameProducer`` is ``FrameProducer`` for ``ambulo generate --device cuda``: the same
config, randomizers and writers, but a ``Simulation`` of ``num_worlds`` worlds on the warp engine
and a ``TiledCamera`` that renders all of them in one launch. Each world gets the frame that
``FrameProducer`` would have drawn for its index: randomizer k of frame i samples from
``frame_rng(seed, k, i // every_n)`` on the host exactly as the CPU path does (that is what
makes the two paths' datasets agree object for object), and applies to its own world
(``SceneContext.world``) of host copies of the fields, which then reach the device in one copy
per field (``host_worlds``); the draws may run on other processes, a batch ahead
(``draw_pool``). One kinematics pass poses the worlds (no collision or dynamics: nothing is
simulated). Everything per pixel stays on the device: the render, geom id ->
instance id, and each instance's tight box and pixel count (``device_tight_boxes``: three
scatter reductions over all worlds at once). The host receives one copy per batch of the
images and boxes and of the geom and body poses, from which the loose 2D and the 3D boxes are
computed as the CPU camera computes them (they depend on the pose, not on pixels).

What differs from the CPU path, and why the fingerprint says so (``image_source``): the colours
come from MuJoCo Warp's ray caster (no shadows, one ray per pixel), not from MuJoCo's OpenGL
rasterizer; ids and boxes agree with the CPU path's to a pixel at object silhouettes (tested
with pycocotools). A dataset is never resumed with the other path's images.
"""

from __future__ import annotations

import dataclasses
from typing import TYPE_CHECKING

import numpy as np
import torch

from ambulo.core import Simulation
from ambulo.sensors import annotators as ann
from ambulo.sensors.camera import PinholeCfg, _extrinsics
from ambulo.sensors.tiled_camera import TiledCamera, TiledCameraCfg
from ambulo.utils.rotations import mat_to_quat

from .config import DatasetConfig
from .host_worlds import HostWorlds
from .producer import apply_randomizers
from .randomizers import SceneContext

if TYPE_CHECKING:
    from .draw_pool import DrawPool

IMAGE_SOURCE = "mujoco_warp_raycast"
"""The fingerprint's ``image_source`` of a dataset this module renders."""


def device_tight_boxes(instances: torch.Tensor, num_instances: int) -> tuple[torch.Tensor, torch.Tensor]:
    """Each instance's box and pixel count in every image, on the images' device (no host sync).

    Args:
      instances: (N, H, W) integer instance ids, 0 for background, 1..K objects.
      num_instances: K.
    Returns:
      boxes: (N, K, 4) int64 [x_min, y_min, x_max, y_max] inclusive pixel indices, -1 where the
        instance has no pixel (``annotators.tight_boxes``'s layout, per image);
      pixels: (N, K) int64 visible pixel counts.
    """
    n, h, w = instances.shape
    k = num_instances
    dev = instances.device
    # per image row first: each row's first and last column and pixel count of every instance,
    # (N, H, K+1), scattered along the row; the columns are a broadcast view, never materialized
    ids = instances.long()
    cols = torch.arange(w, device=dev).expand(n, h, w)
    big = torch.iinfo(torch.int64).max
    row_lo = torch.full((n, h, k + 1), big, dtype=torch.int64, device=dev).scatter_reduce_(2, ids, cols, "amin")
    row_hi = torch.full((n, h, k + 1), -1, dtype=torch.int64, device=dev).scatter_reduce_(2, ids, cols, "amax")
    # scatter_add, not bincount: bincount reads the largest id back to size its output (a sync)
    row_px = torch.zeros((n, h, k + 1), dtype=torch.int64, device=dev).scatter_add_(
        2, ids, torch.ones((1, 1, 1), dtype=torch.int64, device=dev).expand(n, h, w))
    # then over the rows: the columns' extremes, and the first and last row holding a pixel
    present = row_px > 0
    row = torch.arange(h, device=dev)[None, :, None]
    lo_y = torch.where(present, row, big).amin(1)
    hi_y = torch.where(present, row, -1).amax(1)
    pixels = row_px.sum(1)[:, 1:]
    boxes = torch.stack((row_lo.amin(1), lo_y, row_hi.amax(1), hi_y), dim=-1)[:, 1:]
    boxes = torch.where((pixels > 0)[..., None], boxes, torch.full_like(boxes, -1))
    return boxes, pixels


def tiled_camera_cfg(camera: PinholeCfg) -> TiledCameraCfg:
    """The dataset camera's pinhole (mount, offset, resolution, field of view, clip) as a
    ``TiledCameraCfg`` with the outputs a dataset frame needs."""
    shared = {f.name: getattr(camera, f.name) for f in dataclasses.fields(PinholeCfg) if f.init}
    shared["renderer"] = "raster"
    return TiledCameraCfg(**shared, data_types=("rgb", "depth", "instance_segmentation", "semantic_segmentation"))


class BatchedFrameProducer:
    """Renders ``num_worlds`` frames of a seeded dataset per launch (see the module docstring)."""

    def __init__(self, config: DatasetConfig, num_worlds: int = 64, device: str = "cuda",
                 draws: DrawPool | None = None):
        if config.visible_fraction:
            raise ValueError("visible_fraction needs one isolated render per object, which the batched GPU path "
                             "does not do; generate on the CPU (no --device) or set visible_fraction=False")
        if config.camera.renderer != "raster":
            raise ValueError(f"the GPU path renders with MuJoCo Warp's ray caster, not renderer="
                             f"{config.camera.renderer!r}; drop --renderer or generate on the CPU")
        self.config = config
        self.num_worlds = int(num_worlds)
        names = [r.name or type(r).__name__ for r in config.randomizers]
        if len(set(names)) != len(names):
            raise ValueError(f"randomizer names must be unique (they key the frame log): {names}")
        self.sim = Simulation(config.build_scene(), config.physics, num_worlds=self.num_worlds, device=device,
                              engine="warp", num_threads=1)
        for name, r in zip(names, config.randomizers):
            r.name = name
            self.sim.add(r)
        self.camera = self.sim.add(TiledCamera(tiled_camera_cfg(config.camera)))
        self.engine = self.sim.start()
        self.model = self.sim.model
        # the randomizers sample and apply on host copies of the fields, uploaded once a batch
        self.host = HostWorlds(self.engine, {self.camera.name: self.camera})
        self.ctx = SceneContext(model=self.model, engine=self.host, cameras=self.host.cameras)
        self.table = ann.instance_table(self.model)
        # geom id + 1 -> instance id (index 0: no geom -> background)
        self._instance_of_geom = torch.as_tensor(self.table.geom_instance, dtype=torch.int32,
                                                 device=self.engine.device)
        self._names = names
        self._cache: dict[int, tuple[tuple[int, int], dict]] = {}
        self._annotators = set(config.camera.annotators)
        self._fields = {name: self.engine.field(name) for name in ("geom_xpos", "geom_xmat", "xpos", "xmat")}
        self._compiled = False
        self.draws = draws
        """Processes that draw the randomizations a batch ahead (``draw_pool.DrawPool`` of this
        config; the producer closes it), or None: drawn on this thread."""
        self.device_draws = None
        """The in-memory mode's ``device_draws.DeviceDraws``, made on first use."""
        self.disk_blocks = None
        """The disk mode's shared batch blocks, kept between runs: ((layout, pinned), blocks)
        (``batched_disk.shared_blocks``)."""

    @property
    def gl_renderer(self) -> str:
        return f"{IMAGE_SOURCE} ({self.engine.device})"

    def randomize_world(self, world: int, seed: int, index: int) -> dict:
        """Apply every randomizer of frame ``index`` to world ``world`` of the host copies
        (``self.host``, uploaded by ``randomize``); returns the frame log. The draws are
        ``FrameProducer.randomize``'s: the same parameters for the same index."""
        self.ctx.world = world
        return apply_randomizers(self.config.randomizers, self._names, self._cache, self.ctx, seed, index)

    def randomize(self, seed: int, chunk: list[int], drawn: list | None = None) -> list[dict]:
        """World w gets frame ``chunk[w]``'s scene: every world's draws applied on the host
        (``draw_on_host``), then the device reset and one copy per written field (``upload_draws``);
        returns the frame logs. With a draw pool the draws come from its processes (``drawn``: the
        chunk's submission, made here if not given)."""
        logs = self.draw_on_host(seed, chunk, drawn)
        self.upload_draws(len(chunk))
        return logs

    def draw_on_host(self, seed: int, chunk: list[int], drawn: list | None = None) -> list[dict]:
        """``randomize``'s host half: the host copies (``self.host``) get the chunk's draws; the
        device is not touched, so this may run while it still renders the batch before (the
        randomizers apply to the host copies alone, and nothing a device reset does is read)."""
        self.host.begin()
        if self.draws is None:
            return [self.randomize_world(w, seed, index) for w, index in enumerate(chunk)]
        return self.draws.collect(self.draws.submit(seed, chunk) if drawn is None else drawn, self.host)

    def upload_draws(self, count: int) -> None:
        """``randomize``'s device half: the state reset, then the host copies' first ``count``
        worlds written to the device (queued on its stream behind the batch before's work; the
        host copies may be rewritten as soon as this returns: ``host_worlds._copy_rows``)."""
        self.sim.reset(forward=False)
        self.host.upload(count)

    def _chunks(self, seed: int, indices: list[int]):
        """(chunk, drawn) for each launch's frames; with a draw pool, the next chunk's draws are
        submitted before this one is rendered, so they run while it renders and is consumed."""
        chunks = _split(indices, self.num_worlds)
        ahead = self.draws.submit(seed, chunks[0]) if self.draws is not None and chunks else None
        for i, chunk in enumerate(chunks):
            drawn = ahead
            if self.draws is not None and i + 1 < len(chunks):
                ahead = self.draws.submit(seed, chunks[i + 1])
            yield chunk, drawn

    def kinematics(self) -> None:
        """Poses of bodies, geoms, cameras and lights from ``qpos``: all a render and the boxes
        read. ``engine.forward`` would add collision detection, constraints and dynamics, which a
        picture does not need (the state is set, not simulated), and their kernels' compile."""
        import mujoco_warp as mjw  # the warp engine's dependency

        m, d = self.engine.wp_model, self.engine.wp_data
        with self.engine.warp_scope():  # the passes GpuEngine.step(refresh=True) runs
            mjw.kinematics(m, d)
            mjw.com_pos(m, d)
            mjw.camlight(m, d)

    def frames(self, seed: int, indices: list[int]):
        """Yield (index, log, capture) for ``indices``, ``num_worlds`` at a time; ``capture`` has
        ``Camera.capture``'s keys and layouts (NumPy), so the CPU path's writers take it."""
        k_matrix = self.camera.get_intrinsics_matrix()
        for chunk, drawn in self._chunks(seed, indices):
            logs, labels = self._render_chunk(seed, chunk, drawn)
            host = self.to_host(len(chunk), *labels)
            for w, (index, log) in enumerate(zip(chunk, logs)):
                yield index, log, self.capture(w, host, k_matrix)

    def batches(self, seed: int, indices: list[int], device_draws: bool = False):
        """The in-memory mode: yield one dict of device tensors per ``num_worlds`` frames, for a
        training loop that never touches the disk. The tensors are the camera's buffers and are
        overwritten by the next batch (clone what must outlive it).

        ``device_draws``: the randomizers draw and apply on the device (``device_draws.DeviceDraws``:
        all worlds at once, no host work per frame and no host sync, so the GPU never waits for the
        CPU), with their own seeded streams: frames of the same (seed, index) are the same in every
        run, but not the CPU path's or the disk mode's scenes. Else the CPU path's host draws.

        Keys: ``index`` (B,) int64 frame indices; ``rgb`` (B, H, W, 3) uint8; ``depth`` (B, H, W)
        float32 m, +inf for no hit; ``instances`` (B, H, W) int32 instance ids (0 background);
        ``boxes`` (B, K, 4) int64 inclusive [x_min, y_min, x_max, y_max] (-1 if unseen);
        ``pixels`` (B, K) int64; ``semantic_ids`` (K,) int64 category id of each instance (1-based
        into ``table.categories``). B is ``num_worlds`` but for a last, partial batch.
        """
        dev = self.engine.device
        semantic = torch.as_tensor(self.table.semantic_ids[1:], dtype=torch.int64, device=dev)
        chunks = ((chunk, None) for chunk in _split(indices, self.num_worlds)) if device_draws \
            else self._chunks(seed, indices)
        for chunk, drawn in chunks:
            # through pinned memory: a plain copy to the GPU would wait for the batch's render
            index = torch.as_tensor(chunk, dtype=torch.int64)
            index = index.pin_memory().to(dev, non_blocking=True) if dev.type == "cuda" else index
            if device_draws:
                self.randomize_on_device(seed, index)
                self.render()
                instances, boxes, pixels = self.labels(len(chunk))
            else:
                _, (instances, boxes, pixels) = self._render_chunk(seed, chunk, drawn)
            out, count = self.camera.data.output, len(chunk)
            yield {"index": index, "rgb": out["rgb"][:count],
                   "depth": out["depth"][:count, ..., 0], "instances": instances, "boxes": boxes, "pixels": pixels,
                   "semantic_ids": semantic}

    def randomize_on_device(self, seed: int, index: torch.Tensor) -> None:
        """World w gets a scene drawn on the device for frame ``index[w]`` ((B,) int64 on the
        engine's device): the state reset, then ``DeviceDraws`` (made on first use)."""
        if self.device_draws is None:
            from .device_draws import DeviceDraws

            self.device_draws = DeviceDraws(self.config.randomizers, self.engine, self.camera, self.model)
        self.sim.reset(forward=False)
        self.camera.reset_pose()
        self.device_draws.apply(seed, index)

    def _render_chunk(self, seed: int, chunk: list[int], drawn: list | None = None) -> tuple[list[dict], tuple]:
        """World w shows frame ``chunk[w]``: reset, randomize, one kinematics pass, one render.
        Returns the frame logs and the device labels of the chunk's worlds (``labels``)."""
        logs = self.randomize(seed, chunk, drawn)
        self.render()
        return logs, self.labels(len(chunk))

    def render(self) -> None:
        """One kinematics pass and one render of every world, as the worlds' fields now stand."""
        if self._compiled:
            self.kinematics()
            self.camera.render()
            return
        from ambulo.engine.gpu import _Ticker  # the engine's own progress lines for a first compile

        # the first launch compiles (or loads) the kernels: minutes when cold, so say so
        with _Ticker("compiling MuJoCo Warp's kinematics and render kernels"):
            self.kinematics()
            self.camera.render()
            if self.engine.device.type == "cuda":
                torch.cuda.synchronize(self.engine.device)
        self._compiled = True

    def labels(self, count: int) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
        """Instance ids (B, H, W), tight boxes (B, K, 4) and pixel counts (B, K) of the first
        ``count`` worlds' images, on the device (no sync)."""
        geom_ids = self.camera.data.output["instance_segmentation"][:count, ..., 0]
        instances = self._instance_of_geom[(geom_ids + 1).long()]
        return (instances, *device_tight_boxes(instances, self.table.num_instances))

    def to_host(self, count: int, instances: torch.Tensor, boxes: torch.Tensor, pixels: torch.Tensor,
                images: bool = True) -> dict:
        """Everything the first ``count`` worlds' captures read, as NumPy arrays of the whole batch:
        one copy each, queued together (pinned buffers) and waited for once. New arrays every
        batch: the writer threads may still be encoding the last batch's frames. ``images=False``:
        the boxes and poses alone (``batched_disk`` moves the images itself)."""
        cam = self.camera
        out = cam.data.output
        device = {
            **({"rgb": out["rgb"][:count], "depth": out["depth"][:count],
                "geom_ids": out["instance_segmentation"][:count, ..., 0], "instances": instances,
                "semantic": out["semantic_segmentation"][:count, ..., 0]} if images else {}),
            "boxes": boxes, "pixels": pixels,
            "pos_w": cam.data.pos_w[:count], "rot_gl": cam.data.rot_w_gl[:count],
            **{name: field[:count] for name, field in self._fields.items()},
        }
        cuda = self.engine.device.type == "cuda"
        host = {}
        for name, tensor in device.items():
            # on Warp's CPU device the tensors are the camera's buffers: copied, not viewed
            host[name] = torch.empty(tensor.shape, dtype=tensor.dtype, pin_memory=cuda)
            host[name].copy_(tensor, non_blocking=cuda)
        if cuda:
            torch.cuda.current_stream(self.engine.device).synchronize()
        arrays = {name: t.numpy() for name, t in host.items()}
        for name in ("pos_w", "rot_gl", *self._fields):  # the pose arithmetic is float64, as on the CPU camera
            arrays[name] = arrays[name].astype(np.float64)
        return arrays

    def capture(self, w: int, host: dict, k_matrix: np.ndarray) -> dict:
        """World ``w``'s frame of a batch (``to_host``) in ``Camera.capture``'s form."""
        return frame_capture(w, host, k_matrix, self.camera.cfg, self.table, self.model, self._annotators)

    def close(self) -> None:
        """Stop the draw processes and free the disk mode's blocks (the engine and camera buffers
        are freed with the producer)."""
        if self.draws is not None:
            self.draws.close()
            self.draws = None
        self.close_disk_blocks()

    def close_disk_blocks(self) -> None:
        """Free the disk mode's shared blocks (their files and page locks), if any."""
        if self.disk_blocks is not None:
            for block in self.disk_blocks[1]:
                block.close()
            self.disk_blocks = None


def frame_capture(w: int, host: dict, k_matrix: np.ndarray, cfg: TiledCameraCfg, table, model, annotators) -> dict:
    """World ``w``'s frame of a batch's host arrays (``BatchedFrameProducer.to_host``) in
    ``Camera.capture``'s form, for camera ``cfg`` and ``annotators`` (a set of names). An image
    missing from ``host`` is missing from the capture (the disk mode's writers get the images
    already converted on the device, and the instance ids only for their PNGs: its COCO masks come
    with the capture's ``coco_rles``)."""
    names = annotators
    pos, rot_gl = host["pos_w"][w], host["rot_gl"][w]
    extr = _extrinsics(pos[None], rot_gl[None])[0]
    out: dict = {"camera": {"intrinsics": k_matrix, "extrinsics_cw": extr, "pos_w": pos,
                            "quat_w_opengl": mat_to_quat(rot_gl), "width": cfg.width, "height": cfg.height}}
    out |= {name: host[name][w] for name in ("rgb", "geom_ids") if name in host}
    if "depth" in names and "depth" in host:
        out["depth"] = host["depth"][w, ..., 0]
    if "instance_segmentation" in names and "instances" in host:
        out["instance_segmentation"] = host["instances"][w]
    if "semantic_segmentation" in names and "semantic" in host:
        out["semantic_segmentation"] = host["semantic"][w]
    boxes, pixels = host["boxes"][w], host["pixels"][w]
    visible = np.flatnonzero(pixels > 0)
    if "bounding_box_2d_tight" in names:
        out["bounding_box_2d_tight"] = {"instance_id": visible + 1, "semantic_id": table.semantic_ids[visible + 1],
                                        "box": boxes[visible], "pixels": pixels[visible]}
    geom_pos, geom_rot = host["geom_xpos"][w], host["geom_xmat"][w].reshape(-1, 3, 3)
    if "bounding_box_2d_loose" in names:
        loose = ann.loose_boxes(table, model, geom_pos, geom_rot, extr, k_matrix, cfg.width, cfg.height,
                                cfg.clipping_range_m[0])
        ids = np.array([i for i, b in enumerate(loose) if b is not None], np.int64)
        out["bounding_box_2d_loose"] = {"instance_id": ids + 1, "semantic_id": table.semantic_ids[ids + 1],
                                        "box": np.array([loose[i] for i in ids]).reshape(-1, 4)}
    if "bounding_box_3d" in names:
        center_w, rot_w, half = ann.instance_boxes_3d(table, model, host["xpos"][w],
                                                      host["xmat"][w].reshape(-1, 3, 3), geom_pos, geom_rot)
        out["bounding_box_3d"] = {
            "instance_id": np.arange(1, table.num_instances + 1), "semantic_id": table.semantic_ids[1:],
            "center_w": center_w, "rot_w": rot_w, "half_extent": half,
            "center_c": center_w @ extr[:3, :3].T + extr[:3, 3], "rot_c": extr[:3, :3] @ rot_w}
    return out


def _split(indices, size: int) -> list[list[int]]:
    """``indices`` in launches of ``size`` frames (the last may be short)."""
    indices = list(indices)
    return [indices[start:start + size] for start in range(0, len(indices), size)]


__all__ = ["BatchedFrameProducer", "IMAGE_SOURCE", "device_tight_boxes", "frame_capture", "tiled_camera_cfg"]
