"""A trained detector scored on any ``ambulo generate`` dataset: the issue's domain-gap splits.

Training evaluates on its own held-out frames (split (a): unseen seeds of the training
distribution). ``evaluate_checkpoint`` scores the same checkpoint on another dataset, e.g. one whose
textures, lighting, clutter and camera heights were never seen in training (split (b),
``benchmarks/detect_domain_gap.py`` makes one), or one drawn by another renderer (split (c),
``ambulo generate --renderer pbr``). Categories are matched by name, so the other dataset may number
them differently; its frames must fit the checkpoint's canvas (the model's input size).
"""

from __future__ import annotations

from pathlib import Path

import torch

from .dataset import CocoFrames, DatasetError, collate, load_coco, split_image_ids
from .evaluate import evaluate_all, predict_coco
from .train import load_trained


def evaluate_checkpoint(checkpoint: str | Path, dataset_dir: str | Path, held_out_fraction: float | None = None,
                        batch_size: int = 16, device: str = "cpu", num_workers: int = 0, masks: bool = True) -> dict:
    """``evaluate_all`` (boxes, and masks for a model with them unless ``masks`` is False: pasting and
    encoding every detection's mask is most of a CPU's scoring time) of ``checkpoint`` on the frames of
    ``dataset_dir``: all of them, or with ``held_out_fraction`` only the last fraction (the split
    training holds out), plus ``"frames"``: how many were scored."""
    model, state = load_trained(checkpoint, device)
    coco = load_coco(dataset_dir)
    by_name = {c["name"]: c["id"] for c in coco["categories"]}
    missing = [name for name in state["categories"] if name not in by_name]
    if missing:
        raise DatasetError(f"{dataset_dir} has no categories {missing} the detector was trained on",
                           f"evaluate on a dataset of the categories {state['categories']}")
    category_ids = [by_name[name] for name in state["categories"]]
    if held_out_fraction is None:
        image_ids = sorted(im["id"] for im in coco["images"])
    else:
        _, image_ids = split_image_ids(coco, held_out_fraction)
    canvas_hw = tuple(state["canvas_hw"])
    too_big = [im["id"] for im in coco["images"] if im["height"] > canvas_hw[0] or im["width"] > canvas_hw[1]]
    if too_big:
        raise DatasetError(f"{len(too_big)} frames of {dataset_dir} are larger than the detector's "
                           f"{canvas_hw[1]}x{canvas_hw[0]} input", "generate the dataset at the training size")
    # ground truth of categories the detector was never trained on is left out: it cannot find them
    coco = {**coco, "categories": [c for c in coco["categories"] if c["id"] in category_ids]}
    coco["annotations"] = [a for a in coco["annotations"] if a["category_id"] in category_ids]
    loader = torch.utils.data.DataLoader(CocoFrames(dataset_dir, coco, image_ids, canvas_hw,
                                                    depth=model.cfg.inputs in ("rgbd", "rgbdh"),
                                                    height=model.cfg.inputs == "rgbdh"), batch_size=batch_size,
                                         num_workers=num_workers, collate_fn=collate)
    sizes = {im["id"]: (im["height"], im["width"]) for im in coco["images"]} if masks else None
    results = predict_coco(model, loader, torch.device(device), category_ids, sizes)
    return {**evaluate_all(coco, image_ids, results), "frames": len(image_ids)}


__all__ = ["evaluate_checkpoint"]
