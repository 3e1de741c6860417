"""The generated COCO file: pycocotools scores perturbed detections as computed by hand; it agrees with the PNGs."""

import contextlib
import io
import json

import numpy as np
import pytest
from PIL import Image
from pycocotools import mask as mask_utils
from pycocotools.coco import COCO
from pycocotools.cocoeval import COCOeval

from ambulo.replicator.records import read_records

# pycocotools 2.0.11 calls np.array(copy=False) on its own RLE objects under NumPy 2
pytestmark = pytest.mark.filterwarnings("ignore:__array__ implementation:DeprecationWarning")


def load(dataset):
    with contextlib.redirect_stdout(io.StringIO()):
        return COCO(str(dataset / "annotations.json"))


def evaluate(gt, detections, iou_type):
    with contextlib.redirect_stdout(io.StringIO()):
        ev = COCOeval(gt, gt.loadRes(detections), iou_type)
        ev.evaluate()
        ev.accumulate()
        ev.summarize()
    return ev.stats


def test_perturbed_detections_score_the_hand_computed_ap_and_ar(dataset):
    """Detections made from the instance PNGs (not from annotations.json), perturbed in known ways.

    Per category with n ground-truth objects (all boxes and masks come from the PNG):
      - its first object is missed (no detection);
      - the other n - 1 are found: the box is shifted right by 0.2 w, so its IoU with the
        true box is (w - 0.2 w) h / ((w + 0.2 w) h) = 0.8 / 1.2 = 2/3; the mask is exact (IoU 1);
      - one false positive (a box off the image, the image's background as mask: IoU 0 with
        every object) has the highest score, above every true detection.
    Ranked by score the detections are FP, TP, ..., TP: precision after the k-th TP is
    k / (k + 1), so COCO's interpolated precision (the maximum at any recall >= r) is
    (n - 1) / n at every recall point up to the final recall (n - 1) / n, and 0 above it.
    COCO averages it over the 101 recall points 0, 0.01, ..., 1, then over categories:
      AP_c = (n - 1) / n * #{r in recall points : r <= (n - 1) / n} / 101.
    A box with IoU 2/3 matches at the IoU thresholds .50, .55, .60, .65 (4 of the 10 in
    .50:.05:.95) and is a false positive at the other 6, where AP and recall are 0; an exact
    mask matches at all 10.
    """
    gt = load(dataset)
    boxes, masks = [], []
    missed, score = set(), 0.9
    for img in gt.dataset["images"]:
        instances = np.asarray(Image.open(dataset / "instance" / img["file_name"].split("/")[-1]))
        for ann in gt.loadAnns(gt.getAnnIds(imgIds=img["id"])):
            if ann["category_id"] not in missed:
                missed.add(ann["category_id"])  # the category's first object: no detection
                continue
            mask = instances == ann["instance_id"]
            assert mask.any(), f"annotation {ann['id']}: its instance is not in its image's instance PNG"
            ys, xs = np.nonzero(mask)
            x, y, w, h = xs.min(), ys.min(), xs.max() - xs.min() + 1, ys.max() - ys.min() + 1
            score -= 0.001  # distinct scores, all below the false positives' 1.0
            det = {"image_id": img["id"], "category_id": ann["category_id"], "score": score}
            boxes.append({**det, "bbox": [float(x + 0.2 * w), float(y), float(w), float(h)]})
            rle = mask_utils.encode(np.asfortranarray(mask.astype(np.uint8)))
            masks.append({**det, "segmentation": {"size": rle["size"], "counts": rle["counts"].decode()}})
    img = gt.dataset["images"][0]
    background = np.asarray(Image.open(dataset / "instance" / img["file_name"].split("/")[-1])) == 0
    assert background.any()
    rle = mask_utils.encode(np.asfortranarray(background.astype(np.uint8)))
    for cat in gt.getCatIds():
        det = {"image_id": img["id"], "category_id": cat, "score": 1.0}
        boxes.append({**det, "bbox": [-100.0, -100.0, 20.0, 20.0]})
        masks.append({**det, "segmentation": {"size": rle["size"], "counts": rle["counts"].decode()}})

    # the hand arithmetic of the docstring, per category present in the ground truth
    counts = np.bincount([a["category_id"] for a in gt.dataset["annotations"]])
    n = counts[counts > 0].astype(float)
    assert len(n) >= 3 and n.min() >= 2  # each category's AP is non-trivial
    final_recall = (n - 1) / n
    recall_points = np.linspace(0.0, 1.00, 101)  # COCO's recall points, as pycocotools makes them
    ap = final_recall * (recall_points[None, :] <= final_recall[:, None]).sum(1) / 101
    assert 0.5 < ap.mean() < 0.99

    bbox = evaluate(gt, boxes, "bbox")
    assert bbox[0] == pytest.approx(4 / 10 * ap.mean(), abs=1e-12)  # AP@[.50:.95]
    assert bbox[1] == pytest.approx(ap.mean(), abs=1e-12)  # AP@.50
    assert bbox[2] == 0.0  # AP@.75: IoU 2/3 < .75
    assert bbox[8] == pytest.approx(4 / 10 * final_recall.mean(), abs=1e-12)  # AR@100
    segm = evaluate(gt, masks, "segm")
    assert segm[0] == pytest.approx(ap.mean(), abs=1e-12)
    assert segm[2] == pytest.approx(ap.mean(), abs=1e-12)
    assert segm[8] == pytest.approx(final_recall.mean(), abs=1e-12)


