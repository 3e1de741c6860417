"""The generated COCO file passes pycocotools, evaluates itself to AP = 1, and agrees with the PNGs."""

import contextlib
import io
import json

import numpy as np
import pytest
from PIL import Image
from pycocotools import mask as mask_utils
from pycocotools.coco import COCO
from pycocotools.cocoeval import COCOeval

# pycocotools 2.0.11 calls np.array(copy=False) on its own RLE objects under NumPy 2
pytestmark = pytest.mark.filterwarnings("ignore:__array__ implementation:DeprecationWarning")


def load(dataset):
    with contextlib.redirect_stdout(io.StringIO()):
        return COCO(str(dataset / "annotations.json"))


def test_self_evaluation_gives_ap_1_for_bbox_and_segm(dataset):
    gt = load(dataset)
    detections = [{**a, "score": 1.0} for a in gt.dataset["annotations"]]
    assert len(detections) > 20
    with contextlib.redirect_stdout(io.StringIO()):
        dt = gt.loadRes(detections)
        for iou_type in ("bbox", "segm"):
            ev = COCOeval(gt, dt, iou_type)
            ev.evaluate()
            ev.accumulate()
            ev.summarize()
            assert ev.stats[0] == 1.0, iou_type  # AP@[.5:.95]


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
    for img in coco.dataset["images"]:
        stem = img["file_name"].split("/")[-1]
        instances = np.asarray(Image.open(dataset / "instance" / stem))
        record = json.loads((dataset / "frames" / stem.replace(".png", ".json")).read_text())
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
