"""The GPU path's disk mode: a batch's pixels prepared on the device, its files written on every core.

``run_frames`` with writer threads (the batched path's first disk mode) leaves a frame's host
work (loose and 3D boxes, COCO RLE, the PNG encodes, the record) to threads of the producer's
process, and much of it holds the GIL. ``run_batched_frames`` does the per-pixel conversions on
the device for all worlds at once (``encode``: the RGB images as JPEG through nvjpeg with
``image_format='jpg'``, the depth as uint16 mm, the ids as 16 bits) and moves the rest to the draw
processes (``draw_pool.DrawPool``, which already hold the scene): each batch's images are copied
once into a memory-mapped block (``SharedBatch``, page-locked for the GPU's copy where CUDA allows;
two per producer, kept between runs: ``shared_blocks``), holding only what the dataset's writers
read (``batch_layout``), and each process writes a contiguous part of the batch's frames from
there (``writers.write_frame_files``) and hands back their records. The COCO masks' run lengths
of the whole batch are found on the device too (``device_rle``); a process only compresses them.
``commits.BatchCommits`` frees a batch's block as soon as its files are written and writes its
records after one flush of the files (a flush per group of batches, off the render's path), so a
record on disk still always points to data on disk. The device renders batch i+1 while the
processes write batch i, and the host applies batch i+1's draws while the device renders batch i;
with JPEG, a thread of its own encodes batch i while batch i+1 renders (``jpeg_stage``: three
blocks then); a share of each batch's frames (``cpu_jpeg_share``, by frame index: ``cpu_jpeg``) is
copied raw instead and encoded on the processes (libjpeg-turbo), at the same time as nvjpeg encodes
the rest. The processes also make each frame's COCO piece (``coco_file``), so the dataset's
``annotations.json`` is a concatenation at the end rather than a pass over every record.

The files are the ``run_frames`` path's, byte for byte, with PNG RGB (tested); with JPEG the RGB
file is ``rgb/NNNNNN.jpg`` and the record's ``file_name`` says so (``writers.write_frame_files`` with
``rgb_jpeg``; the frames of the CPU's share decode to the same picture, not the same bytes, as
nvjpeg's would). Writers supported: coco, depth (png16), masks, kitti; others (raw, npy depth) take
``run_frames``. ``STAGES`` says where a run's time went.
"""

from __future__ import annotations

import collections
import contextlib
import functools
import math
import mmap
import os
import pickle
import queue
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
import torch

from . import draw_pool
from .batched import BatchedFrameProducer, _split, frame_capture, tiled_camera_cfg
from .coco_file import frame_piece
from .commits import BatchCommits
from .cpu_jpeg import DEFAULT_CPU_JPEG_SHARE, cpu_worlds, encode_jpeg_cpu, share_fraction
from .device_rle import frame_rles, rle_counts
from .encode import IMAGE_FORMATS, as_u16_bits, depth_mm, encode_jpegs
from .jpeg_stage import JpegStage
from .writers import EncodedRecord, FrameWriter, encode_record, write_frame_files

SUPPORTED_OUTPUTS = {"coco", "depth", "masks", "kitti"}


def supports(writer_cfg) -> bool:
    """Whether ``run_batched_frames`` writes this writer config (else ``run_frames`` does)."""
    return set(writer_cfg.outputs) <= SUPPORTED_OUTPUTS and writer_cfg.depth_format == "png16"


class SharedBatch:
    """One batch's images in a memory-mapped file that the writer processes map too: named NumPy
    arrays over it, page-locked for CUDA copies when the driver agrees (else the copies go through
    pageable memory). The file lives in ``/dev/shm`` when that has room for it (a container's is
    often 64 MB), else in the temporary folder (the page cache holds it)."""

    def __init__(self, layout: dict[str, tuple[tuple[int, ...], str]], pin: bool, folder: str | None | bool = True):
        self.layout = layout
        self.offsets, self.size = _offsets(layout)
        folder = _block_dir(self.size) if folder is True else folder
        fd, self.path = tempfile.mkstemp(prefix="ambulo-batch-", dir=folder)
        try:
            os.ftruncate(fd, self.size)
            self._map = mmap.mmap(fd, self.size)
        finally:
            os.close(fd)
        self.arrays = _arrays(self._map, layout, self.offsets)
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


