"""The GPU path's disk mode: a batch's pixels prepared on the device, its files written on every core.

``run_frames`` with writer threads (the batched path's first disk mode) leaves a frame's host
work (loose and 3D boxes, COCO RLE, four PNG encodes, the record: ~20 ms of CPU a 640x480 frame)
to threads of the producer's process, and much of it holds the GIL. ``run_batched_frames`` encodes
the RGB images on the device when ``image_format='jpg'`` (``encode``: nvjpeg, a third of the PNG
work gone) and moves the rest to the draw processes (``draw_pool.DrawPool``, which already hold
the scene): each batch's images (ids as 16 bits) are copied once into a memory-mapped block
(``SharedBatch``, page-locked for the GPU's copy when CUDA allows), and each process writes a
contiguous part of the batch's frames from there (``writers.write_frame_files``) and hands back
their records. A thread here writes the records, a batch at a time after one flush of the batch's
files (``FrameWriter``), so a record on disk still always points to data on disk; two blocks
alternate, so the device renders batch i+1 while the processes write batch i.

The files are the ``run_frames`` path's, byte for byte, with PNG RGB (tested); with JPEG the RGB
file is ``rgb/NNNNNN.jpg`` and the record's ``file_name`` says so (``writers.write_frame_files`` with ``rgb_jpeg``). Writers
supported: coco, depth (png16), masks, kitti; others (raw, npy depth) take ``run_frames``.
"""

from __future__ import annotations

import contextlib
import mmap
import os
import pickle
import queue
import tempfile
import threading
from pathlib import Path

import numpy as np
import torch

from . import draw_pool
from .batched import BatchedFrameProducer, frame_capture, tiled_camera_cfg
from .encode import IMAGE_FORMATS, as_u16_bits, depth_mm, encode_jpegs
from .writers import FrameWriter, write_frame_files

SUPPORTED_OUTPUTS = {"coco", "depth", "masks", "kitti"}


def supports(writer_cfg) -> bool:
    """Whether ``run_batched_frames`` writes this writer config (else ``run_frames`` does)."""
    return set(writer_cfg.outputs) <= SUPPORTED_OUTPUTS and writer_cfg.depth_format == "png16"


