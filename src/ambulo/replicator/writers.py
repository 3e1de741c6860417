"""Per-frame dataset writers: PNG rgb, depth, masks, KITTI labels, raw arrays, and the frame record.

A ``FrameWriter`` runs on the generator's writer thread. A frame's record lists every file of the
frame with its size in bytes and is written last, as one line appended to the writer process's
journal ``frames/records-<host>-<pid>.jsonl`` (``records``): a resumed run counts a frame as done
only when its record parses and each file has that size (``records.complete_records``), so a
truncated image or a torn record is made again. With ``WriterCfg.fsync`` the data files and their
folders reach the disk before the record is appended, and the journal is flushed after it: after a
power loss a record never points to data that is not there.

The record is what makes a frame's files count, so they are written in place (``write_file``), not
as a temporary renamed onto the name: a resumed run drops every record that does not count before
it writes frames again (``records.prune_records``), and a record appears only after the frame's
files (and, with ``fsync``, after they reach the disk). A write cut short leaves a frame without a
record, which a resumed run makes again over the partial files; a torn record (a line without its
newline, or a strict prefix of a JSON object) never counts. The rename of every file cost ~0.09 ms
of CPU each, four a frame, ~3 % of an annotated frame at 320x240; a file per record was a fourth
create a frame (0.47-0.51 ms each on the 2-core VM's aged ext4), which the journal saves.

Layout of a dataset folder::

    rgb/000000.png          uint8 RGB
    depth/000000.png        uint16 depth to the image plane in mm (0 = none), or depth/000000.npy float32 m
    instance/000000.png     uint16 instance ids (0 = background; see the record's prim paths)
    semantic/000000.png     uint16 category ids (COCO category ids, 0 = background), only when the
                            camera's annotators include semantic_segmentation (``semantic_image``
                            gives it from the instance image and ``dataset.json`` otherwise)
    kitti/000000.txt        KITTI object labels (type, truncation, occlusion, 2D and 3D box)
    raw/000000_<name>.npy   float/int arrays of every annotator
    frames/records-<host>-<pid>.jsonl
                            records, one line a frame, of the frames that process wrote: COCO image +
                            annotations, camera K/extrinsics, randomizer log, files and their sizes
                            (compact JSON: ``json_bytes``; ``records.read_records`` reads them all)
    annotations.json        COCO instances file (merged at the end)
    metadata.json           GL renderer, versions, seed, categories
    dataset.json            what the frames were made with (``manifest.py``), written first
"""

from __future__ import annotations

import json
import math
import os
import re
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ambulo.utils.atomic import can_sync_filesystem, fsync_dir, sync_filesystem
from ambulo.utils.validate import Checked

from .coco import frame_annotations
from .io import encode_depth_png, encode_ids_png, encode_png
from .records import append_records, complete_records

try:  # a dependency of viser (core) and of the data extra; the standard library's json without it
    from msgspec.json import encode as _msgspec_encode
except ImportError:
    _msgspec_encode = None

WRITERS = ("coco", "depth", "masks", "kitti", "raw")
PNG_ROW_FILTERS = {"rgb": "none", "depth": "sub", "instance": "none", "semantic": "none"}
"""``io.encode_png``'s row filter for each image folder: the smallest files for the least time on
rendered frames (flat-shaded colours and ids: none; depth, smooth along rows: sub)."""


@dataclass(kw_only=True)
class WriterCfg(Checked):
    outputs: tuple[str, ...] = ("coco", "depth", "masks")
    """Any of ``WRITERS``; 'coco' (rgb PNG + records + annotations.json) is always on."""
    depth_format: str = "png16"
    """'png16' (uint16 mm) or 'npy' (float32 m)."""
    png_compress_level: int = 1
    """zlib level 0-9: 1 is ~5x faster than the default 6 for ~15% larger files. With ISA-L
    installed (``isal``) 1-3, 4-6 and 7-9 become its levels 1, 2 and 3 (``io.deflate``)."""
    min_visible_pixels: int = 10
    """Objects with fewer visible pixels get no annotation (they are noise to a detector)."""
    fsync: bool = True
    """Flush each frame's files and folders to disk before its record is appended, and the journal
    after (survives a power loss); it changes no file's bytes. Measured cost: see ``FrameWriter``."""


def default_writer_cfg() -> WriterCfg:
    return WriterCfg()


def frame_stem(index: int) -> str:
    return f"{index:06d}"


SUBDIRS = ("rgb", "depth", "instance", "semantic", "kitti", "raw", "frames")
"""Every folder a dataset may have; ``frame_subdirs`` says which ones a writer config uses."""
FRAME_FILE = re.compile(r"\d{6,}(_[a-z_]+)?\.(png|jpg|npy|txt|json)|records-[A-Za-z0-9._-]+\.jsonl")
"""The whole name of every file ``write_frame`` makes (``000012.png``, ``000012_depth.npy``, the journals
``records-<host>-<pid>.jsonl``; ``000012.json``: a record of a dataset made before the journals)."""


