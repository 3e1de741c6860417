"""COCO evaluation of a detector on held-out frames with pycocotools: mAP, mAP50 and AP per class,
of the boxes and, for a model with masks, of the instance masks (iouType 'segm') and of the semantic
image painted from them (``semantic.semantic_metrics``: mIoU, IoU per class, pixel accuracy)."""

from __future__ import annotations

import contextlib
import copy
import io

import numpy as np
import torch
from pycocotools import mask as mask_utils

from .model import CenterNet, decode, decode_masks, paste_masks
from .semantic import semantic_metrics


@torch.no_grad()
def predict_coco(model: CenterNet, loader, device: torch.device, category_ids: list[int],
                 image_sizes: dict[int, tuple[int, int]] | None = None) -> list[dict]:
    """COCO result entries ``{"image_id", "category_id", "bbox" (x, y, w, h px), "score"}`` of every
    image of ``loader``; class index k is category ``category_ids[k]``. For a model with masks and
    ``image_sizes`` ({image id: (H, W) px}), each entry also has its ``segmentation`` (compressed
    RLE of the image's size), which ``coco_metrics(..., iou_type="segm")`` scores."""
    model.eval()
    with_masks = bool(model.cfg.mask_prototypes) and image_sizes is not None
    results = []
    for images, batch_targets in loader:
        maps = model(images.to(device))
        if with_masks:  # masks are pasted on the device: a GPU's evaluation does not wait on the CPU
            boxes, scores, classes, masks = decode_masks(maps, model.cfg.max_detections)
        else:
            boxes, scores, classes = decode(maps, model.cfg.max_detections)
        boxes_cpu, scores, classes = boxes.cpu(), scores.cpu(), classes.cpu()
        for n, target in enumerate(batch_targets):
            image_id = int(target["image_id"])
            b = boxes_cpu[n]
            xywh = torch.cat([b[:, :2], b[:, 2:] - b[:, :2]], dim=1)
            entries = [{"image_id": image_id, "category_id": category_ids[cls], "bbox": box, "score": score}
                       for box, score, cls in zip(xywh.tolist(), scores[n].tolist(), classes[n].tolist())]
            if with_masks:
                binary = paste_masks(masks[n], boxes[n], image_sizes[image_id]).cpu().numpy()
                rles = mask_utils.encode(np.asfortranarray(binary.transpose(1, 2, 0).astype(np.uint8)))
                for entry, rle in zip(entries, rles):
                    entry["segmentation"] = {"size": [int(v) for v in rle["size"]], "counts": rle["counts"].decode()}
            results.extend(entries)
    return results


def coco_metrics(coco_dict: dict, image_ids: list[int], results: list[dict], iou_type: str = "bbox") -> dict:
    """``{"mAP", "mAP50", "per_class": {name: AP}}`` of ``results`` on ``image_ids`` of the COCO dict
    (pycocotools' COCOeval, ``iou_type`` 'bbox' or 'segm', maxDets 100; AP of a class with no ground
    truth is left out)."""
    from pycocotools.coco import COCO
    from pycocotools.cocoeval import COCOeval

    with contextlib.redirect_stdout(io.StringIO()):  # pycocotools prints its progress
        gt = COCO()
        gt.dataset = copy.deepcopy(coco_dict)
        gt.createIndex()
        if not results:
            return {"mAP": 0.0, "mAP50": 0.0, "per_class": {}}
        # copies (loadRes writes into them) without the other kind: given both, loadRes keeps the box's
        # area for the mask; given only masks, it takes each mask's area and box
        drop = "segmentation" if iou_type == "bbox" else "bbox"
        results = [{k: v for k, v in r.items() if k != drop} for r in results]
        dt = gt.loadRes(results)
        ev = COCOeval(gt, dt, iou_type)
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


def evaluate_all(coco_dict: dict, image_ids: list[int], results: list[dict]) -> dict:
    """``coco_metrics`` of the boxes, with ``"mask"``: the same of the masks, and ``"semantic"``:
    ``semantic_metrics`` (``{"mIoU", "per_class", "pixel_acc"}``), when ``results`` have masks."""
    metrics = coco_metrics(coco_dict, image_ids, results, "bbox")
    if results and "segmentation" in results[0]:
        metrics["mask"] = coco_metrics(coco_dict, image_ids, results, "segm")
        metrics["semantic"] = semantic_metrics(coco_dict, image_ids, results)
    return metrics
