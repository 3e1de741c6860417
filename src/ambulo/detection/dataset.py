"""An ``ambulo generate`` dataset as detection samples: COCO boxes and labels, a held-out split.

The dataset folder is the one ``replicator.writers`` documents: ``annotations.json`` (COCO instances,
categories 1..C, one image per frame, ``bbox`` in pixel edges x, y, w, h) and ``rgb/NNNNNN.png``.
The split is by frame: the last ``held_out_fraction`` of the frames are never trained on. Frames
differ by randomization seed stream, so held-out frames are unseen poses, textures and lighting of
the training distribution (the issue's split (a)).

A sample is ``(image, target)``: image float32 (3, H, W) in [0, 1] (with ``depth``: (4, H, W), the 4th
channel the frame's ``depth/`` PNG as ``model.depth_channel`` encodes it; with ``height`` too: (5, H, W),
the 5th each pixel's height above the floor from that depth and the frame record's camera
(``height.height_above_floor_m``, ``model.height_channel``)) on a canvas of the fixed
``canvas_hw`` (the dataset's size rounded up to the model's stride; padding is black, bottom and
right), target ``{"boxes": (N, 4) float32 x0 y0 x1 y1 px, "labels": (N,) int64 COCO category ids,
"image_id": int}`` and, with ``masks``, ``"masks": (N, H, W) bool`` on the canvas (decoded from
each annotation's ``segmentation``, RLE or polygons). Boxes stay in the canvas's pixels, which are
the image's pixels (padding is only ever added after the image's last row and column). These
samples are what evaluation and inference read; training reads ``frames``' uint8 records and
augments them on the device (``augment``).
"""

from __future__ import annotations

import json
import math
from pathlib import Path

import imageio.v3 as iio
import numpy as np
import torch
from pycocotools import mask as mask_utils

from ambulo.utils.frame_journal import read_records

from .height import camera_of_record, height_above_floor_m
from .model import depth_channel, height_channel


class DatasetError(Exception):
    """A folder that is not a readable ``ambulo generate`` dataset: ``problem`` and ``fix``."""

    def __init__(self, problem: str, fix: str):
        self.problem, self.fix = problem, fix
        super().__init__(f"{problem}; {fix}")


def load_coco(root: str | Path) -> dict:
    """The merged COCO file of a dataset folder, with a clear error when it is not one."""
    path = Path(root) / "annotations.json"
    if not path.is_file():
        raise DatasetError(f"{root} has no annotations.json",
                           "give a folder made by `ambulo generate` (an interrupted one: run the same command to finish)")
    coco = json.loads(path.read_text())
    if not coco.get("images") or not coco.get("categories"):
        raise DatasetError(f"{path} has no images or no categories", "generate at least one frame with objects")
    return coco


def split_image_ids(coco: dict, held_out_fraction: float) -> tuple[list[int], list[int]]:
    """(train ids, held-out ids): the held-out ids are the last frames, at least one when asked for any."""
    ids = [image["id"] for image in sorted(coco["images"], key=lambda im: im["id"])]
    n_held = math.ceil(len(ids) * held_out_fraction) if held_out_fraction > 0 else 0
    if n_held >= len(ids):
        raise DatasetError(f"{len(ids)} frames leave none to train on with {held_out_fraction:.0%} held out",
                           "generate more frames or hold out a smaller fraction")
    return ids[:len(ids) - n_held], ids[len(ids) - n_held:]