def frame_subdirs(cfg: WriterCfg, annotators=None) -> list[str]:
    """The folders of a dataset written with ``cfg``, in ``SUBDIRS`` order. ``annotators``: the
    camera's; "masks" writes ``semantic/`` only with semantic_segmentation among them (None: with it)."""
    used = {"rgb", "frames"}
    used |= {"depth"} if "depth" in cfg.outputs else set()
    if "masks" in cfg.outputs:
        used |= {"instance"}
        used |= {"semantic"} if annotators is None or "semantic_segmentation" in annotators else set()
    used |= {"kitti"} if "kitti" in cfg.outputs else set()
    used |= {"raw"} if "raw" in cfg.outputs else set()
    return [sub for sub in SUBDIRS if sub in used]


def check_writer_cfg(cfg: WriterCfg) -> None:
    unknown = set(cfg.outputs) - set(WRITERS)
    if unknown:
        raise ValueError(f"unknown writer(s) {sorted(unknown)}; choose from {WRITERS}")
    if cfg.depth_format not in ("png16", "npy"):
        raise ValueError(f"depth_format must be 'png16' or 'npy', got {cfg.depth_format!r}")


def prepare_dirs(out: Path, cfg: WriterCfg, annotators=None) -> None:
    check_writer_cfg(cfg)
    for sub in frame_subdirs(cfg, annotators):
        (out / sub).mkdir(parents=True, exist_ok=True)


@dataclass(frozen=True, slots=True)
class EncodedRecord:
    """A frame record as the bytes ``FrameWriter.flush`` writes (``json_bytes``), and the folders of
    its files (what a flush without ``syncfs`` flushes)."""

    data: bytes
    folders: tuple[str, ...]


def record_folders(record: dict) -> tuple[str, ...]:
    """The dataset folders that hold the files ``record`` lists."""
    return tuple(sorted({relpath.split("/")[0] for relpath in record["files"]}))


def encode_record(record: dict) -> EncodedRecord:
    return EncodedRecord(json_bytes(record), record_folders(record))


class FrameWriter:
    """Writes frames' files into dataset ``out``, and their records in batches.

    Used from one thread (the generator's writer thread). ``write`` writes a frame's data
    files and holds its record back; every ``batch`` frames, and on ``flush``, the data
    written since the last batch is flushed to disk (``cfg.fsync``) and then the records
    are written. So a record on disk always points to data on disk. On Linux the flush is
    one ``syncfs`` of the dataset's file system per batch (``sync_filesystem``); elsewhere
    each data file is flushed before it is closed and each folder once per batch. One
    ``syncfs`` for 8 frames costs a tenth of the wait and a quarter of the CPU of 32
    file flushes (``benchmarks/results/cpu-2026-11-28-replicator.md``); an fdatasync of each
    of the batch's 40 files (and one fsync per folder) was measured again against it on ext4:
    10x the CPU (4-14 ms a batch, up to 1.8 ms a frame) and 5-20x the wait, each file's flush
    committing the journal on its own (``cpu-2026-11-28-replicator-producer.md``). What
    ``syncfs`` costs instead: it also flushes other processes' dirty data on that file system,
    so a neighbour writing gigabytes can hold this writer thread (and, four frames later,
    rendering) until the disk catches up; ``WriterCfg.fsync=False`` avoids it. The batch's records
    are then appended to the journal in one write, and the journal flushed (one ``fsync`` a batch):
    a record lost or torn by a crash before that fails ``frame_is_complete`` and its frame is made
    again. What it costs a whole ``generate`` call: ``benchmarks/generate_fsync.py``
    (the writer thread overlaps the flushes with rendering).
    """

    def __init__(self, out: Path, cfg: WriterCfg, batch: int = 8):
        self.out, self.cfg, self.batch = Path(out), cfg, batch
        self._records: list[tuple[int, dict]] = []
        self._folders: set[str] = set()
        self._syncfs = cfg.fsync and can_sync_filesystem()
        """One flush of the whole file system per batch rather than one per file."""

    @property
    def fsync_files(self) -> bool:
        """Whether each data file is flushed before it is closed (no ``syncfs`` per batch)."""
        return self.cfg.fsync and not self._syncfs

    def write(self, index: int, capture: dict, table, log: dict) -> None:
        self.add(index, write_frame_files(self.out, index, capture, table, log, self.cfg,
                                          fsync_files=self.fsync_files))

    def add(self, index: int, record: dict | EncodedRecord) -> None:
        """Hold back the record of frame ``index``, whose files ``write_frame_files`` wrote (on any
        thread), until the next batch flush; ``record`` as a dict or already encoded
        (``encode_record``: on the process that wrote the files, off this one's GIL)."""
        self._records.append((index, record))
        folders = record.folders if isinstance(record, EncodedRecord) else record_folders(record)
        self._folders.update(folders)
        if len(self._records) >= self.batch:
            self.flush()

    def flush(self) -> None:
        """Write the records held back (after flushing their files and folders)."""
        if self._syncfs and self._records:
            sync_filesystem(self.out)
        elif self.cfg.fsync:
            for folder in sorted(self._folders):
                fsync_dir(self.out / folder)
        lines = [record.data if isinstance(record, EncodedRecord) else json_bytes(record)
                 for _, record in self._records]
        append_records(os.path.join(os.fspath(self.out), "frames"), lines, fsync=self.cfg.fsync)
        self._records.clear()
        self._folders.clear()