def test_categories_images_and_boxes_are_well_formed(dataset):
    coco = load(dataset)
    cats = coco.dataset["categories"]
    names = [c["name"] for c in cats]
    assert len(set(names)) == len(names) and min(c["id"] for c in cats) >= 1
    assert sorted(names) == ["ball", "box", "can", "cone"]
    for img in coco.dataset["images"]:
        with Image.open(dataset / img["file_name"]) as png:
            assert png.size == (img["width"], img["height"]) == (160, 120)
    for ann in coco.dataset["annotations"]:
        img = coco.imgs[ann["image_id"]]
        x, y, w, h = ann["bbox"]
        assert ann["area"] > 0 and w > 0 and h > 0
        assert x >= 0 and y >= 0 and x + w <= img["width"] and y + h <= img["height"]
        mask = mask_utils.decode(ann["segmentation"])
        ys, xs = np.nonzero(mask)
        assert [x, y, w, h] == [xs.min(), ys.min(), xs.max() - xs.min() + 1, ys.max() - ys.min() + 1]
        assert ann["area"] == mask.sum() and ann["category_id"] in coco.cats


def test_masks_match_instance_png_and_occluded_objects_are_left_out(dataset):
    coco = load(dataset)
    records = read_records(dataset / "frames")
    for img in coco.dataset["images"]:
        stem = img["file_name"].split("/")[-1]
        instances = np.asarray(Image.open(dataset / "instance" / stem))
        record = records[img["frame"]]
        anns = coco.loadAnns(coco.getAnnIds(imgIds=img["id"]))
        annotated = {a["instance_id"] for a in anns}
        for ann in anns:
            assert np.array_equal(mask_utils.decode(ann["segmentation"]).astype(bool), instances == ann["instance_id"])
            assert 0 < ann["visible_fraction"] <= 1
        # every object with no annotation is invisible or below the 10-pixel floor
        for iid in set(np.unique(instances)) - {0} - annotated:
            assert np.count_nonzero(instances == iid) < 10
        assert len(record["annotations"]) == len(anns)


def test_depth_png_kitti_and_raw_outputs_agree(dataset):
    coco = load(dataset)
    img = coco.dataset["images"][0]
    stem = img["file_name"].split("/")[-1][:-4]
    depth_mm = np.asarray(Image.open(dataset / "depth" / f"{stem}.png")).astype(np.int64)
    raw = np.load(dataset / "raw" / f"{stem}_depth.npy")
    finite = np.isfinite(raw) & (raw < 65)
    assert np.abs(depth_mm[finite] - raw[finite] * 1000).max() <= 0.5
    lines = (dataset / "kitti" / f"{stem}.txt").read_text().splitlines()
    anns = coco.loadAnns(coco.getAnnIds(imgIds=img["id"]))
    assert len(lines) == len(anns)
    for line, ann in zip(lines, anns):
        fields = line.split()
        assert len(fields) == 15 and fields[0] == coco.cats[ann["category_id"]]["name"]
        x, y, w, h = ann["bbox"]
        assert np.allclose([float(v) for v in fields[4:8]], [x, y, x + w, y + h], atol=0.01)
        assert float(fields[13]) > 0  # objects are in front of the camera (z forward)
    meta = json.loads((dataset / "metadata.json").read_text())
    assert meta["gl_renderer"] and meta["seed"] == 5
