"""The training-curve picture: scores and loss against minutes from a run's metrics.json, and the loss
of an older run (no ``train_loss``) from its TensorBoard events, placed by the evaluations' clock."""

import json

import imageio.v3 as iio
import numpy as np
import pytest

from ambulo.detection.curve import plot_curve, read_curve


def evaluation(step: int, seconds: float, map50: float, **extra) -> dict:
    return {"epoch": step // 10, "step": step, "elapsed_s": seconds, "mAP": map50 / 2, "mAP50": map50,
            "per_class": {}, **extra}


def test_curve_reads_scores_and_loss_and_draws_them(tmp_path):
    entries = [evaluation(10, 30.0, 0.2, train_loss=3.0), evaluation(20, 60.0, 0.5, train_loss=2.0),
               evaluation(30, 90.0, 0.7, train_loss=1.5, mask={"mAP": 0.3, "mAP50": 0.6, "per_class": {}})]
    (tmp_path / "metrics.json").write_text(json.dumps(entries))
    curve = read_curve(tmp_path)
    assert curve["minutes"].tolist() == [0.5, 1.0, 1.5] and curve["mAP50"].tolist() == [0.2, 0.5, 0.7]
    assert curve["loss"].tolist() == [3.0, 2.0, 1.5] and curve["loss_minutes"].tolist() == [0.5, 1.0, 1.5]
    assert np.isnan(curve["mask_mAP50"][:2]).all() and curve["mask_mAP50"][2] == 0.6
    png = plot_curve(tmp_path / "metrics.json", tmp_path / "curve.png")
    assert iio.imread(png).shape[:2] == (480, 840)


def test_an_older_runs_loss_comes_from_its_events(tmp_path):
    from torch.utils.tensorboard import SummaryWriter

    writer = SummaryWriter(log_dir=str(tmp_path))
    for step in range(0, 101, 20):
        writer.add_scalar("loss/total", 5.0 - step / 25, step)
    writer.close()
    (tmp_path / "metrics.json").write_text(json.dumps([evaluation(100, 120.0, 0.9)]))
    curve = read_curve(tmp_path)
    # steps 0..100 over the evaluation's 2 minutes: step 20 at 0.4 min
    assert curve["loss_minutes"] == pytest.approx([0.0, 0.4, 0.8, 1.2, 1.6, 2.0])
    assert curve["loss"] == pytest.approx([5.0, 4.2, 3.4, 2.6, 1.8, 1.0])


def test_a_run_without_evaluations_is_refused(tmp_path):
    (tmp_path / "metrics.json").write_text("[]")
    with pytest.raises(ValueError, match="no evaluation"):
        read_curve(tmp_path)
