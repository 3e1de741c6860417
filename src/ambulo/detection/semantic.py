"""Semantic segmentation from a mask model's detections, and its score against a dataset's ground truth.

A semantic image is (H, W) uint8 class ids: 0 background, else the COCO category id of the detection
that covers the pixel. ambulo's datasets number their categories 1..C (category index + 1), and a
dataset's semantic image (``replicator.manifest.semantic_image``: its instance PNG looked up in
``dataset.json``'s ``instance_categories``) holds those same COCO ids, so a predicted image and the
dataset's PNG compare pixel for pixel. Where masks overlap, the highest-scoring detection wins.

``semantic_image`` is the one painter: the evaluation here calls it, and the ROS 2 bridge reaches it
through ``Detections.semantic_image`` (ros2 and detection are peer layers: the bridge takes
detections duck-typed and imports nothing of this package).

Scoring (``semantic_metrics``) accumulates one confusion matrix over the frames (``np.bincount``) of
ground truth painted from the COCO annotations' masks: those masks are the instance PNG's pixels of
each instance (``replicator.coco.instance_rles``), so the painted map is the dataset's semantic image
(``replicator.manifest.semantic_image``; ``tests/detection/test_semantic_eval.py`` checks it frame by
frame) except for objects too small to be annotated (``WriterCfg.min_visible_pixels``, 10 px), which
are background here as they are not ground truth to the box and mask scores either. (The detection
layer may not import the replicator, its peer, so it cannot call that function itself.)
"""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
from pycocotools import mask as mask_utils

SCORE_THRESHOLD = 0.3
"""Detections below this score are not painted: ``Detector``'s default ``score_threshold``, so the
evaluation scores the image the bridge publishes."""

BACKGROUND = "background"


def semantic_image(detections, shape_hw: tuple[int, int], threshold: float = 0.0) -> np.ndarray:
    """(H, W) uint8 class ids of duck-typed ``detections`` (``masks`` (N, H, W) bool, ``category_ids``
    (N,) COCO ids 1..255, ``scores`` (N,)): 0 background, else the category id of the highest-scoring
    detection with ``score >= threshold`` whose mask covers the pixel. ``shape_hw`` (H, W) px is the
    image's size (needed when there are no detections)."""
    out = np.zeros(shape_hw, np.uint8)
    masks = detections.masks
    if masks is None or len(masks) == 0:
        return out
    masks = np.asarray(masks, bool)
    if masks.shape[1:] != tuple(shape_hw):
        raise ValueError(f"masks are {masks.shape[1:]} px, the image {tuple(shape_hw)}")
    ids = np.asarray(detections.category_ids, np.int64)
    if ids.size and (ids.min() < 1 or ids.max() > 255):
        raise ValueError(f"category ids must be 1..255 for a uint8 semantic image, got {ids.min()}..{ids.max()}")
    scores = np.asarray(detections.scores, np.float64)
    # lowest score first, each painted over the ones before it: the highest score is on top where they overlap
    for k in np.argsort(scores, kind="stable"):
        if scores[k] >= threshold:
            out[masks[k]] = ids[k]
    return out


def _decode(segmentation, h: int, w: int) -> np.ndarray:
    """(H, W) bool of a COCO ``segmentation``: compressed RLE (counts a str), uncompressed RLE
    (counts a list) or polygons."""
    if isinstance(segmentation, list):  # polygons: one RLE per polygon, merged
        rle = mask_utils.merge(mask_utils.frPyObjects(segmentation, h, w))
    elif isinstance(segmentation["counts"], list):
        rle = mask_utils.frPyObjects(segmentation, h, w)
    else:
        rle = {"size": segmentation["size"], "counts": segmentation["counts"].encode()}
    return mask_utils.decode(rle).astype(bool)


def ground_truth_semantic(annotations: list[dict], shape_hw: tuple[int, int]) -> np.ndarray:
    """(H, W) uint8: each (non-crowd) annotation's mask painted with its category id, 0 elsewhere.
    An ambulo dataset's masks are disjoint (one instance per pixel), so the order does not matter."""
    out = np.zeros(shape_hw, np.uint8)
    for ann in annotations:
        if not ann.get("iscrowd", 0):
            out[_decode(ann["segmentation"], *shape_hw)] = ann["category_id"]
    return out


def semantic_metrics(coco_dict: dict, image_ids: list[int], results: list[dict],
                     threshold: float = SCORE_THRESHOLD) -> dict:
    """``{"mIoU", "per_class": {name: IoU}, "pixel_acc"}`` of the semantic images of ``results`` (COCO
    result entries with ``segmentation``, as ``evaluate.predict_coco`` makes for a mask model; those
    with ``score >= threshold`` are painted) on ``image_ids`` of the COCO dict, against the ground truth
    of its annotations. Classes are ``background`` and the dict's categories; a class that is neither
    in the ground truth nor predicted on any frame has no IoU and is left out of ``per_class`` and of
    the mean (background counts as a class, as in Pascal VOC)."""
    categories = sorted(coco_dict["categories"], key=lambda c: c["id"])
    names = [BACKGROUND] + [c["name"] for c in categories]
    num = len(names)
    index_of = np.zeros(256, np.int64)  # category id -> row of the confusion matrix (unknown ids: background)
    index_of[[c["id"] for c in categories]] = np.arange(1, num)
    images = {im["id"]: im for im in coco_dict["images"]}
    truth: dict[int, list[dict]] = {i: [] for i in image_ids}
    for ann in coco_dict["annotations"]:
        if ann["image_id"] in truth:
            truth[ann["image_id"]].append(ann)
    found: dict[int, list[dict]] = {i: [] for i in image_ids}
    for r in results:
        if r["image_id"] in found and r["score"] >= threshold:
            found[r["image_id"]].append(r)
    confusion = np.zeros(num * num, np.int64)  # row: ground truth class, column: predicted
    for image_id in image_ids:
        shape = (images[image_id]["height"], images[image_id]["width"])
        kept = found[image_id]
        detections = SimpleNamespace(  # the duck type semantic_image paints
            masks=np.stack([_decode(r["segmentation"], *shape) for r in kept]) if kept else None,
            category_ids=np.array([r["category_id"] for r in kept], np.int64),
            scores=np.array([r["score"] for r in kept], np.float64))
        predicted = index_of[semantic_image(detections, shape, threshold)]
        actual = index_of[ground_truth_semantic(truth[image_id], shape)]
        confusion += np.bincount((actual * num + predicted).ravel(), minlength=num * num)
    return metrics_of_confusion(confusion.reshape(num, num), names)


def metrics_of_confusion(confusion: np.ndarray, names: list[str]) -> dict:
    """``{"mIoU", "per_class", "pixel_acc"}`` of a (C, C) confusion matrix (rows ground truth, columns
    predicted, pixel counts): IoU = TP / (TP + FP + FN) of each class with any pixel in either."""
    tp = np.diag(confusion).astype(np.float64)
    union = confusion.sum(0) + confusion.sum(1) - tp
    per_class = {name: float(tp[k] / union[k]) for k, name in enumerate(names) if union[k] > 0}
    total = confusion.sum()
    return {"mIoU": float(np.mean(list(per_class.values()))) if per_class else 0.0, "per_class": per_class,
            "pixel_acc": float(tp.sum() / total) if total else 0.0}


__all__ = ["BACKGROUND", "SCORE_THRESHOLD", "ground_truth_semantic", "metrics_of_confusion", "semantic_image",
           "semantic_metrics"]
