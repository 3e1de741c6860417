"""``annotations.json`` streamed from each frame's COCO piece, the bytes of ``json_bytes(merge_coco(...))``.

``merge_coco`` reads every frame record at the end of a run, builds the whole COCO dict and encodes
it: one serial pass that cost the GPU disk path 0.46 ms a 640x480 frame on the H200, as much as
everything else it does a frame (``benchmarks/results/h200-2026-11-29-session7.md``). A frame's
part of the file depends on that frame alone but for the annotations' ids (a running count over the
frames before it). So each frame's part is encoded where its record is made (``frame_piece``: on the
GPU path's writer processes, in parallel, as the frames are written), and ``write_annotations``
only concatenates: each annotation was encoded without its closing brace, and gets ``"id"`` and
``"image_id"`` appended, the last two keys of ``merge_coco``'s ``{**ann, "id": ..., "image_id": ...}``.
A frame without a piece (made by an earlier, interrupted run, or by the CPU path) gets one from its
record on disk (its journal's line, ``records``: only those lines are decoded). The records stay what a dataset is: a piece is only ever a faster reading of the
record that was written with it, and a resumed run's file is the same whichever run made a frame.

The bytes are ``writers.json_bytes``' (msgspec's compact JSON) for the same dict; where that falls
back to the standard library's json (a NaN, msgspec missing), so does this, through ``merge_coco``.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path

from ambulo.utils.atomic import atomic_open

from .coco import coco_categories, coco_image, merge_coco
from .records import read_json, record_lines
from .writers import json_bytes

try:  # as writers.json_bytes: without msgspec every file is json's, so no piece is made
    from msgspec.json import encode as _encode
except ImportError:
    _encode = None


@dataclass(frozen=True, slots=True)
class FramePiece:
    """One frame's part of ``annotations.json``: ``image``, its image entry's JSON (complete: its id
    is the frame index + 1); ``annotations``, each annotation's JSON object without its closing
    brace (the ids are appended by ``write_annotations``)."""

    image: bytes
    annotations: tuple[bytes, ...]


def frame_piece(index: int, record: dict) -> FramePiece | None:
    """Frame ``index``'s piece, from its record (``writers.write_frame_files``' dict, or the record
    read back: the same bytes). None where ``json_bytes`` would not use msgspec for the whole file
    (a NaN or infinity, which msgspec writes as null; a value it refuses; msgspec missing) or an
    annotation already has an ``id``/``image_id`` key: ``write_annotations`` then merges as before."""
    if _encode is None:
        return None
    try:
        image = _encode(coco_image(index, record))
        annotations = []
        for ann in record["annotations"]:
            if not ann or "id" in ann or "image_id" in ann:
                return None
            annotations.append(_encode(ann)[:-1])
    except (TypeError, ValueError, OverflowError, KeyError):
        return None
    if b"null" in image or any(b"null" in a for a in annotations):
        return None
    return FramePiece(image, tuple(annotations))


def record_piece(frames_dir: Path, index: int, lines: Mapping[int, bytes] | None = None) -> FramePiece | None:
    """Frame ``index``'s piece from its record in ``frames_dir`` (``lines``: ``records.record_lines`` of
    it, read once by the caller); ``FileNotFoundError`` when it has none."""
    lines = record_lines(frames_dir) if lines is None else lines
    if index not in lines:
        raise FileNotFoundError(f"{frames_dir}: no record of frame {index}")
    return frame_piece(index, read_json(lines[index]))


def write_annotations(path: Path, frames_dir: Path, num_frames: int, categories: list[str], info: dict,
                      pieces: Mapping[int, FramePiece] | None = None, fsync: bool = False) -> None:
    """Write the COCO file of frames 0..num_frames-1 to ``path`` (atomically; ``fsync``: flushed
    before the rename): ``json_bytes(merge_coco(frames_dir, ...))``'s bytes. ``pieces``: the frames
    whose pieces this run made with their records; every other frame's comes from its record."""
    pieces = pieces or {}
    head = json_bytes({"info": info, "licenses": [], "categories": coco_categories(categories)})
    ordered = [] if b"null" not in head else None
    # the journals are read (not decoded) only when some frame has no piece
    lines = None if ordered is None or all(i in pieces for i in range(num_frames)) else record_lines(frames_dir)
    for index in range(num_frames if ordered is not None else 0):
        piece = pieces.get(index) or record_piece(frames_dir, index, lines)
        if piece is None:
            ordered = None
            break
        ordered.append(piece)
    with atomic_open(path, fsync=fsync) as f:
        if ordered is None:  # json's bytes for the whole file, as json_bytes decides
            f.write(json_bytes(merge_coco(frames_dir, num_frames, categories, info)))
            return
        f.write(head[:-1] + b',"images":[')
        f.write(b",".join(piece.image for piece in ordered))
        f.write(b'],"annotations":[')
        count = 0
        for image_id, piece in enumerate(ordered, start=1):
            if not piece.annotations:
                continue
            ids = range(count + 1, count + 1 + len(piece.annotations))
            count += len(piece.annotations)
            # the separator before each annotation: none before the file's first
            f.write(b"," if ids[0] > 1 else b"")
            f.write(b",".join(b'%s,"id":%d,"image_id":%d}' % (ann, ann_id, image_id)
                              for ann, ann_id in zip(piece.annotations, ids)))
        f.write(b"]}")


__all__ = ["FramePiece", "frame_piece", "record_piece", "write_annotations"]