def _offsets(layout: dict) -> tuple[dict[str, int], int]:
    """Each array's byte offset in a block of ``layout`` (64-byte aligned), and the block's size."""
    offsets, size = {}, 0
    for name, (shape, dtype) in layout.items():
        offsets[name] = size
        size += -(-int(np.prod(shape)) * np.dtype(dtype).itemsize // 64) * 64
    return offsets, max(size, 64)


def _block_dir(size: int, blocks: int = 2) -> str | None:
    """``/dev/shm`` when it has room for ``blocks`` blocks and one to spare, else the temporary folder."""
    try:
        stat = os.statvfs("/dev/shm")
    except OSError:
        return None
    return "/dev/shm" if stat.f_bavail * stat.f_frsize > (blocks + 1) * size else None


def _arrays(buffer, layout: dict, offsets: dict) -> dict:
    return {name: np.ndarray(shape, dtype, buffer=buffer, offset=offsets[name]) for name, (shape, dtype) in layout.items()}


def batch_layout(num_worlds: int, height: int, width: int, jpeg: bool, semantic: bool = True,
                 depth: bool = True, instances: bool = True, cpu_rgb: int = 0) -> dict:
    """The arrays a batch's block holds: the instance ids (16 bits) when the dataset writes their
    PNGs (``instances``: its ``masks``; the COCO masks come from the device's run lengths,
    ``device_rle``), the depth in uint16 mm (converted on the device, ``encode.depth_mm``: half the
    float's bytes to copy and no host conversion) when it writes ``depth``, the semantic ids when
    its masks include them (``semantic``), and the RGB images, raw or as the batch's JPEG files end
    to end (``jpeg_bytes``, with their offsets), and with JPEG the raw RGB images of up to ``cpu_rgb``
    frames that the processes encode (``rgb_cpu``: the CPU's share, ``cpu_jpeg``; sized for the
    share, not the batch). Nothing a writer does not read is copied: the headline dataset (RGB and
    COCO) copies its JPEG files and the CPU share's pixels alone."""
    image = (num_worlds, height, width)
    layout = {"instances": (image, "<u2")} if instances else {}
    if depth:
        layout["depth_mm"] = (image, "<u2")
    if semantic:
        layout["semantic"] = (image, "<u2")
    if jpeg:  # a JPEG larger than its raw pixels does not occur at the quality used
        layout["jpeg_bytes"] = ((num_worlds * height * width * 3,), "u1")
        if cpu_rgb:
            layout["rgb_cpu"] = ((cpu_rgb, height, width, 3), "u1")
    else:
        layout["rgb"] = ((*image, 3), "u1")
    return layout


STAGES = ("render_s", "draws_s", "jpeg_s", "rle_s", "wait_block_s", "copy_s", "submit_s", "jpeg_encode_s",
          "wait_writes_s", "commit_s", "part_capture_s", "part_write_s")
"""What ``run_batched_frames(stats=...)`` adds up, in seconds: on the main thread the upload of the
batch's draws and the launches of its render and conversions (``render_s``: host time, the device
works on), the next batch's draws collected and applied to the host copies meanwhile
(``draws_s``: includes waiting for the draw processes), the copy of the RGB images for the JPEG
thread (``jpeg_s``), the COCO masks' run lengths found on the device and copied (``rle_s``: it
waits for the render), waiting for a free block (``wait_block_s``: the processes or the JPEG
thread are behind), the copy into it (the CPU share's raw RGB too) and the boxes' and poses' to
the host (``copy_s``), handing out the parts (``submit_s``); on the JPEG thread its encode and copy
into the block (``jpeg_encode_s``: ``jpeg_stage``); on the settle thread waiting for the processes
(``wait_writes_s``); on the commit thread the file system's flushes and the records' writes
(``commit_s``); and summed over the processes, the captures (loose and 3D boxes) and the files'
encode (the CPU share's JPEGs included) and write with the COCO annotations, the record's JSON and
the frame's COCO piece (``part_capture_s``, ``part_write_s``): CPU seconds, to divide by the processes."""


def run_batched_frames(config, out: Path, seed: int, frames: list[int], producer: BatchedFrameProducer,
                       progress=None, image_format: str = "png", stats: dict | None = None,
                       pieces: dict | None = None, cpu_jpeg_share=DEFAULT_CPU_JPEG_SHARE) -> str:
    """Render and write ``frames`` (see the module docstring); returns the renderer's name.
    ``producer.draws`` (a ``DrawPool`` of this config) draws the scenes and writes the files.
    ``stats``: a dict that gets each of ``STAGES``' seconds added (and ``commits``, the flushes).
    ``pieces``: a dict that gets each committed frame's COCO piece (``coco_file.FramePiece``, made
    on the processes with its record), for ``coco_file.write_annotations``. ``cpu_jpeg_share`` (0 to
    1, JPEG only): the share of the frames, by index, whose JPEG the processes encode instead of
    nvjpeg (``cpu_jpeg``; 0: none)."""
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
    share = share_fraction(cpu_jpeg_share) if jpeg else share_fraction(0)
    # the block's rgb_cpu rows: the most CPU frames any num_worlds consecutive frames hold (the same
    # layout, so the same kept blocks, from one run to the next), or more where a resumed run's
    # sparse frames put more of a batch there
    cpu_rgb = max([math.ceil(producer.num_worlds * share)] +
                  [len(cpu_worlds(chunk, share)) for chunk in _split(frames, producer.num_worlds)])
    cfg = producer.camera.cfg
    cuda = producer.engine.device.type == "cuda"
    # records are held until a commit's flush: the commit thread flushes explicitly
    writer = FrameWriter(out, config.writer, batch=sys.maxsize)
    semantic = "semantic_segmentation" in config.camera.annotators and "masks" in config.writer.outputs
    layout = batch_layout(producer.num_worlds, cfg.height, cfg.width, jpeg, semantic,
                          depth="depth" in config.writer.outputs, instances="masks" in config.writer.outputs,
                          cpu_rgb=cpu_rgb)
    blocks = shared_blocks(producer, layout, pin=cuda, count=3 if jpeg else 2)
    free: queue.Queue = queue.Queue()
    for block in blocks:
        free.put(block)
    commits = BatchCommits(writer, free, progress, pieces)
    times = commits.times
    # the JPEG encode a batch behind, on its own thread (and the render on its own stream)
    stage = JpegStage(producer.engine.device, encode_jpegs) if jpeg else None
    chunks = producer._chunks(seed, frames)  # each chunk's draws submitted one chunk ahead
    try:
        with stage.rendering() if stage is not None else contextlib.nullcontext():
            _render_batches(producer, seed, chunks, layout, semantic, stage, free, commits, pool, out, config.writer,
                            writer.fsync_files, share)
    finally:
        if stage is not None:  # every batch handed to the stage is encoded and submitted (or its block freed)
            stage.close()
            times["jpeg_encode_s"] += stage.encode_s
        commits.close()  # the batches submitted are written and their records committed, whatever happened
        if stats is not None:
            for name, seconds in times.items():
                stats[name] = stats.get(name, 0) + seconds
    for failed in (commits.failed, stage.failed if stage is not None else []):
        if failed:
            raise failed[0]
    return producer.gl_renderer


def _render_batches(producer, seed: int, chunks, layout: dict, semantic: bool, stage: JpegStage | None,
                    free: queue.Queue, commits: BatchCommits, pool, out: Path, writer_cfg, fsync_files: bool,
                    share=0) -> None:
    """``run_batched_frames``' loop on the render's thread: each batch rendered, converted, copied
    into a free block and handed to the processes (through ``stage``, which encodes its JPEGs first,
    but for the frames of the CPU's ``share``: their raw RGB goes into the block)."""
    cuda = producer.engine.device.type == "cuda"
    times = commits.times
    ahead = next(chunks, None)
    ahead_logs = None if ahead is None else producer.draw_on_host(seed, *ahead)
    while ahead is not None:
        start = time.perf_counter()
        chunk, logs, count = ahead[0], ahead_logs, len(ahead[0])
        producer.upload_draws(count)  # queued behind the last batch's copies: its images are read
        producer.render()
        instances, boxes, pixels = producer.labels(count)
        images = producer.camera.data.output
        device = {"instances": as_u16_bits(instances)} if "instances" in layout else {}
        if "depth_mm" in layout:
            device["depth_mm"] = depth_mm(images["depth"][:count, ..., 0])
        if semantic:
            device["semantic"] = as_u16_bits(images["semantic_segmentation"][:count, ..., 0])
        mark = _lap(times, "render_s", start)
        # the next chunk's draws applied to the host copies while the device renders this one
        ahead = next(chunks, None)
        if ahead is not None:
            ahead_logs = producer.draw_on_host(seed, *ahead)
        mark = _lap(times, "draws_s", mark)
        cpu = cpu_worlds(chunk, share) if stage is not None else []
        if stage is not None:  # copied before the next render overwrites the camera's images
            rgb = images["rgb"][:count]
            if cpu:  # (n, H, W, 3) gathers: the CPU's frames raw into the block, the others to nvjpeg
                gpu = sorted(set(range(count)) - set(cpu))
                device["rgb_cpu"] = rgb[_world_index(cpu, rgb.device)]
                rgb = rgb[_world_index(gpu, rgb.device)]
            taken = stage.take(rgb)
        else:
            device["rgb"] = images["rgb"][:count]
        mark = _lap(times, "jpeg_s", mark)
        # the COCO masks' run lengths of every frame (one sync; the host compresses its frames')
        rle = tuple(t.cpu().numpy() for t in rle_counts(instances, producer.table.num_instances))
        mark = _lap(times, "rle_s", mark)
        block = _free_block(free, commits, stage)  # the batch before last has been written
        mark = _lap(times, "wait_block_s", mark)
        for name, tensor in device.items():
            target = block.arrays[name].reshape(-1)[:tensor.numel()].view(_NUMPY[tensor.dtype])
            torch.from_numpy(target).view(tensor.shape).copy_(tensor, non_blocking=cuda)
        small = producer.to_host(count, instances, boxes, pixels, images=False)  # syncs the stream
        mark = _lap(times, "copy_s", mark)
        submit = functools.partial(_submit_parts, pool, block, chunk, logs, small, rle=rle, out=out,
                                   writer_cfg=writer_cfg, fsync_files=fsync_files, cpu=cpu)
        if stage is None:
            commits.put(block, submit(None))
        else:
            jpeg_bytes = block.arrays["jpeg_bytes"]
            stage.put(taken, lambda size, a=jpeg_bytes: a[:size],
                      then=lambda sizes, block=block, submit=submit: commits.put(block, submit(sizes)),
                      drop=functools.partial(free.put, block))
        _lap(times, "submit_s", mark)


def _world_index(worlds: list[int], device: torch.device) -> torch.Tensor:
    """(n,) int64 ``worlds`` on ``device``; to CUDA from page-locked memory, so the upload does not
    wait for the render queued before it (a pageable one syncs the stream)."""
    index = torch.as_tensor(worlds, dtype=torch.int64)
    if device.type != "cuda":
        return index
    return index.pin_memory().to(device, non_blocking=True)


def _free_block(free: queue.Queue, commits: BatchCommits, stage: JpegStage | None) -> SharedBatch:
    """The next free block; raises the first error of the commits or the JPEG thread instead (a
    batch whose hand-over failed there may never give its block back: the wait checks again)."""
    while True:
        for failed in (commits.failed, stage.failed if stage is not None else []):
            if failed:
                raise failed[0]
        try:
            return free.get(timeout=0.5)
        except queue.Empty:
            continue


def _lap(times: collections.Counter, name: str, start: float) -> float:
    """Add the seconds since ``start`` to ``times[name]``; returns now. No device sync is added: a
    stage's time is its host time and what it waited for (an encode waits for the render)."""
    now = time.perf_counter()
    times[name] += now - start
    return now


_NUMPY = {torch.int16: np.int16, torch.uint8: np.uint8, torch.float32: np.float32}
"""The NumPy view of a block's bytes that a device tensor is copied into (the same bits)."""


def shared_blocks(producer: BatchedFrameProducer, layout: dict, pin: bool, count: int = 2) -> list[SharedBatch]:
    """``count`` blocks of ``layout`` for ``producer``'s batches (all in one folder), kept on the
    producer from one run to the next (``producer.disk_blocks``; closed with it): making and
    page-locking blocks of a few hundred MB costs more than a thousand frames' copies, and a run
    may be a few batches. Two let the processes write one batch while the next is copied; the JPEG
    mode asks for three (one more is being encoded: ``jpeg_stage``), and gets two where only two fit
    in ``/dev/shm`` (page-locked copies matter more than the third)."""
    held = producer.disk_blocks
    if held is not None and held[0] == (layout, pin, count):
        return held[1]
    producer.close_disk_blocks()
    size, made = _offsets(layout)[1], count
    folder = _block_dir(size, count)
    if folder is None and count > 2 and _block_dir(size, 2) is not None:
        folder, made = _block_dir(size, 2), 2
    blocks = [SharedBatch(layout, pin=pin, folder=folder) for _ in range(made)]
    producer.disk_blocks = ((layout, pin, count), blocks)
    return blocks


def _submit_parts(pool, block: SharedBatch, chunk, logs, small: dict, sizes, *, rle: tuple, out, writer_cfg,
                  fsync_files: bool, cpu: list[int] = ()) -> list:
    """The batch's frames in one contiguous part per process, each written there (``_write_part``).
    ``sizes``: the JPEG files' bytes of the worlds not in ``cpu`` (in world order), end to end in the
    block's ``jpeg_bytes``; the worlds in ``cpu`` are rows of its ``rgb_cpu``, in that order."""
    count = len(chunk)
    size = -(-count // pool.workers)
    spans = None
    if sizes is not None:  # each world's (start, stop) in jpeg_bytes, or its rgb_cpu row (an int)
        spans, rows, ends = [], {w: row for row, w in enumerate(cpu)}, np.cumsum(sizes)
        gpu = 0
        for w in range(count):
            if w in rows:
                spans.append(rows[w])
            else:
                spans.append((int(ends[gpu] - sizes[gpu]), int(ends[gpu])))
                gpu += 1
    counts, offsets, lengths = rle
    per_image = len(offsets) // count  # instances
    futures = []
    for start in range(0, count, size):
        stop = min(count, start + size)
        part_small = {name: array[start:stop] for name, array in small.items()}
        jpeg_spans = None if spans is None else spans[start:stop]
        first, last = start * per_image, stop * per_image  # the part's images' groups, contiguous
        lo, hi = int(offsets[first]), int(offsets[last - 1] + lengths[last - 1])
        part_rle = (counts[lo:hi], offsets[first:last] - lo, lengths[first:last])
        futures.append(pool.submit_call(_write_part, block.spec, start, chunk[start:stop], logs[start:stop],
                                        part_small, jpeg_spans, part_rle, os.fspath(out), writer_cfg, fsync_files))
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


def _write_part(spec, start: int, indices: list[int], logs: list[dict], small: dict, jpeg_spans, rle: tuple,
                out: str, writer_cfg, fsync_files: bool) -> tuple[list[tuple[int, EncodedRecord]], dict, dict]:
    """Write frames ``indices`` (worlds ``start``... of the block ``spec``); returns their records
    (encoded here: the main process only writes them), this part's seconds of captures and of
    file writing (``STAGES``), and the frames' COCO pieces (``coco_file.frame_piece``: the
    annotations file's parts made here, in parallel, rather than from the records at the end;
    a frame whose piece can't be made is read from its record then). Each capture carries
    ``coco_rles``: its masks' RLEs from the device's run lengths (``device_rle.frame_rles``, the
    bytes of ``coco.instance_rles``), for ``coco.frame_annotations`` to take instead of finding
    the runs again on the host. ``jpeg_spans`` (JPEG): per frame its file's (start, stop) in the
    block's ``jpeg_bytes``, or its row of ``rgb_cpu`` to encode here (``cpu_jpeg``)."""
    arrays = _attach(spec)
    cfg, k_matrix, table, model, annotators = _frame_context()
    records, pieces = [], {}
    part = slice(start, start + len(indices))
    host = {**small, **{name: arrays[name][part] for name in ("instances", "semantic", "rgb") if name in arrays}}
    depth = arrays.get("depth_mm")
    capture_s = write_s = 0.0
    for i, (index, log) in enumerate(zip(indices, logs)):
        begin = time.perf_counter()
        capture = frame_capture(i, host, k_matrix, cfg, table, model, annotators)
        capture["coco_rles"] = functools.partial(frame_rles, *rle, i, table.num_instances, height=cfg.height,
                                                 width=cfg.width)
        middle = time.perf_counter()
        rgb_jpeg = None
        if jpeg_spans is not None:
            span = jpeg_spans[i]
            if isinstance(span, int):  # the CPU's share: encoded here, on this process's core
                rgb_jpeg = encode_jpeg_cpu(arrays["rgb_cpu"][span])
            else:
                rgb_jpeg = arrays["jpeg_bytes"][span[0]:span[1]]
        record = write_frame_files(Path(out), index, capture, table, log, writer_cfg, fsync_files, rgb_jpeg=rgb_jpeg,
                                   depth_mm_u16=None if depth is None else depth[start + i])
        records.append((index, encode_record(record)))
        piece = frame_piece(index, record)
        if piece is not None:
            pieces[index] = piece
        end = time.perf_counter()
        capture_s += middle - begin
        write_s += end - middle
    return records, {"part_capture_s": capture_s, "part_write_s": write_s}, pieces


__all__ = ["STAGES", "SUPPORTED_OUTPUTS", "SharedBatch", "batch_layout", "run_batched_frames", "shared_blocks", "supports"]