class SharedBatch:
    """One batch's images in a memory-mapped file that the writer processes map too: named NumPy
    arrays over it, page-locked for CUDA copies when the driver agrees (else the copies go through
    pageable memory). The file lives in ``/dev/shm`` when that has room for it (a container's is
    often 64 MB), else in the temporary folder (the page cache holds it)."""

    def __init__(self, layout: dict[str, tuple[tuple[int, ...], str]], pin: bool):
        self.layout = layout
        offsets, size = {}, 0
        for name, (shape, dtype) in layout.items():
            offsets[name] = size
            size += -(-int(np.prod(shape)) * np.dtype(dtype).itemsize // 64) * 64
        self.offsets, self.size = offsets, max(size, 64)
        folder = _block_dir(self.size)
        fd, self.path = tempfile.mkstemp(prefix="ambulo-batch-", dir=folder)
        try:
            os.ftruncate(fd, self.size)
            self._map = mmap.mmap(fd, self.size)
        finally:
            os.close(fd)
        self.arrays = _arrays(self._map, layout, offsets)
        self._pinned = None
        if pin and folder is not None:  # shared memory pins; a file's pages may not (Linux refuses long pins)
            pointer = np.frombuffer(self._map, np.uint8, count=1).ctypes.data
            if int(torch.cuda.cudart().cudaHostRegister(pointer, self.size, 1)) == 0:  # 1: portable
                self._pinned = pointer
            else:
                _clear_cuda_error()

    @property
    def spec(self) -> tuple[str, dict, dict]:
        """What a process needs to map the block: its file, the layout and the offsets."""
        return self.path, self.layout, self.offsets

    def close(self) -> None:
        if self._pinned is not None:
            torch.cuda.cudart().cudaHostUnregister(self._pinned)
            self._pinned = None
        self.arrays.clear()
        with contextlib.suppress(BufferError):  # a view still alive: the mapping goes with it
            self._map.close()
        with contextlib.suppress(FileNotFoundError):
            os.unlink(self.path)


def _clear_cuda_error() -> None:
    """A failed ``cudaHostRegister`` leaves its error as the CUDA runtime's last error, which torch's
    next kernel-launch check would raise as its own: one throwaway launch takes it."""
    with contextlib.suppress(RuntimeError):
        torch.ones(1, device="cuda").add_(1)
        torch.cuda.synchronize()


def _block_dir(size: int) -> str | None:
    """``/dev/shm`` when it has room for two blocks and some to spare, else the temporary folder."""
    try:
        stat = os.statvfs("/dev/shm")
    except OSError:
        return None
    return "/dev/shm" if stat.f_bavail * stat.f_frsize > 3 * size else None


def _arrays(buffer, layout: dict, offsets: dict) -> dict:
    return {name: np.ndarray(shape, dtype, buffer=buffer, offset=offsets[name]) for name, (shape, dtype) in layout.items()}


def batch_layout(num_worlds: int, height: int, width: int, jpeg: bool, semantic: bool = True) -> dict:
    """The arrays a batch's block holds: depth (m), instance ids and, when the camera's annotators ask
    for them (``semantic``), semantic ids (16 bits), and the RGB images, raw or as the batch's JPEG
    files end to end (``jpeg_bytes``, with their offsets)."""
    image = (num_worlds, height, width)
    # the JPEG mode's own writer takes the depth in mm (converted on the device: half the bytes)
    layout = {"depth_mm": (image, "<u2")} if jpeg else {"depth": ((*image, 1), "<f4")}
    layout["instances"] = (image, "<u2")
    if semantic:
        layout["semantic"] = (image, "<u2")
    if jpeg:  # a JPEG larger than its raw pixels does not occur at the quality used
        layout["jpeg_bytes"] = ((num_worlds * height * width * 3,), "u1")
    else:
        layout["rgb"] = ((*image, 3), "u1")
    return layout


def run_batched_frames(config, out: Path, seed: int, frames: list[int], producer: BatchedFrameProducer,
                       progress=None, image_format: str = "png") -> str:
    """Render and write ``frames`` (see the module docstring); returns the renderer's name.
    ``producer.draws`` (a ``DrawPool`` of this config) draws the scenes and writes the files."""
    if image_format not in IMAGE_FORMATS:
        raise ValueError(f"image format must be one of {IMAGE_FORMATS}, got {image_format!r}")
    if not supports(config.writer):
        raise ValueError(f"the batched disk mode writes {sorted(SUPPORTED_OUTPUTS)} with png16 depth; "
                         f"got outputs {list(config.writer.outputs)}, depth {config.writer.depth_format!r}")
    pool = producer.draws
    if pool is None:
        raise ValueError("run_batched_frames writes on the producer's draw processes: give it a DrawPool")
    out = Path(out)
    jpeg = image_format == "jpg"
    cfg = producer.camera.cfg
    cuda = producer.engine.device.type == "cuda"
    writer = FrameWriter(out, config.writer, batch=producer.num_worlds)
    semantic = "semantic_segmentation" in config.camera.annotators
    layout = batch_layout(producer.num_worlds, cfg.height, cfg.width, jpeg, semantic)
    blocks = [SharedBatch(layout, pin=cuda) for _ in range(2)]
    free: queue.Queue = queue.Queue()
    for block in blocks:
        free.put(block)
    written: queue.Queue = queue.Queue()  # (block, futures) in batch order, then None
    failed: list[BaseException] = []

    def settle() -> None:
        """On a thread: each batch's records, as its processes finish (the batch flushes, the
        records' writes), while this thread renders the next; then its block is free again."""
        while (item := written.get()) is not None:
            block, futures = item
            try:
                for future in futures:
                    for index, record in future.result():
                        writer.add(index, record)
                        if progress is not None:
                            progress(1)
            except BaseException as err:  # the frames of the other parts are kept; the run stops
                failed.append(err)
            finally:
                free.put(block)

    settler = threading.Thread(target=settle, name="ambulo-records", daemon=True)
    settler.start()
    try:
        for chunk, drawn in producer._chunks(seed, frames):
            logs, (instances, boxes, pixels) = producer._render_chunk(seed, chunk, drawn)
            count = len(chunk)
            images = producer.camera.data.output
            device = {"depth_mm": depth_mm(images["depth"][:count, ..., 0])} if jpeg \
                else {"depth": images["depth"][:count]}
            device["instances"] = as_u16_bits(instances)
            if semantic:
                device["semantic"] = as_u16_bits(images["semantic_segmentation"][:count, ..., 0])
            sizes = None
            if jpeg:
                files = encode_jpegs(images["rgb"][:count])
                sizes = [int(f.numel()) for f in files]
                device["jpeg_bytes"] = torch.cat(files)
            else:
                device["rgb"] = images["rgb"][:count]
            block = free.get()  # the batch before last has been written
            if failed:
                raise failed[0]
            for name, tensor in device.items():
                target = block.arrays[name].reshape(-1)[:tensor.numel()].view(_NUMPY[tensor.dtype])
                torch.from_numpy(target).view(tensor.shape).copy_(tensor, non_blocking=cuda)
            small = producer.to_host(count, instances, boxes, pixels, images=False)  # syncs the stream
            written.put((block, _submit_parts(pool, block, chunk, logs, small, sizes, out, config.writer,
                                              writer.fsync_files)))
    finally:
        written.put(None)  # the batches submitted are written and their records kept, whatever happened
        settler.join()
        writer.flush()
        for block in blocks:
            block.close()
    if failed:
        raise failed[0]
    return producer.gl_renderer


_NUMPY = {torch.int16: np.int16, torch.uint8: np.uint8, torch.float32: np.float32}
"""The NumPy view of a block's bytes that a device tensor is copied into (the same bits)."""


def _submit_parts(pool, block: SharedBatch, chunk, logs, small: dict, sizes, out, writer_cfg,
                  fsync_files: bool) -> list:
    """The batch's frames in one contiguous part per process, each written there (``_write_part``)."""
    count = len(chunk)
    size = -(-count // pool.workers)
    ends = np.cumsum(sizes) if sizes is not None else None
    futures = []
    for start in range(0, count, size):
        stop = min(count, start + size)
        part_small = {name: array[start:stop] for name, array in small.items()}
        jpeg_spans = None if ends is None else [(int(ends[w] - sizes[w]), int(ends[w])) for w in range(start, stop)]
        futures.append(pool.submit_call(_write_part, block.spec, start, chunk[start:stop], logs[start:stop],
                                        part_small, jpeg_spans, os.fspath(out), pickle.dumps(writer_cfg),
                                        fsync_files))
    return futures


# -- in the draw processes ----------------------------------------------------------------------

_blocks: dict[str, tuple] = {}


def _attach(spec) -> dict:
    """The arrays of a batch block (mapped once per process; the mappings of earlier runs' blocks,
    whose files are gone, are dropped)."""
    path, layout, offsets = spec
    hit = _blocks.get(path)
    if hit is None:
        for old in [p for p in _blocks if not os.path.exists(p)]:
            mapping, arrays = _blocks.pop(old)
            arrays.clear()
            with contextlib.suppress(BufferError):
                mapping.close()
        with open(path, "r+b") as f:
            mapping = mmap.mmap(f.fileno(), 0)
        hit = _blocks[path] = (mapping, _arrays(mapping, layout, offsets))
    return hit[1]


def _frame_context() -> tuple:
    """(camera cfg at the dataset's size, its K, table, model, annotators) of this process's config."""
    ctx = draw_pool._worker.get("frame_context")
    if ctx is None:
        producer = draw_pool._producer()  # the scene at 8x8: the model and the instance table
        config = pickle.loads(draw_pool._worker["payload"])
        cfg = tiled_camera_cfg(config.camera)
        ctx = draw_pool._worker["frame_context"] = (cfg, cfg.intrinsics_matrix(), producer.table, producer.model,
                                                     set(config.camera.annotators))
    return ctx


def _write_part(spec, start: int, indices: list[int], logs: list[dict], small: dict, jpeg_spans, out: str,
                writer_payload: bytes, fsync_files: bool) -> list[tuple[int, dict]]:
    """Write frames ``indices`` (worlds ``start``... of the block ``spec``); returns their records."""
    arrays = _attach(spec)
    cfg, k_matrix, table, model, annotators = _frame_context()
    writer_cfg = pickle.loads(writer_payload)
    records = []
    part = slice(start, start + len(indices))
    host = {**small, **{name: arrays[name][part] for name in ("instances", "semantic", "depth") if name in arrays}}
    if jpeg_spans is None:
        host["rgb"] = arrays["rgb"][part]
    for i, (index, log) in enumerate(zip(indices, logs)):
        capture = frame_capture(i, host, k_matrix, cfg, table, model, annotators)
        if jpeg_spans is None:
            record = write_frame_files(Path(out), index, capture, table, log, writer_cfg, fsync_files)
        else:
            lo, hi = jpeg_spans[i]
            record = write_frame_files(Path(out), index, capture, table, log, writer_cfg, fsync_files,
                                       rgb_jpeg=arrays["jpeg_bytes"][lo:hi], depth_mm_u16=arrays["depth_mm"][start + i])
        records.append((index, record))
    return records


__all__ = ["SUPPORTED_OUTPUTS", "SharedBatch", "batch_layout", "run_batched_frames", "supports"]