def canvas_size(coco: dict, stride: int) -> tuple[int, int]:
    """(H, W) holding every image, rounded up to a multiple of ``stride``."""
    h = max(im["height"] for im in coco["images"])
    w = max(im["width"] for im in coco["images"])
    return -(-h // stride) * stride, -(-w // stride) * stride


def frames_and_annotations(coco: dict, image_ids: list[int]) -> tuple[list[dict], list[list[dict]]]:
    """The image records of ``image_ids`` and, for each, its annotations (crowd ones left out)."""
    images = {im["id"]: im for im in coco["images"]}
    by_image: dict[int, list[dict]] = {i: [] for i in image_ids}
    for ann in coco["annotations"]:
        if ann["image_id"] in by_image and not ann.get("iscrowd", 0):
            by_image[ann["image_id"]].append(ann)
    return [images[i] for i in image_ids], [by_image[i] for i in image_ids]


def read_rgb(root: Path, image_info: dict) -> np.ndarray:
    """The frame's colour image (H, W, 3) uint8; a missing file is a one-line ``DatasetError``."""
    path = root / image_info["file_name"]
    if not path.is_file():
        raise DatasetError(f"{path} is missing", "run `ambulo generate` again with the same command to repair it")
    return iio.imread(path)[..., :3]


def depth_path(root: Path, image_info: dict) -> Path:
    """The frame's depth PNG (``replicator.writers``: ``depth/`` beside ``rgb/``, the same stem)."""
    return root / "depth" / (Path(image_info["file_name"]).stem + ".png")


def read_depth_mm(root: Path, image_info: dict) -> np.ndarray:
    """The frame's depth (H, W) uint16 mm (0: no return); a missing file is a one-line ``DatasetError``."""
    path = depth_path(root, image_info)
    if not path.is_file():
        raise DatasetError(f"{path} is missing", "train an rgb model (inputs 'rgb'), or give a dataset "
                           "generated with the 'depth' output in png16 (the default)")
    depth = iio.imread(path)
    if depth.dtype != np.uint16 or depth.ndim != 2:
        raise DatasetError(f"{path} is {depth.dtype} {depth.shape}, not a (H, W) uint16 depth in mm",
                           "generate the dataset with depth_format 'png16'")
    return depth


def boxes_xyxy(annotations: list[dict]) -> torch.Tensor:
    """(N, 4) float32 x0 y0 x1 y1 px of COCO ``bbox`` (x, y, w, h) annotations."""
    return torch.tensor([[x, y, x + w, y + h] for x, y, w, h in (a["bbox"] for a in annotations)],
                        dtype=torch.float32).reshape(-1, 4)


def read_height_m(root: Path, records: dict[int, dict], image_info: dict, depth_mm: np.ndarray) -> np.ndarray:
    """The frame's height above the floor (H, W) float32 m (``height``) from its depth (H, W) mm and the camera
    its record holds (``records``: ``frame_records(root)``, read once a dataset); a missing record is a
    ``DatasetError``."""
    frame = image_info.get("frame", int(Path(image_info["file_name"]).stem))
    record = records.get(frame)
    if record is None:
        raise DatasetError(f"{Path(root) / 'frames'}: no record of frame {frame} (the camera's pose) for the height "
                           "channel", "train inputs 'rgbdh' on an `ambulo generate` dataset with its frames/ records")
    intrinsics, extrinsics_cw = camera_of_record(record)
    return height_above_floor_m(depth_mm.astype(np.float32) / 1000.0, intrinsics, extrinsics_cw)


def frame_records(root: str | Path) -> dict[int, dict]:
    """Frame index -> record of dataset ``root`` (the lines of its ``frames/records-*.jsonl`` journals,
    ``utils.frame_journal``): read once when a dataset is opened, not per sample."""
    return read_records(Path(root) / "frames")


class CocoFrames(torch.utils.data.Dataset):
    """The frames ``image_ids`` of dataset ``root`` as (image, target) samples (module docstring): a
    torch ``Dataset`` (batch it with ``collate``) for the held-out evaluations (``train``,
    ``transfer``) or a user's own training loop. ``masks``: each target also holds ``"masks"``, the
    objects' (N, H, W) bool masks on the canvas (their COCO segmentation, ``instance_masks``), as
    torchvision-style instance segmentation takes them; ambulo's own training reads masks from the
    one instance map a frame of ``frames`` holds instead."""

    def __init__(self, root: str | Path, coco: dict, image_ids: list[int], canvas_hw: tuple[int, int],
                 masks: bool = False, depth: bool = False, height: bool = False):
        self.root, self.canvas_hw, self.masks, self.depth, self.height = Path(root), canvas_hw, masks, depth, height
        self.images, self.annotations = frames_and_annotations(coco, image_ids)
        self.records = frame_records(self.root) if height else {}

    def __len__(self) -> int:
        return len(self.images)

    def __getitem__(self, index: int) -> tuple[torch.Tensor, dict]:
        image_info = self.images[index]
        rgb = torch.from_numpy(np.ascontiguousarray(read_rgb(self.root, image_info))).permute(2, 0, 1).float() / 255.0
        anns = self.annotations[index]
        boxes = boxes_xyxy(anns)
        labels = torch.tensor([a["category_id"] for a in anns], dtype=torch.int64)
        masks = instance_masks(anns, rgb.shape[1], rgb.shape[2]) if self.masks else None
        if self.depth or self.height:
            mm = read_depth_mm(self.root, image_info)
            rgb = torch.cat([rgb, depth_channel(torch.from_numpy(mm.astype(np.float32)) / 1000.0)[None]])
        if self.height:
            height_m = read_height_m(self.root, self.records, image_info, mm)
            rgb = torch.cat([rgb, height_channel(torch.from_numpy(height_m))[None]])
        canvas = torch.zeros(len(rgb), *self.canvas_hw)
        h, w = min(rgb.shape[1], self.canvas_hw[0]), min(rgb.shape[2], self.canvas_hw[1])
        canvas[:, :h, :w] = rgb[:, :h, :w]
        target = {"boxes": boxes, "labels": labels, "image_id": image_info["id"]}
        if masks is not None:
            target["masks"] = torch.zeros(len(masks), *self.canvas_hw, dtype=torch.bool)
            target["masks"][:, :h, :w] = masks[:, :h, :w]
        return canvas, target


def instance_masks(annotations: list[dict], height: int, width: int) -> torch.Tensor:
    """(N, H, W) bool masks of COCO annotations' ``segmentation`` (compressed or plain RLE, or polygons)."""
    if not annotations:
        return torch.zeros(0, height, width, dtype=torch.bool)
    rles = []
    for ann in annotations:
        seg = ann.get("segmentation")
        if not seg:
            raise DatasetError(f"annotation {ann.get('id')} has no segmentation",
                               "train boxes only (ModelCfg(mask_prototypes=0)) or give a dataset with masks")
        if isinstance(seg, dict) and isinstance(seg["counts"], str):  # compressed RLE, as ambulo writes
            rles.append({"size": seg["size"], "counts": seg["counts"].encode()})
            continue
        rle = mask_utils.frPyObjects(seg, height, width)
        rles.append(mask_utils.merge(rle) if isinstance(rle, list) else rle)  # polygons: one RLE per part
    return torch.from_numpy(mask_utils.decode(rles).transpose(2, 0, 1).astype(bool))


def collate(batch: list[tuple[torch.Tensor, dict]]) -> tuple[torch.Tensor, list[dict]]:
    """Images stacked (all share the canvas), targets kept as a list (each image has its own count)."""
    return torch.stack([image for image, _ in batch]), [target for _, target in batch]
