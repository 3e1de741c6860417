"""COCO instance annotations: per-frame records (RLE masks via pycocotools) and the merged file.

Each frame's record is self-contained JSON (image entry, annotations without
ids, camera, randomization log), a line of its writer's journal (``records``);
``merge_coco`` numbers images and annotations in frame order, so a dataset made
by one process, by resumed runs or by Ray shards is the same file.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np
from pycocotools import mask as mask_utils

from ambulo.sensors.annotators import boxes_of_runs

from .records import read_records


def frame_annotations(capture: dict, semantic_ids: np.ndarray, instance_names: list[str],
                      min_visible_pixels: int = 1) -> list[dict]:
    """COCO annotations (no ids yet) for the visible instances of one camera capture.

    ``semantic_ids`` (K+1,) maps instance id -> category id (``InstanceTable``).

    Fully occluded or out-of-view instances have no pixels and are left out;
    ``bbox`` is the box of the RLE mask itself (``toBbox``), so they agree exactly.
    """
    tight = capture["bounding_box_2d_tight"]
    keep = tight["pixels"] >= max(1, min_visible_pixels)
    ids = tight["instance_id"][keep]
    if len(ids) == 0:
        return []
    # the GPU path hands the masks' run lengths found on the device (``device_rle``): the same bytes
    rles = capture["coco_rles"](ids) if "coco_rles" in capture else instance_rles(capture["instance_segmentation"], ids)
    # every array to Python numbers once (not one small conversion per annotation and field)
    boxes = mask_utils.toBbox(rles).tolist()
    areas = mask_utils.area(rles).tolist()
    categories = np.asarray(semantic_ids).tolist()
    loose_boxes = capture.get("bounding_box_2d_loose", {})
    loose = dict(zip(np.asarray(loose_boxes.get("instance_id", [])).tolist(),
                     np.asarray(loose_boxes.get("box", []), np.float64).tolist()))  # floats, as the boxes are
    b3 = capture.get("bounding_box_3d")
    if b3 is not None:
        b3 = {key: b3[key].tolist() for key in ("center_w", "rot_w", "half_extent", "center_c", "rot_c")}
    fraction = capture.get("visible_fraction")
    fraction = None if fraction is None else np.asarray(fraction, np.float64).tolist()
    # a Python step per annotation is most of this function's cost (~10 a frame): what every
    # annotation shares is made once, and each value is already a Python number from ``tolist``
    b3_items = None if b3 is None else tuple(b3.items())
    out = []
    for k, iid in enumerate(ids.tolist()):
        rle = rles[k]
        size = rle["size"]
        ann = {
            "category_id": int(categories[iid]),
            "bbox": boxes[k],
            "area": int(areas[k]),
            "segmentation": {"size": [int(size[0]), int(size[1])], "counts": rle["counts"].decode()},
            "iscrowd": 0,
            "instance_id": iid,
            "prim_path": instance_names[iid - 1],
        }
        box = loose.get(iid)
        if box is not None:
            x0, y0, x1, y1 = box
            ann["bbox_loose"] = [x0 + 0.5, y0 + 0.5, x1 - x0, y1 - y0]  # COCO: pixel edges, not centres
        if b3_items is not None:
            i = iid - 1
            ann["bbox_3d"] = {key: values[i] for key, values in b3_items}
        if fraction is not None:
            ann["visible_fraction"] = fraction[iid - 1]
        out.append(ann)
    return out


@dataclass(frozen=True, slots=True)
class InstanceRuns:
    """The runs of equal ids of one (H, W) instance image in column-major order (COCO's), grouped by id.

    One pass over the image (``column_runs``) that both a frame's tight boxes (``runs_tight_boxes``)
    and its COCO masks (``instance_rles``) are read from, instead of a pass in row order for the
    boxes and another in column order for the masks.
    """

    height: int
    width: int
    starts: np.ndarray
    """(R,) int64 where each run starts (column-major pixel index)."""
    ids: np.ndarray
    """(R,) each run's id (0 = background)."""
    ends: np.ndarray
    """(R,) int64 where each run ends (exclusive)."""
    order: np.ndarray
    """(R,) int64 the runs sorted by id (stable: in image order within an id)."""

    @classmethod
    def of(cls, instances: np.ndarray) -> InstanceRuns:
        h, w = instances.shape
        starts, ids = column_runs(instances)
        return cls(h, w, starts, ids, np.append(starts[1:], h * w), np.argsort(ids, kind="stable"))


def runs_tight_boxes(runs: InstanceRuns, num_instances: int) -> tuple[np.ndarray, np.ndarray]:
    """``sensors.annotators.tight_boxes`` of the image ``runs`` were found in, from its column runs.

    Returns ``boxes`` (K, 4) int64 [x_min, y_min, x_max, y_max] inclusive (-1 where invisible) and
    ``pixels`` (K,) int64. A column-major run spans columns c0..c1 and, within a column, rows r0..r1
    (all rows when it wraps onto the next column): the row-order computation, transposed.
    """
    order = runs.order
    # background runs (id 0) come first in id order: the foreground is the sorted tail
    fg = order[int(np.searchsorted(runs.ids[order], 1)):]
    return boxes_of_runs(runs.starts[fg], runs.ends[fg], runs.ids[fg], runs.height, num_instances, column_major=True)


def instance_rles(instances: np.ndarray | None, ids: np.ndarray, runs: InstanceRuns | None = None) -> list[dict]:
    """Compressed COCO RLEs of the masks ``instances == id``, one per id of ``ids``.

    The same bytes as ``mask_utils.encode`` of the K binary masks, ~5x faster:
    one pass finds the runs of equal ids in column-major order (COCO's), and
    each instance's RLE counts are the gaps between its runs. ``runs``: that pass's
    ``InstanceRuns``, when the caller has them already (then ``instances`` is not read).
    """
    runs = InstanceRuns.of(instances) if runs is None else runs
    h, w = runs.height, runs.width
    size = h * w
    starts, ends, order = runs.starts, runs.ends, runs.order  # runs grouped by id, in image order within one
    values = runs.ids[order]
    first, last = np.searchsorted(values, ids, "left"), np.searchsorted(values, ids, "right")
    # every kept instance's runs, grouped by instance (in ``ids`` order), in image order within one
    n_runs = last - first
    total = int(n_runs.sum())
    group_start = np.cumsum(n_runs) - n_runs  # where each instance's runs begin in ``runs``
    picked = order[np.repeat(first - group_start, n_runs) + np.arange(total)]
    run_start, run_end = starts[picked], ends[picked]
    # one array of every instance's counts, side by side: zeros, ones, ..., zeros, ones, then the
    # zeros after its last run; run j of instance g sits at 2 j + g (each instance before adds a tail)
    group = np.repeat(np.arange(len(ids)), n_runs)
    has_runs = n_runs > 0
    previous_end = np.zeros(total, np.int64)
    previous_end[1:] = run_end[:-1]
    previous_end[group_start[has_runs]] = 0
    counts = np.empty(2 * total + len(ids), np.int64)
    at = 2 * np.arange(total) + group
    counts[at] = run_start - previous_end
    counts[at + 1] = run_end - run_start
    offsets = 2 * group_start + np.arange(len(ids))
    tails = offsets + 2 * n_runs
    last_end = np.zeros(len(ids), np.int64)  # an instance without pixels: all zeros
    last_end[has_runs] = run_end[(group_start + n_runs - 1)[has_runs]]
    counts[tails] = size - last_end
    # pycocotools drops an empty last run
    stops = np.where(counts[tails] == 0, tails, tails + 1)
    objs = [{"counts": counts[lo:hi], "size": [h, w]} for lo, hi in zip(offsets.tolist(), stops.tolist())]
    return mask_utils.frPyObjects(objs, h, w) if objs else []


def column_runs(instances: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Where each run of equal ids starts in column-major order (COCO's), and its id.

    A run starts at the first pixel, where a pixel differs from the one above it, and at the
    top of a column that differs from the bottom of the column before. The comparisons run on
    the image as it is stored (rows); only their (W, H) boolean map is laid out by columns, a
    quarter of the bytes of a column-major copy of the int32 ids.
    """
    h, w = instances.shape
    change = np.empty((w, h), bool)
    np.not_equal(instances[1:], instances[:-1], out=change[:, 1:].T)
    np.not_equal(instances[0, 1:], instances[-1, :-1], out=change[1:, 0])
    change[0, 0] = True
    starts = np.flatnonzero(change)
    column, row = np.divmod(starts, h)
    return starts, instances[row, column]


def coco_categories(categories: list[str]) -> list[dict]:
    """Category entries with ids 1..C in sorted-label order (0 is background in COCO tools)."""
    if len(set(categories)) != len(categories):
        raise ValueError(f"duplicate category labels: {categories}")
    return [{"id": i + 1, "name": name, "supercategory": "object"} for i, name in enumerate(categories)]


def coco_image(index: int, record: dict) -> dict:
    """Frame ``index``'s COCO image entry from its record (id: the frame index + 1)."""
    return {"id": index + 1, "file_name": record["file_name"], "width": record["width"],
            "height": record["height"], "frame": index}


def merge_coco(frames_dir: Path, num_frames: int, categories: list[str], info: dict) -> dict:
    """The COCO dict of frames 0..num_frames-1 from their records (the journals in ``frames_dir``);
    ``FileNotFoundError`` naming the first frame without one."""
    records = read_records(frames_dir)
    images, annotations = [], []
    for index in range(num_frames):
        record = records.get(index)
        if record is None:
            raise FileNotFoundError(f"{frames_dir}: no record of frame {index}")
        image_id = index + 1
        images.append(coco_image(index, record))
        for ann in record["annotations"]:
            annotations.append({**ann, "id": len(annotations) + 1, "image_id": image_id})
    return {"info": info, "licenses": [], "categories": coco_categories(categories),
            "images": images, "annotations": annotations}
