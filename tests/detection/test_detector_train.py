"""Training on a generated dataset: the loss falls, pycocotools reads the predictions, a resume
continues from the checkpoint's step; the decoding and the augmentations' box arithmetic by hand."""

import json

import torch
from pycocotools.coco import COCO

from ambulo.detection import TrainCfg, coco_metrics, decode, load_trained, no_augment, predict_coco, train
from ambulo.detection.dataset import AugmentCfg, CocoFrames, augment_sample, collate, load_coco, split_image_ids
from ambulo.detection.model import STRIDE_OUT


def tiny_cfg(**overrides) -> TrainCfg:
    base = dict(epochs=1, batch_size=8, learning_rate=3e-3, warmup_steps=0, num_workers=0, eval_every_epochs=0,
                held_out_fraction=0.25, augment=no_augment())
    return TrainCfg(**{**base, **overrides})


def test_loss_falls_and_pycocotools_evaluates_the_predictions(tiny_dataset, tmp_path):
    result = train(tiny_dataset, tmp_path, tiny_cfg(epochs=10), show_progress=False)
    losses = [loss for _, loss in result.losses]
    assert len(losses) == 10  # 6 training frames: one batch per epoch
    assert sum(losses[-3:]) / 3 < 0.7 * sum(losses[:3]) / 3, losses
    evaluation = result.evaluations[-1]
    categories = {c["name"] for c in load_coco(tiny_dataset)["categories"]}
    assert set(evaluation["per_class"]) <= categories and 0.0 <= evaluation["mAP"] <= evaluation["mAP50"] <= 1.0
    assert json.loads((tmp_path / "metrics.json").read_text())[-1]["step"] == result.step
    # the predictions are a COCO results list pycocotools loads, every one on a held-out frame
    coco = load_coco(tiny_dataset)
    _, held = split_image_ids(coco, 0.25)
    model, _ = load_trained(tmp_path / "checkpoint.pt")
    canvas = (128, 160)
    loader = torch.utils.data.DataLoader(CocoFrames(tiny_dataset, coco, held, canvas), batch_size=2,
                                         collate_fn=collate)
    results = predict_coco(model, loader, torch.device("cpu"), [c["id"] for c in coco["categories"]])
    assert len(results) == len(held) * model.cfg.max_detections
    gt = COCO(str(tiny_dataset / "annotations.json"))
    loaded = gt.loadRes(results)
    assert len(loaded.getAnnIds()) == len(results)
    assert {a["image_id"] for a in loaded.dataset["annotations"]} == set(held)
    # ground truth as predictions scores 1: the evaluation itself is right
    perfect = [{"image_id": a["image_id"], "category_id": a["category_id"], "bbox": a["bbox"], "score": 1.0}
               for a in coco["annotations"] if a["image_id"] in held]
    assert coco_metrics(coco, held, perfect)["mAP"] > 0.99


def test_resume_continues_from_the_checkpoint_step(tiny_dataset, tmp_path):
    first = train(tiny_dataset, tmp_path, tiny_cfg(epochs=1, batch_size=3), show_progress=False)
    assert first.step == 2 and first.epoch == 0
    saved, _ = load_trained(tmp_path / "checkpoint.pt")
    second = train(tiny_dataset, tmp_path, tiny_cfg(epochs=2, batch_size=3), resume=True, show_progress=False)
    assert [step for step, _ in second.losses] == [3, 4] and second.epoch == 1
    _, state = load_trained(tmp_path / "checkpoint.pt")
    assert state["step"] == 4 and state["epoch"] == 1
    assert state["optimizer"]["state"][0]["step"].item() == 4  # AdamW's moments went on, not restarted
    restarted = train(tiny_dataset, tmp_path / "fresh", tiny_cfg(epochs=2, batch_size=3), show_progress=False)
    assert restarted.losses[0][0] == 1
    assert saved is not None


def test_decode_reads_a_peak_as_its_box():
    heat = torch.full((1, 2, 8, 10), -10.0)
    heat[0, 1, 5, 3] = 3.0  # class 1 at cell (x 3, y 5)
    size = torch.zeros(1, 2, 8, 10)
    size[0, :, 5, 3] = torch.tensor([4.0, 2.0])  # 16 x 8 px
    offset = torch.zeros(1, 2, 8, 10)
    offset[0, :, 5, 3] = torch.tensor([0.5, 0.25])
    boxes, scores, classes = decode({"heat": heat, "size": size, "offset": offset}, max_detections=3)
    cx, cy = (3 + 0.5) * STRIDE_OUT, (5 + 0.25) * STRIDE_OUT
    assert torch.allclose(boxes[0, 0], torch.tensor([cx - 8, cy - 4, cx + 8, cy + 4]))
    assert classes[0, 0] == 1 and abs(scores[0, 0].item() - torch.sigmoid(torch.tensor(3.0)).item()) < 1e-6
    assert scores[0, 1] < 1e-4  # the neighbours of a peak are no peaks


def test_flip_and_scale_move_boxes_with_the_pixels():
    rgb = torch.zeros(3, 20, 30)
    rgb[:, 4:10, 2:8] = 1.0  # an object at x 2..8, y 4..10
    boxes, labels = torch.tensor([[2.0, 4.0, 8.0, 10.0]]), torch.tensor([1])
    g = torch.Generator().manual_seed(0)
    flipped, fb, _, _ = augment_sample(rgb, boxes, labels, AugmentCfg(flip_probability=1.0, scale_range=(1.0, 1.0),
                                                                   brightness_fraction=0.0), g)
    assert torch.equal(fb, torch.tensor([[22.0, 4.0, 28.0, 10.0]]))
    assert flipped[0, 4:10, 22:28].min() == 1 and flipped[0].sum() == 36
    # scale 0.5: the halved image lands somewhere in a black window of the input's size; the box moves with it
    scaled, sb, sl, _ = augment_sample(rgb, boxes, labels, AugmentCfg(flip_probability=0.0, scale_range=(0.5, 0.5),
                                                                   brightness_fraction=0.0), g)
    x0, y0, x1, y1 = sb[0].round().int().tolist()
    inside = scaled[0, y0:y1, x0:x1]
    assert (x1 - x0, y1 - y0) == (3, 3) and inside.min() == 1 and scaled[0].sum() == inside.sum() == 9
    assert sl.tolist() == [1]
