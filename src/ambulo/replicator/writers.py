"""Per-frame dataset writers: PNG rgb, depth, masks, KITTI labels, raw arrays, and the frame record.

``write_frame`` runs on a writer thread. The frame record ``frames/NNNNNN.json``
is written last: its presence means every file of the frame is complete, which
is what a resumed run checks.

Layout of a dataset folder::

    rgb/000000.png          uint8 RGB
    depth/000000.png        uint16 depth to the image plane in mm (0 = none), or depth/000000.npy float32 m
    instance/000000.png     uint16 instance ids (0 = background; see the record's prim paths)
    semantic/000000.png     uint16 category ids (COCO category ids, 0 = background)
    kitti/000000.txt        KITTI object labels (type, truncation, occlusion, 2D and 3D box)
    raw/000000_<name>.npy   float/int arrays of every annotator
    frames/000000.json      record: COCO image + annotations, camera K/extrinsics, randomizer log
    annotations.json        COCO instances file (merged at the end)
    metadata.json           GL renderer, versions, seed, categories
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ambulo.utils.atomic import atomic_save_npy, atomic_write_bytes, atomic_write_json

from .coco import frame_annotations
from .io import depth_to_mm_u16, encode_png

WRITERS = ("coco", "depth", "masks", "kitti", "raw")


@dataclass(kw_only=True)
class WriterCfg:
    outputs: tuple[str, ...] = ("coco", "depth", "masks")
    """Any of ``WRITERS``; 'coco' (rgb PNG + records + annotations.json) is always on."""
    depth_format: str = "png16"
    """'png16' (uint16 mm) or 'npy' (float32 m)."""
    png_compress_level: int = 1
    """zlib level 0-9: 1 is ~5x faster than the default 6 for ~15% larger files. With ISA-L
    installed (``isal``) 1-3, 4-6 and 7-9 become its levels 1, 2 and 3 (``io.deflate``)."""
    min_visible_pixels: int = 10
    """Objects with fewer visible pixels get no annotation (they are noise to a detector)."""


def default_writer_cfg() -> WriterCfg:
    return WriterCfg()


def frame_stem(index: int) -> str:
    return f"{index:06d}"


def prepare_dirs(out: Path, cfg: WriterCfg) -> None:
    unknown = set(cfg.outputs) - set(WRITERS)
    if unknown:
        raise ValueError(f"unknown writer(s) {sorted(unknown)}; choose from {WRITERS}")
    if cfg.depth_format not in ("png16", "npy"):
        raise ValueError(f"depth_format must be 'png16' or 'npy', got {cfg.depth_format!r}")
    subdirs = {"rgb", "frames"}
    subdirs |= {"depth"} if "depth" in cfg.outputs else set()
    subdirs |= {"instance", "semantic"} if "masks" in cfg.outputs else set()
    subdirs |= {"kitti"} if "kitti" in cfg.outputs else set()
    subdirs |= {"raw"} if "raw" in cfg.outputs else set()
    for sub in subdirs:
        (out / sub).mkdir(parents=True, exist_ok=True)


def write_frame(out: Path, index: int, capture: dict, table, log: dict, cfg: WriterCfg) -> None:
    """Write every output of frame ``index``; the record goes last (completion marker)."""
    stem = frame_stem(index)
    level = cfg.png_compress_level
    atomic_write_bytes(out / "rgb" / f"{stem}.png", encode_png(capture["rgb"], level))
    if "depth" in cfg.outputs:
        if cfg.depth_format == "png16":
            atomic_write_bytes(out / "depth" / f"{stem}.png", encode_png(depth_to_mm_u16(capture["depth"]), level))
        else:
            atomic_save_npy(out / "depth" / f"{stem}.npy", capture["depth"])
    if "masks" in cfg.outputs:
        atomic_write_bytes(out / "instance" / f"{stem}.png",
                           encode_png(capture["instance_segmentation"].astype(np.uint16), level))
        atomic_write_bytes(out / "semantic" / f"{stem}.png",
                           encode_png(capture["semantic_segmentation"].astype(np.uint16), level))
    annotations = frame_annotations(capture, table.semantic_ids, table.names, cfg.min_visible_pixels)
    if "kitti" in cfg.outputs:
        atomic_write_bytes(out / "kitti" / f"{stem}.txt",
                           kitti_lines(annotations, table.categories, capture).encode())
    if "raw" in cfg.outputs:
        for name in ("depth", "instance_segmentation", "semantic_segmentation", "normals", "distance_to_camera"):
            if name in capture:
                atomic_save_npy(out / "raw" / f"{stem}_{name}.npy", capture[name])
    cam = capture["camera"]
    record = {
        "frame": index, "file_name": f"rgb/{stem}.png", "width": int(cam["width"]), "height": int(cam["height"]),
        "annotations": annotations,
        "camera": {"intrinsics": cam["intrinsics"].tolist(), "extrinsics_cw": cam["extrinsics_cw"].tolist(),
                   "pos_w": cam["pos_w"].tolist(), "quat_w_opengl": cam["quat_w_opengl"].tolist()},
        "randomization": log,
    }
    atomic_write_json(out / "frames" / f"{stem}.json", record)


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
