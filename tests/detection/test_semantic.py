"""``detection.semantic``: the semantic image painted from detections (highest score on top, a score
threshold, the dataset's category ids) and its mIoU / per-class IoU / pixel accuracy, hand-computed."""

from types import SimpleNamespace

import numpy as np
import pytest
from pycocotools import mask as mask_utils

from ambulo.detection.detector import Detections
from ambulo.detection.evaluate import evaluate_all
from ambulo.detection.semantic import metrics_of_confusion, semantic_image, semantic_metrics


def rle(mask: np.ndarray) -> dict:
    encoded = mask_utils.encode(np.asfortranarray(mask.astype(np.uint8)))
    return {"size": [int(v) for v in encoded["size"]], "counts": encoded["counts"].decode()}


def block(shape, rows, cols) -> np.ndarray:
    mask = np.zeros(shape, bool)
    mask[rows, cols] = True
    return mask


def test_overlapping_detections_resolve_by_score_and_threshold():
    masks = np.stack([block((3, 4), slice(None), slice(0, 3)), block((3, 4), slice(None), slice(1, 4))])
    # listed low score first: the order of the array must not matter, only the scores
    low_first = SimpleNamespace(masks=masks, category_ids=np.array([5, 7]), scores=np.array([0.4, 0.9]))
    assert semantic_image(low_first, (3, 4)).tolist() == [[5, 7, 7, 7]] * 3
    high_first = SimpleNamespace(masks=masks, category_ids=np.array([5, 7]), scores=np.array([0.9, 0.4]))
    image = semantic_image(high_first, (3, 4))
    assert image.dtype == np.uint8 and image.tolist() == [[5, 5, 5, 7]] * 3
    # below the threshold a detection is not painted, even where nothing else covers the pixel
    assert semantic_image(high_first, (3, 4), threshold=0.5).tolist() == [[5, 5, 5, 0]] * 3
    assert semantic_image(SimpleNamespace(masks=None, category_ids=[], scores=[]), (2, 3)).tolist() == [[0] * 3] * 2
    with pytest.raises(ValueError, match="1..255"):
        semantic_image(SimpleNamespace(masks=masks, category_ids=np.array([5, 300]), scores=np.ones(2)), (3, 4))


def test_detections_paint_their_own_semantic_image():
    """What the ROS 2 bridge publishes: ``Detections.semantic_image``, None for a box-only model."""
    masks = np.stack([block((2, 3), slice(None), slice(0, 2)), block((2, 3), 0, slice(None))])
    found = Detections(boxes_px=np.zeros((2, 4), np.float32), labels=["a", "b"], category_ids=np.array([1, 3]),
                       scores=np.array([0.8, 0.5], np.float32), masks=masks)
    assert found.semantic_image().tolist() == [[1, 1, 3], [1, 1, 0]]
    assert Detections(found.boxes_px, found.labels, found.category_ids, found.scores).semantic_image() is None


def coco_of(gt_masks: dict[int, np.ndarray], shape) -> dict:
    """One image of ``shape`` with one annotation of each {category id: mask}; categories 1 'a', 2 'b'."""
    anns = [{"id": k + 1, "image_id": 1, "category_id": cid, "segmentation": rle(m), "iscrowd": 0,
             "area": int(m.sum()), "bbox": mask_utils.toBbox(mask_utils.encode(np.asfortranarray(m.astype(np.uint8)))
                                                            ).tolist()}
            for k, (cid, m) in enumerate(gt_masks.items())]
    return {"images": [{"id": 1, "width": shape[1], "height": shape[0], "file_name": "x.png"}], "annotations": anns,
            "categories": [{"id": 1, "name": "a"}, {"id": 2, "name": "b"}]}


def test_two_masks_of_known_overlap_give_known_iou():
    # ground truth: a 4x4 square of category 1 in an 8x8 image; predicted: the same square 2 px to the right
    # class a: overlap 4x2 = 8 px, union 16 + 16 - 8 = 24 -> IoU 1/3
    # background: 48 px each, both background 64 - 24 = 40 px -> IoU 40 / (48 + 48 - 40) = 5/7
    # pixel accuracy: (8 + 40) / 64 = 0.75; class b is in neither: no IoU, not in the mean
    shape = (8, 8)
    coco = coco_of({1: block(shape, slice(2, 6), slice(1, 5))}, shape)
    predicted = [{"image_id": 1, "category_id": 1, "score": 0.9, "segmentation": rle(block(shape, slice(2, 6), slice(3, 7))),
                  "bbox": [3, 2, 4, 4]},
                 {"image_id": 1, "category_id": 2, "score": 0.1,  # below the threshold: not painted
                  "segmentation": rle(block(shape, slice(0, 8), slice(0, 8))), "bbox": [0, 0, 8, 8]}]
    got = semantic_metrics(coco, [1], predicted, threshold=0.3)
    assert got["per_class"] == pytest.approx({"background": 5 / 7, "a": 1 / 3})
    assert got["mIoU"] == pytest.approx((5 / 7 + 1 / 3) / 2) and got["pixel_acc"] == pytest.approx(0.75)
    # the weak detection over the whole image, when kept, wins nowhere it is outscored and everywhere else
    kept = semantic_metrics(coco, [1], predicted, threshold=0.0)
    assert kept["per_class"] == pytest.approx({"background": 0.0, "a": 1 / 3, "b": 0.0})
    assert kept["pixel_acc"] == pytest.approx(8 / 64)


def test_confusion_matrix_metrics():
    # rows ground truth, columns predicted: class 1 TP 6, FN 2 (as 0), FP 1 (0 predicted as 1); class 2 never seen
    confusion = np.array([[10, 1, 0], [2, 6, 0], [0, 0, 0]])
    got = metrics_of_confusion(confusion, ["background", "x", "y"])
    assert got["per_class"] == pytest.approx({"background": 10 / 13, "x": 6 / 9})
    assert got["pixel_acc"] == pytest.approx(16 / 19) and got["mIoU"] == pytest.approx((10 / 13 + 6 / 9) / 2)


def test_evaluation_reports_semantic_for_masks_only(tmp_path, shapes_dataset, perfect_results):
    from ambulo.detection import load_coco

    root = shapes_dataset(tmp_path / "shapes", num_frames=3)
    coco = load_coco(root)
    ids = [im["id"] for im in coco["images"]]
    perfect = perfect_results(coco)
    metrics = evaluate_all(coco, ids, perfect)
    assert metrics["semantic"]["mIoU"] == 1.0 and metrics["semantic"]["pixel_acc"] == 1.0
    assert metrics["semantic"]["per_class"] == {"background": 1.0, "disc": 1.0, "square": 1.0}
    # discs predicted as squares: the disc pixels are all wrong, the square's IoU falls by their share
    swapped = [{**r, "category_id": 2} for r in perfect]
    semantic = evaluate_all(coco, ids, swapped)["semantic"]
    assert semantic["per_class"]["disc"] == 0.0 and 0.0 < semantic["per_class"]["square"] < 1.0
    disc_px = sum(a["area"] for a in coco["annotations"] if a["category_id"] == 1)
    assert semantic["pixel_acc"] == pytest.approx(1 - disc_px / (3 * 64 * 64))
    boxes_only = [{k: v for k, v in r.items() if k != "segmentation"} for r in perfect]
    assert "semantic" not in evaluate_all(coco, ids, boxes_only) and "mask" not in evaluate_all(coco, ids, boxes_only)