def json_bytes(value) -> bytes:
    """``value`` (a frame record, the COCO file) as compact JSON (UTF-8): msgspec's encoder, a tenth of
    the standard library's time (its floats' shortest round-trip digits take most of it: 36 vs 372 us
    a record), and the same values read back. msgspec writes NaN and infinities as ``null``, which
    json writes as NaN and Infinity; anything with a ``null`` (or that msgspec refuses) is written by
    json instead."""
    if _msgspec_encode is not None:
        try:
            data = _msgspec_encode(value)
        except (TypeError, ValueError, OverflowError):
            data = None
        if data is not None and b"null" not in data:
            return data
    return json.dumps(value, separators=(",", ":")).encode()


def write_file(path: str, data, fsync: bool = False) -> int:
    """Write ``data`` (bytes, any buffer, or an array saved as ``.npy``) to ``path`` in place, replacing
    what was there; returns the file's size in bytes. ``fsync``: flushed to disk before it is closed.
    Not atomic on its own: a frame's record makes its files count (module doc)."""
    fd = os.open(path, os.O_WRONLY | os.O_CREAT | os.O_TRUNC | getattr(os, "O_BINARY", 0), 0o666)
    try:
        if isinstance(data, np.ndarray):
            with open(fd, "wb", closefd=False) as f:
                np.save(f, data)
                size = f.tell()
        else:
            with memoryview(data) as view, view.cast("B") as octets:
                size, done = len(octets), 0
                while done < size:
                    done += os.write(fd, octets[done:])
        if fsync:
            os.fsync(fd)
    finally:
        os.close(fd)
    return size


def write_frame(out: Path, index: int, capture: dict, table, log: dict, cfg: WriterCfg) -> None:
    """Write every file of frame ``index`` and then its record (``FrameWriter`` of one frame)."""
    writer = FrameWriter(out, cfg, batch=1)
    writer.write(index, capture, table, log)


