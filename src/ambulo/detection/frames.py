"""Training frames as uint8 tensors, read by worker processes or held whole in the device's memory.

A record is one frame of an ``ambulo generate`` dataset: ``image`` (3, h, w) uint8, ``instances``
(h, w) uint8 (0: no object, k + 1: the frame's k-th annotation), ``boxes`` (M, 4) float32 x0 y0 x1 y1
px and ``classes`` (M,) int64, 0-based; with ``depth``, also ``depth`` (h, w) int16 mm (the
dataset's uint16 mm clipped to 32.767 m, far beyond ``model.DEPTH_MAX_M``: int16 has torch kernels,
uint16 few); with ``height``, also ``height`` (h, w) int16 mm above the floor (``dataset.read_height_m``).
A batch (``pad_collate``) pads every frame to the most boxes
of the batch: boxes (B, M, 4), classes (B, M) with -1 for no box, and ``depths`` / ``heights`` (B, h, w)
int16 mm when the records have them. The augmentations
(``augment.augment_batch``) then run on the whole batch on the training device.

Why one instance map and not a mask per object: one byte a pixel whatever the object count (10,000
frames of 320x240 hold in 0.8 GB beside their 2.3 GB of pixels), and ambulo's masks are each
object's visible pixels, so they do not overlap (where a foreign dataset's do, the later annotation
keeps the pixel).

``ResidentFrames`` decodes every record once (in ``num_workers`` processes) into tensors on the
device: an epoch is then index selections, no PNG decoding, no host-to-device copies.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import torch

from .dataset import (
    DatasetError,
    boxes_xyxy,
    frame_records,
    frames_and_annotations,
    instance_masks,
    read_depth_mm,
    read_height_m,
    read_rgb,
)

MAX_INSTANCES = 255
"""Annotations a frame may have: the instance map is one byte a pixel."""


def pad_rows(rows: list[torch.Tensor], fill: float, width: int | None = None) -> torch.Tensor:
    """(B, width, ...) of tensors (M_i, ...) with ``fill`` after each one's rows (width: the most rows)."""
    width = max((len(r) for r in rows), default=0) if width is None else width
    out = torch.full((len(rows), width, *rows[0].shape[1:]), fill, dtype=rows[0].dtype)
    for i, r in enumerate(rows):
        out[i, :len(r)] = r
    return out


class FrameRecords(torch.utils.data.Dataset):
    """The frames ``image_ids`` of dataset ``root`` as records (module docstring); ``class_of`` maps
    a COCO category id to its 0-based class; ``depth``: records carry the frame's depth; ``height``: its
    height above the floor too. Every frame must have the same size."""

    def __init__(self, root: str | Path, coco: dict, image_ids: list[int], class_of: dict[int, int],
                 depth: bool = False, height: bool = False):
        self.root, self.class_of, self.depth, self.height = Path(root), class_of, depth or height, height
        self.images, self.annotations = frames_and_annotations(coco, image_ids)
        self.records = frame_records(self.root) if height else {}
        sizes = {(im["height"], im["width"]) for im in self.images}
        if len(sizes) > 1:
            raise DatasetError(f"{root} has frames of {len(sizes)} sizes {sorted(sizes)}",
                               "train on frames of one size (one `ambulo generate` run)")
        self.hw = sizes.pop()
        self.max_boxes = max((len(a) for a in self.annotations), default=0)
        if self.max_boxes > MAX_INSTANCES:
            raise DatasetError(f"a frame of {root} has {self.max_boxes} annotations",
                               f"give frames of at most {MAX_INSTANCES} objects")

    def __len__(self) -> int:
        return len(self.images)

    def __getitem__(self, index: int) -> dict[str, torch.Tensor]:
        rgb = np.ascontiguousarray(read_rgb(self.root, self.images[index]).transpose(2, 0, 1))
        anns = self.annotations[index]
        h, w = self.hw
        instances = np.zeros((h, w), np.uint8)
        if anns and any(a.get("segmentation") for a in anns):
            for k, mask in enumerate(instance_masks(anns, h, w).numpy()):
                instances[mask] = k + 1
        boxes = boxes_xyxy(anns)
        classes = torch.tensor([self.class_of[a["category_id"]] for a in anns], dtype=torch.int64)
        record = {"image": torch.from_numpy(rgb), "instances": torch.from_numpy(instances), "boxes": boxes,
                  "classes": classes}
        if self.depth:
            mm = read_depth_mm(self.root, self.images[index]).clip(max=np.iinfo(np.int16).max)
            record["depth"] = torch.from_numpy(mm.astype(np.int16))
        if self.height:
            height_m = read_height_m(self.root, self.records, self.images[index], mm)
            height_mm = np.round(height_m * 1000.0).clip(-32768, 32767)
            record["height"] = torch.from_numpy(height_mm.astype(np.int16))
        return record


def pad_collate(records: list[dict[str, torch.Tensor]]) -> dict[str, torch.Tensor]:
    """Records stacked into a batch, boxes padded (classes -1) to the batch's most boxes."""
    batch = {"images": torch.stack([r["image"] for r in records]),
             "instances": torch.stack([r["instances"] for r in records]),
             "boxes": pad_rows([r["boxes"] for r in records], 0.0),
             "classes": pad_rows([r["classes"] for r in records], -1)}
    if "depth" in records[0]:
        batch["depths"] = torch.stack([r["depth"] for r in records])
    if "height" in records[0]:
        batch["heights"] = torch.stack([r["height"] for r in records])
    return batch


class ResidentFrames:
    """Every record of ``records`` decoded once into padded tensors on ``device``; ``batch(index)``
    selects frames (index: (B,) int64 on ``device``)."""

    def __init__(self, records: FrameRecords, device: torch.device, num_workers: int = 0, chunk: int = 64):
        n, (h, w), m = len(records), records.hw, max(1, records.max_boxes)
        self.images = torch.empty(n, 3, h, w, dtype=torch.uint8, device=device)
        self.instances = torch.empty(n, h, w, dtype=torch.uint8, device=device)
        self.boxes = torch.zeros(n, m, 4, device=device)
        self.classes = torch.full((n, m), -1, dtype=torch.int64, device=device)
        self.depths = torch.empty(n, h, w, dtype=torch.int16, device=device) if records.depth else None
        self.heights = torch.empty(n, h, w, dtype=torch.int16, device=device) if records.height else None
        loader = torch.utils.data.DataLoader(records, batch_size=chunk, num_workers=num_workers,
                                             collate_fn=pad_collate)
        start = 0
        for batch in loader:
            end, k = start + len(batch["images"]), batch["boxes"].shape[1]
            self.images[start:end] = batch["images"].to(device)
            self.instances[start:end] = batch["instances"].to(device)
            self.boxes[start:end, :k] = batch["boxes"].to(device)
            self.classes[start:end, :k] = batch["classes"].to(device)
            if self.depths is not None:
                self.depths[start:end] = batch["depths"].to(device)
            if self.heights is not None:
                self.heights[start:end] = batch["heights"].to(device)
            start = end

    def __len__(self) -> int:
        return len(self.images)

    def batch(self, index: torch.Tensor) -> dict[str, torch.Tensor]:
        batch = {"images": self.images[index], "instances": self.instances[index], "boxes": self.boxes[index],
                 "classes": self.classes[index]}
        if self.depths is not None:
            batch["depths"] = self.depths[index]
        if self.heights is not None:
            batch["heights"] = self.heights[index]
        return batch


__all__ = ["MAX_INSTANCES", "FrameRecords", "ResidentFrames", "pad_collate", "pad_rows"]
