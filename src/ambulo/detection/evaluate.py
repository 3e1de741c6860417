"""COCO evaluation of a detector on held-out frames with pycocotools: mAP, mAP50 and AP per class."""

from __future__ import annotations

import contextlib
import copy
import io

import numpy as np
import torch

from .model import CenterNet, decode


@torch.no_grad()
def predict_coco(model: CenterNet, loader, device: torch.device, category_ids: list[int]) -> list[dict]:
    """COCO result entries ``{"image_id", "category_id", "bbox" (x, y, w, h px), "score"}`` of every
    image of ``loader``; class index k is category ``category_ids[k]``."""
    model.eval()
    results = []
    for images, batch_targets in loader:
        boxes, scores, classes = decode(model(images.to(device)), model.cfg.max_detections)
        for target, b, s, c in zip(batch_targets, boxes.cpu(), scores.cpu(), classes.cpu()):
            xywh = torch.cat([b[:, :2], b[:, 2:] - b[:, :2]], dim=1)
            for box, score, cls in zip(xywh.tolist(), s.tolist(), c.tolist()):
                results.append({"image_id": int(target["image_id"]), "category_id": category_ids[cls],
                                "bbox": box, "score": score})
    return results


def coco_metrics(coco_dict: dict, image_ids: list[int], results: list[dict]) -> dict:
    """``{"mAP", "mAP50", "per_class": {name: AP}}`` of ``results`` on ``image_ids`` of the COCO dict
    (pycocotools' COCOeval, bbox, maxDets 100; AP of a class with no ground truth is left out)."""
    from pycocotools.coco import COCO
    from pycocotools.cocoeval import COCOeval

    with contextlib.redirect_stdout(io.StringIO()):  # pycocotools prints its progress
        gt = COCO()
        gt.dataset = copy.deepcopy(coco_dict)
        gt.createIndex()
        if not results:
            return {"mAP": 0.0, "mAP50": 0.0, "per_class": {}}
        dt = gt.loadRes(results)
        ev = COCOeval(gt, dt, "bbox")
        ev.params.imgIds = list(image_ids)
        ev.evaluate()
        ev.accumulate()
        ev.summarize()
    precision = ev.eval["precision"]  # (iou thresholds, recall, class, area, max dets)
    per_class = {}
    for k, cat_id in enumerate(ev.params.catIds):
        p = precision[:, :, k, 0, -1]
        if (p > -1).any():
            per_class[gt.cats[cat_id]["name"]] = float(np.mean(p[p > -1]))
    return {"mAP": max(0.0, float(ev.stats[0])), "mAP50": max(0.0, float(ev.stats[1])), "per_class": per_class}
