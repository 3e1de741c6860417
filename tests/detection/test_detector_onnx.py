"""`ambulo train-detector` then `ambulo export-detector`: ONNX Runtime agrees with torch, and the
``Detector`` runs a frame through either."""

import imageio.v3 as iio
import numpy as np
import pytest

from ambulo.cli import main
from ambulo.detection import Detector, check_onnx
from ambulo.detection.export import compare_detections


def test_cli_trains_exports_and_onnx_matches_torch(tiny_dataset, tmp_path, capsys):
    run = tmp_path / "run"
    assert main(["train-detector", str(tiny_dataset), "--epochs", "2", "--batch-size", "8", "--workers", "0",
                 "--out", str(run), "--quiet"]) == 0
    out = capsys.readouterr().out
    assert "mAP50" in out and "held-out semantic: mIoU" in out  # a mask model's evaluation prints its semantic line
    assert main(["train-detector", str(tiny_dataset), "--out", str(run), "--quiet"]) == 2  # no silent overwrite
    onnx_path = run / "model.onnx"
    assert main(["export-detector", str(run / "checkpoint.pt"), "--out", str(onnx_path)]) == 0
    frame = iio.imread(tiny_dataset / "rgb" / "000007.png")[..., :3]
    canvas = np.zeros((1, 3, 128, 160), np.float32)
    canvas[0, :, :120, :] = frame.transpose(2, 0, 1) / 255.0
    diff = check_onnx(run / "checkpoint.pt", onnx_path, canvas)
    # a model trained two steps has near-flat heatmaps: a few peaks tie with a neighbour to float rounding
    assert diff["compared"] >= 10 and diff["unmatched"] <= 0.05 * diff["compared"], diff
    assert diff["boxes_px"] < 1e-3 and diff["scores"] < 1e-5 and diff["masks"] < 1e-4, diff
    by_onnx, by_torch = Detector(onnx_path, 0.0)(frame), Detector(run / "checkpoint.pt", 0.0)(frame)
    assert len(by_onnx.scores) == len(by_torch.scores) == 100
    # near-flat heatmaps: a peak tied with a neighbour to float rounding is kept once or twice on the
    # runtime's last bit (as compare_detections' `unmatched`), so each score needs a partner in the
    # other list, not a sorted pairing; at most 5 % may lack one
    for a, b in ((by_onnx.scores, by_torch.scores), (by_torch.scores, by_onnx.scores)):
        partnered = (np.abs(a[:, None] - b[None, :]) <= 1e-5).any(axis=1)
        assert partnered.mean() >= 0.95, np.sort(a[~partnered])
    assert by_onnx.boxes_px.shape == (100, 4) and (by_onnx.boxes_px[:, 2] <= 160).all()
    assert set(by_onnx.labels) <= {"ball", "box", "can", "cone"}
    # the masks of the same detections, pasted to the frame: equal but for pixels at the threshold
    assert by_onnx.masks.shape == by_torch.masks.shape == (100, 120, 160)
    order_onnx, order_torch = np.lexsort(by_onnx.boxes_px.T), np.lexsort(by_torch.boxes_px.T)
    differ = by_onnx.masks[order_onnx] != by_torch.masks[order_torch]
    assert differ.mean() < 1e-3, differ.mean()


def test_comparison_sees_a_moved_box():
    boxes = np.array([[[0, 0, 10, 10], [5, 5, 9, 9], [1, 1, 2, 2]]], np.float32)
    scores, classes = np.array([[0.9, 0.5, 0.1]], np.float32), np.array([[0, 1, 1]])
    same = compare_detections([boxes, scores, classes], [boxes[:, ::-1], scores[:, ::-1], classes[:, ::-1]])
    assert same == {"scores": 0.0, "boxes_px": 0.0, "compared": 2, "unmatched": 0}  # the last is at the cut-off
    moved = boxes.copy()
    moved[0, 1, 0] += 0.005
    assert compare_detections([boxes, scores, classes], [moved, scores, classes])["boxes_px"] == pytest.approx(0.005, abs=1e-6)
    nudged = scores.copy()
    nudged[0, 0] += 5e-5  # a matched box's score, within the matching tolerance
    assert compare_detections([boxes, scores, classes], [boxes, nudged, classes])["scores"] == pytest.approx(5e-5, abs=1e-7)
    moved[0, 1, 0] += 4.0  # a cell away
    assert compare_detections([boxes, scores, classes], [moved, scores, classes])["unmatched"] == 1


def test_a_folder_that_is_no_dataset_is_one_line(tmp_path, capsys):
    assert main(["train-detector", str(tmp_path), "--out", str(tmp_path / "run"), "--quiet"]) == 2
    err = capsys.readouterr().err.strip()
    assert err.count("\n") == 0 and "no annotations.json" in err and "ambulo generate" in err
