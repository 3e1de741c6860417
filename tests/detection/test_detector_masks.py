"""Instance masks: the mask head learns shapes that differ from their boxes, ``paste_masks`` by hand,
and pycocotools scores masks ('segm'); masks under augmentation: test_detector_augment.py."""

import torch

from ambulo.detection import TrainCfg, load_trained, no_augment, train
from ambulo.detection.dataset import CocoFrames, collate, load_coco
from ambulo.detection.evaluate import evaluate_all, predict_coco
from ambulo.detection.frames import pad_rows
from ambulo.detection.loss import targets
from ambulo.detection.model import paste_masks


def mask_ious_at_true_centres(model, root) -> dict[int, list[float]]:
    """IoU of each object's predicted mask (its true centre cell's coefficients, cut to its true box)
    with its true mask, per category id: the mask head alone, whatever the heatmap does."""
    coco = load_coco(root)
    frames = CocoFrames(root, coco, [im["id"] for im in coco["images"]], (64, 64), masks=True)
    images, truth = collate([frames[i] for i in range(len(frames))])
    with torch.no_grad():
        maps = model(images)
    p, h, w = maps["proto"].shape[1:]
    classes = pad_rows([t["labels"] - 1 for t in truth], -1)
    _, boxes = targets(pad_rows([t["boxes"] for t in truth], 0.0), classes, 2, (h, w))
    ious: dict[int, list[float]] = {1: [], 2: []}
    for i, t in enumerate(truth):
        cell = boxes["cell"][i, :len(t["boxes"])]
        coef = maps["coef"][i, :, cell[:, 1], cell[:, 0]].T
        probability = torch.sigmoid(coef @ maps["proto"][i].reshape(p, -1)).reshape(-1, h, w)
        for predicted, true, category in zip(paste_masks(probability, t["boxes"], (64, 64)), t["masks"],
                                             t["labels"].tolist()):
            ious[category].append(((predicted & true).sum() / (predicted | true).sum()).item())
    return ious


def test_mask_head_learns_discs_and_squares(trained_shapes):
    root, checkpoint = trained_shapes
    model, _ = load_trained(checkpoint)
    ious = mask_ious_at_true_centres(model, root)
    mean = {category: sum(v) / len(v) for category, v in ious.items()}
    # a disc filling its box scores pi/4 = 0.785: above that, the mask has the disc's shape
    assert mean[1] > 0.85 and mean[2] > 0.75, ious


def test_paste_masks_by_hand():
    probability = torch.zeros(2, 4, 5)  # two detections, 4 x 5 cells: 16 x 20 px
    probability[0, 1, 2] = 1.0  # cell (x 2, y 1): pixels x 8..12, y 4..8
    probability[1] = 1.0
    boxes = torch.tensor([[0.0, 0.0, 20.0, 16.0], [3.2, 2.0, 9.5, 6.0]])
    masks = paste_masks(probability, boxes, (15, 20))
    assert masks.shape == (2, 15, 20) and masks.dtype == torch.bool
    # bilinear from the cell's centre (pixel edge 10, 6): above one half on its own 4 x 4 pixels but their
    # corners (0.625 along each axis, 0.39 together)
    ys, xs = torch.nonzero(masks[0], as_tuple=True)
    assert (ys.min(), ys.max(), xs.min(), xs.max()) == (4, 7, 8, 11) and masks[0].sum() == 12
    assert not masks[0, 4, 8] and masks[0, 4, 9] and masks[0, 5, 8]
    # all ones, cut to the box widened to whole pixels: x 3..10, y 2..6
    ys, xs = torch.nonzero(masks[1], as_tuple=True)
    assert (ys.min(), ys.max(), xs.min(), xs.max()) == (2, 5, 3, 9) and masks[1].sum() == 4 * 7


def test_pycocotools_scores_masks(tmp_path, shapes_dataset, perfect_results):
    root = shapes_dataset(tmp_path / "shapes", num_frames=3)
    coco = load_coco(root)
    ids = [im["id"] for im in coco["images"]]
    perfect = perfect_results(coco)
    metrics = evaluate_all(coco, ids, perfect)
    assert metrics["mask"]["mAP"] > 0.99 and metrics["mAP"] > 0.99
    # the boxes filled in as masks: perfect boxes, imperfect discs
    boxy = [{**entry, "segmentation": box_rle(entry["bbox"], 64)} for entry in perfect]
    boxy_metrics = evaluate_all(coco, ids, boxy)
    assert boxy_metrics["mAP"] > 0.99 and boxy_metrics["mask"]["per_class"]["disc"] < 0.9
    # a model's predictions carry RLEs of the image's size that pycocotools reads
    cfg = TrainCfg(epochs=1, batch_size=3, warmup_steps=0, num_workers=0, eval_every_epochs=0, held_out_fraction=0.0,
                   augment=no_augment())
    train(root, tmp_path / "run", cfg, show_progress=False)
    model, _ = load_trained(tmp_path / "run" / "checkpoint.pt")
    loader = torch.utils.data.DataLoader(CocoFrames(root, coco, ids, (64, 64)), batch_size=2, collate_fn=collate)
    results = predict_coco(model, loader, torch.device("cpu"), [1, 2], {i: (64, 64) for i in ids})
    assert len(results) == len(ids) * model.cfg.max_detections
    assert all(r["segmentation"]["size"] == [64, 64] for r in results)
    got = evaluate_all(coco, ids, results)
    assert 0.0 <= got["mask"]["mAP"] <= got["mask"]["mAP50"] <= 1.0


def box_rle(bbox, size_px: int) -> dict:
    import numpy as np
    from pycocotools import mask as mask_utils

    x, y, w, h = bbox
    mask = np.zeros((size_px, size_px), np.uint8, order="F")
    mask[round(y):round(y + h), round(x):round(x + w)] = 1
    rle = mask_utils.encode(mask)
    return {"size": [size_px, size_px], "counts": rle["counts"].decode()}