def write_frame_files(out: Path, index: int, capture: dict, table, log: dict, cfg: WriterCfg,
                      fsync_files: bool | None = None, rgb_jpeg: bytes | np.ndarray | None = None,
                      depth_mm_u16: np.ndarray | None = None) -> dict:
    """Write the data files of frame ``index``; returns its record, which lists every file with its
    size in bytes, for the caller to write last. Each file is flushed to disk before it is closed when
    ``fsync_files`` (default: ``cfg.fsync``); ``FrameWriter`` may flush a whole batch at once instead.

    The GPU path hands over what it converted on the device: ``rgb_jpeg``, the colour image's JPEG
    bytes (written as ``rgb/NNNNNN.jpg`` instead of the PNG), and ``depth_mm_u16``, the depth already
    in ``io.depth_to_mm_u16``'s uint16 millimetres (H, W)."""
    fsync = cfg.fsync if fsync_files is None else fsync_files
    stem = frame_stem(index)
    level = cfg.png_compress_level
    files: dict[str, int] = {}
    root = os.fspath(out)
    # a frame made again (its record did not count) has no record while its files are rewritten in
    # place: the run dropped it first (records.prune_records; module doc)

    def put(relpath: str, data) -> None:
        # strings: pathlib costs more than the small files' writes
        files[relpath] = write_file(os.path.join(root, relpath), data, fsync)

    if rgb_jpeg is None:
        rgb_file = f"rgb/{stem}.png"
        put(rgb_file, encode_png(capture["rgb"], level, PNG_ROW_FILTERS["rgb"]))
    else:  # bytes or a uint8 view of the shared block: written as they are, never as .npy
        rgb_file = f"rgb/{stem}.jpg"
        files[rgb_file] = write_file(os.path.join(root, rgb_file),
                                     rgb_jpeg if isinstance(rgb_jpeg, bytes) else memoryview(rgb_jpeg), fsync)
    if "depth" in cfg.outputs:
        if cfg.depth_format == "png16":
            if depth_mm_u16 is None:  # millimetres and "sub" rows in one pass (PNG_ROW_FILTERS)
                put(f"depth/{stem}.png", encode_depth_png(capture["depth"], level))
            else:
                put(f"depth/{stem}.png", encode_png(depth_mm_u16.astype(">u2"), level, PNG_ROW_FILTERS["depth"]))
        else:
            put(f"depth/{stem}.npy", capture["depth"])
    if "masks" in cfg.outputs:
        # straight to PNG's big-endian uint16 rows ("none": PNG_ROW_FILTERS), one pass
        put(f"instance/{stem}.png", encode_ids_png(capture["instance_segmentation"], level))
        if "semantic_segmentation" in capture:  # asked for (the camera's annotators), as Replicator's BasicWriter
            put(f"semantic/{stem}.png", encode_ids_png(capture["semantic_segmentation"], level))
    annotations = frame_annotations(capture, table.semantic_ids, table.names, cfg.min_visible_pixels)
    if "kitti" in cfg.outputs:
        put(f"kitti/{stem}.txt", kitti_lines(annotations, table.categories, capture).encode())
    if "raw" in cfg.outputs:
        for name in ("depth", "instance_segmentation", "semantic_segmentation", "normals", "distance_to_camera"):
            if name in capture:
                put(f"raw/{stem}_{name}.npy", capture[name])
    cam = capture["camera"]
    return {
        "frame": index, "file_name": rgb_file, "width": int(cam["width"]), "height": int(cam["height"]),
        "annotations": annotations,
        "camera": {"intrinsics": cam["intrinsics"].tolist(), "extrinsics_cw": cam["extrinsics_cw"].tolist(),
                   "pos_w": cam["pos_w"].tolist(), "quat_w_opengl": cam["quat_w_opengl"].tolist()},
        "randomization": log,
        "files": files,
    }


def frame_is_complete(out: Path, index: int) -> bool:
    """Whether frame ``index`` of dataset ``out`` is whole: a record of it parses and every file it
    lists exists with the recorded size (``records.complete_records``: it reads every journal; for
    many frames call that once)."""
    return index in complete_records(out)


def kitti_lines(annotations: list[dict], categories: list[str], capture: dict) -> str:
    """KITTI object labels, one line per annotation (camera frame: x right, y down, z forward).

    ``type truncated occluded alpha x1 y1 x2 y2 h w l x y z rotation_y``; the 3D
    box is the object's body-aligned box with its bottom centre as location.
    Truncation is 1 - (tight box area / loose box area) as a proxy for the part
    outside the image; occlusion is KITTI's 0-3 scale from the visible fraction
    when it was computed (else 0).
    """
    lines = []
    for ann in annotations:
        kind = categories[ann["category_id"] - 1].replace(" ", "_")
        x, y, w, h = ann["bbox"]
        x1, y1, x2, y2 = x, y, x + w, y + h
        truncated = 0.0
        if "bbox_loose" in ann:
            lw, lh = ann["bbox_loose"][2], ann["bbox_loose"][3]
            truncated = float(np.clip(1.0 - (w * h) / max(lw * lh, 1e-9), 0.0, 1.0)) if lw * lh > 0 else 0.0
        fraction = ann.get("visible_fraction", 1.0)
        occluded = 0 if fraction > 0.8 else 1 if fraction > 0.4 else 2
        dims, loc, rot_y, alpha = (-1.0, -1.0, -1.0), (-1000.0, -1000.0, -1000.0), -10.0, -10.0
        if "bbox_3d" in ann:
            b = ann["bbox_3d"]
            half, rot_c, center_c = np.array(b["half_extent"]), np.array(b["rot_c"]), np.array(b["center_c"])
            dims = (2 * half[2], 2 * half[1], 2 * half[0])  # h (body z), w (body y), l (body x)
            bottom = center_c - rot_c[:, 2] * half[2]
            loc = tuple(bottom)
            heading = rot_c[:, 0]  # body x axis in the camera frame
            rot_y = math.atan2(-heading[2], heading[0])
            alpha = rot_y - math.atan2(bottom[0], bottom[2])
            alpha = (alpha + math.pi) % (2 * math.pi) - math.pi
        lines.append(
            f"{kind} {truncated:.2f} {occluded:d} {alpha:.2f} {x1:.2f} {y1:.2f} {x2:.2f} {y2:.2f} "
            f"{dims[0]:.2f} {dims[1]:.2f} {dims[2]:.2f} {loc[0]:.2f} {loc[1]:.2f} {loc[2]:.2f} {rot_y:.2f}")
    return "\n".join(lines) + ("\n" if lines else "")
