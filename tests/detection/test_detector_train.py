"""Training on a generated dataset: the loss falls, pycocotools reads the predictions, a resume
continues from the checkpoint's step, a time budget stops and anneals a run; the decoding by hand."""

import json

import pytest
import torch
from pycocotools.coco import COCO

from ambulo.detection import TrainCfg, coco_metrics, decode, load_trained, no_augment, predict_coco, train
from ambulo.detection.dataset import CocoFrames, collate, load_coco, split_image_ids
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
    logged = json.loads((tmp_path / "metrics.json").read_text())[-1]
    assert logged["step"] == result.step
    assert logged["train_loss"] == pytest.approx(sum(losses) / len(losses), abs=1e-4)  # one evaluation: every step
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


def test_time_budget_stops_evaluates_and_a_pause_resumes(tiny_dataset, tmp_path):
    # a budget ends the run inside its epochs, with the final evaluation (masks too) and an annealed rate
    budget = train(tiny_dataset, tmp_path / "budget", tiny_cfg(epochs=10_000, max_minutes=0.02, warmup_steps=0),
                   show_progress=False)
    assert budget.stopped == "budget" and budget.epoch < 9_999 and budget.elapsed_s >= 1.2
    assert budget.evaluations[-1]["step"] == budget.step and "mask" in budget.evaluations[-1]
    _, state = load_trained(tmp_path / "budget" / "checkpoint.pt")
    assert state["optimizer"]["param_groups"][0]["lr"] < 0.2 * 3e-3
    # a pause checkpoints without evaluating; the resume counts the time already spent
    paused = train(tiny_dataset, tmp_path / "pause", tiny_cfg(epochs=10_000, max_minutes=10.0,
                                                             pause_after_minutes=0.01), show_progress=False)
    assert paused.stopped == "pause" and paused.evaluations == []
    assert load_trained(tmp_path / "pause" / "checkpoint.pt")[1]["elapsed_s"] == paused.elapsed_s
    resumed = train(tiny_dataset, tmp_path / "pause", tiny_cfg(epochs=paused.epoch + 2, max_minutes=10.0),
                    resume=True, show_progress=False)
    assert resumed.stopped == "epochs" and resumed.losses[0][0] == paused.step + 1
    assert resumed.elapsed_s > paused.elapsed_s and resumed.evaluations[-1]["elapsed_s"] >= paused.elapsed_s


def test_a_missing_frame_file_is_one_line_in_both_readers(tiny_dataset, tmp_path):
    import shutil

    from ambulo.detection.dataset import DatasetError
    from ambulo.detection.frames import FrameRecords

    data = tmp_path / "data"
    shutil.copytree(tiny_dataset, data)
    coco = load_coco(data)
    first = coco["images"][0]
    (data / first["file_name"]).unlink()
    readers = (CocoFrames(data, coco, [first["id"]], (128, 160)),
               FrameRecords(data, coco, [first["id"]], {c["id"]: k for k, c in enumerate(coco["categories"])}))
    for reader in readers:
        with pytest.raises(DatasetError) as err:
            reader[0]
        message = str(err.value)
        assert "\n" not in message and first["file_name"] in message and "ambulo generate" in message
