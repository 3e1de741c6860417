"""The training curve of a detector run: held-out mAP and mAP50 (boxes, and masks where scored) and the
training loss against wall-clock minutes, from the run's ``metrics.json`` (matplotlib, imported on
use: it is a dev extra).

    python -m ambulo.detection.curve runs/det docs/images/detector_curve.png

The loss is each evaluation's ``train_loss`` (the mean since the evaluation before). A run written
before that field existed has it only in its TensorBoard events (``loss/total`` by step): those are
read instead and put on the minutes axis by interpolating the evaluations' (step, elapsed) pairs,
so the picture of an older run still shows its loss.
"""

from __future__ import annotations

import argparse
import json
import os
from pathlib import Path

import numpy as np


def read_curve(run: str | os.PathLike) -> dict[str, np.ndarray]:
    """Arrays of a run folder (or its ``metrics.json``): ``minutes``, ``mAP``, ``mAP50``, ``mask_mAP``,
    ``mask_mAP50`` (NaN where an evaluation scored boxes only) at each evaluation, and ``loss_minutes``,
    ``loss`` (empty if the run logged none)."""
    path = Path(run)
    metrics = path / "metrics.json" if path.is_dir() else path
    entries = json.loads(metrics.read_text())
    if not entries:
        raise ValueError(f"{metrics} holds no evaluation: train at least until the first one")
    curve = {"minutes": np.array([e["elapsed_s"] / 60 for e in entries]),
             "mAP": np.array([e["mAP"] for e in entries]), "mAP50": np.array([e["mAP50"] for e in entries]),
             "mask_mAP": np.array([e["mask"]["mAP"] if "mask" in e else np.nan for e in entries]),
             "mask_mAP50": np.array([e["mask"]["mAP50"] if "mask" in e else np.nan for e in entries])}
    with_loss = [e for e in entries if "train_loss" in e]
    if with_loss:
        curve["loss_minutes"] = np.array([e["elapsed_s"] / 60 for e in with_loss])
        curve["loss"] = np.array([e["train_loss"] for e in with_loss])
    else:
        steps, losses = _tensorboard_loss(metrics.parent)
        # step -> minutes through the evaluations' clock (and step 0 at minute 0)
        known_steps = np.array([0] + [e["step"] for e in entries], float)
        known_minutes = np.concatenate([[0.0], curve["minutes"]])
        curve["loss_minutes"] = np.interp(steps, known_steps, known_minutes)
        curve["loss"] = losses
    return curve


def _tensorboard_loss(run_dir: Path) -> tuple[np.ndarray, np.ndarray]:
    """(steps, total loss) of the ``loss/total`` scalars in the run's event files; empty without them."""
    try:
        from tensorboard.backend.event_processing.event_accumulator import EventAccumulator
    except ImportError:
        return np.zeros(0), np.zeros(0)
    steps, values = [], []
    for events in sorted(run_dir.glob("events.out.tfevents.*")):
        acc = EventAccumulator(str(events), size_guidance={"scalars": 0})
        acc.Reload()
        if "loss/total" in acc.Tags().get("scalars", []):
            for event in acc.Scalars("loss/total"):
                steps.append(event.step)
                values.append(event.value)
    order = np.argsort(steps, kind="stable")
    return np.array(steps, float)[order], np.array(values, float)[order]


def plot_curve(run: str | os.PathLike, path_png: str | os.PathLike, title: str | None = None) -> Path:
    """Write the PNG of ``read_curve(run)``: scores (left axis, 0-1) and loss (right axis) against minutes."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    curve = read_curve(run)
    fig, ax = plt.subplots(figsize=(7, 4), dpi=120)
    marker = "o" if len(curve["minutes"]) < 30 else None
    ax.plot(curve["minutes"], curve["mAP50"], marker=marker, color="tab:blue", label="boxes mAP50")
    ax.plot(curve["minutes"], curve["mAP"], marker=marker, color="tab:blue", ls="--", label="boxes mAP")
    if np.isfinite(curve["mask_mAP50"]).any():
        scored = np.isfinite(curve["mask_mAP50"])
        ax.plot(curve["minutes"][scored], curve["mask_mAP50"][scored], "s", color="tab:green", label="masks mAP50")
        ax.plot(curve["minutes"][scored], curve["mask_mAP"][scored], "D", color="tab:green", mfc="none",
                label="masks mAP")
    ax.set_ylim(0, 1)
    ax.set_xlim(left=0)
    ax.set_xlabel("training time (min, data loading and evaluations included)")
    ax.set_ylabel("held-out score")
    ax.grid(alpha=0.3)
    handles, labels = ax.get_legend_handles_labels()
    if len(curve["loss"]):
        loss_ax = ax.twinx()
        line, = loss_ax.plot(curve["loss_minutes"], curve["loss"], color="tab:red", lw=0.8, alpha=0.8,
                             label="training loss")
        loss_ax.set_ylabel("training loss (total)")
        loss_ax.set_ylim(bottom=0)
        handles.append(line)
        labels.append(line.get_label())
    ax.legend(handles, labels, loc="center right", fontsize=8)
    last = f"last: mAP50 {curve['mAP50'][-1]:.3f}, mAP {curve['mAP'][-1]:.3f} at {curve['minutes'][-1]:.1f} min"
    ax.set_title(title or f"detector training ({last})", fontsize=10)
    fig.tight_layout()
    fig.savefig(os.fspath(path_png))
    plt.close(fig)
    return Path(path_png)


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("run", help="a train-detector run folder or its metrics.json")
    parser.add_argument("png", help="the picture to write")
    parser.add_argument("--title", default=None)
    args = parser.parse_args(argv)
    print(plot_curve(args.run, args.png, args.title))


if __name__ == "__main__":
    main()
