"""Training a detector on an ``ambulo generate`` dataset: AMP on CUDA, checkpoints, resume, TensorBoard,
COCO evaluation on held-out frames every ``eval_every_epochs``.

The run folder holds ``checkpoint.pt`` (model, optimizer, AMP scaler, epoch, step, the configs and
category names: all a resume or an export needs), ``metrics.json`` (every evaluation) and the
TensorBoard events (``loss/*``, ``lr``, ``eval/mAP``, ``eval/mAP50``, ``eval_ap/<class>``, and for
a model with masks ``eval/mask_mAP``, ``eval/mask_mAP50``, ``eval_mask_ap/<class>``).
A resumed run starts at the epoch after the checkpoint's, at its step, with its optimizer state.
"""

from __future__ import annotations

import io
import json
import math
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Literal

import torch
from tqdm import tqdm

from ambulo.utils.atomic import atomic_write_bytes, atomic_write_json
from ambulo.utils.validate import Checked

from .dataset import AugmentCfg, CocoFrames, canvas_size, collate, load_coco, no_augment, split_image_ids
from .evaluate import evaluate_all, predict_coco
from .loss import centernet_loss
from .model import STRIDE_MAX, ModelCfg, build_model

CHECKPOINT = "checkpoint.pt"


@dataclass(kw_only=True)
class TrainCfg(Checked):
    model: Literal["centernet-small", "centernet-medium"] = "centernet-small"
    mask_prototypes: int = 8
    """Instance masks from the dataset's segmentation (``ModelCfg.mask_prototypes``; 0: boxes only)."""
    epochs: int = 30
    batch_size: int = 16
    learning_rate: float = 2e-3
    """AdamW's peak rate; cosine decay to 5 % of it over the run, after ``warmup_steps``."""
    weight_decay: float = 1e-4
    warmup_steps: int = 100
    held_out_fraction: float = 0.1
    eval_every_epochs: int = 5
    """COCO evaluation of the held-out frames (and after the last epoch); 0: only after the last."""
    augment: AugmentCfg = field(default_factory=AugmentCfg)
    num_workers: int = 2
    """DataLoader processes reading PNGs (0: in the training process)."""
    device: str = "cpu"
    amp: bool = True
    """bfloat16 autocast on CUDA (no scaler needed); ignored on CPU."""
    seed: int = 0
    max_steps_per_epoch: int = 0
    """Stop each epoch after this many batches (0: the whole training split); for smoke runs."""


@dataclass
class TrainResult:
    run_dir: Path
    step: int
    epoch: int
    """The last epoch trained, 0-based."""
    losses: list[tuple[int, float]]
    """(step, total loss) of every step this call ran."""
    evaluations: list[dict]


def train(dataset_dir: str | Path, run_dir: str | Path, cfg: TrainCfg, resume: bool = False,
          show_progress: bool = True) -> TrainResult:
    """Train (or with ``resume``, continue from ``run_dir/checkpoint.pt``) and return what happened."""
    from torch.utils.tensorboard import SummaryWriter

    run_dir = Path(run_dir)
    run_dir.mkdir(parents=True, exist_ok=True)
    device = torch.device(cfg.device)
    torch.manual_seed(cfg.seed)
    coco = load_coco(dataset_dir)
    categories = sorted(coco["categories"], key=lambda c: c["id"])
    category_ids = [c["id"] for c in categories]
    class_of = {cat_id: k for k, cat_id in enumerate(category_ids)}
    train_ids, held_ids = split_image_ids(coco, cfg.held_out_fraction)
    canvas = canvas_size(coco, STRIDE_MAX)
    with_masks = cfg.mask_prototypes > 0
    train_set = CocoFrames(dataset_dir, coco, train_ids, canvas, cfg.augment, seed=cfg.seed, masks=with_masks)
    eval_set = CocoFrames(dataset_dir, coco, held_ids, canvas, None)
    image_sizes = {im["id"]: (im["height"], im["width"]) for im in coco["images"]}
    loader = torch.utils.data.DataLoader(train_set, batch_size=cfg.batch_size, shuffle=True, drop_last=False,
                                         num_workers=cfg.num_workers, collate_fn=collate,
                                         persistent_workers=cfg.num_workers > 0,
                                         generator=torch.Generator().manual_seed(cfg.seed))
    eval_loader = torch.utils.data.DataLoader(eval_set, batch_size=cfg.batch_size, num_workers=cfg.num_workers,
                                              collate_fn=collate)
    model_cfg = ModelCfg(name=cfg.model, num_classes=len(categories), mask_prototypes=cfg.mask_prototypes)
    model = build_model(model_cfg).to(device)
    optimizer = torch.optim.AdamW(model.parameters(), lr=cfg.learning_rate, weight_decay=cfg.weight_decay)
    steps_per_epoch = len(loader) if cfg.max_steps_per_epoch == 0 else min(len(loader), cfg.max_steps_per_epoch)
    total_steps = max(1, cfg.epochs * steps_per_epoch)

    def lr_factor(step: int) -> float:
        if step < cfg.warmup_steps:
            return (step + 1) / cfg.warmup_steps
        progress = min(1.0, (step - cfg.warmup_steps) / max(1, total_steps - cfg.warmup_steps))
        return 0.05 + 0.95 * 0.5 * (1 + math.cos(math.pi * progress))

    scheduler = torch.optim.lr_scheduler.LambdaLR(optimizer, lr_factor)
    step, start_epoch, evaluations = 0, 0, []
    if resume and (run_dir / CHECKPOINT).is_file():
        state = torch.load(run_dir / CHECKPOINT, map_location=device, weights_only=False)
        model.load_state_dict(state["model"])
        optimizer.load_state_dict(state["optimizer"])
        scheduler.load_state_dict(state["scheduler"])
        step, start_epoch, evaluations = state["step"], state["epoch"] + 1, state["evaluations"]
    use_amp = cfg.amp and device.type == "cuda"
    writer = SummaryWriter(log_dir=str(run_dir), purge_step=step if step else None)
    losses: list[tuple[int, float]] = []
    epoch = start_epoch - 1
    try:
        for epoch in range(start_epoch, cfg.epochs):
            model.train()
            bar = tqdm(total=steps_per_epoch, desc=f"epoch {epoch + 1}/{cfg.epochs}", unit="batch",
                       disable=not show_progress)
            for i, (images, targets) in enumerate(loader):
                if i >= steps_per_epoch:
                    break
                boxes = [t["boxes"] for t in targets]
                classes = [torch.tensor([class_of[int(c)] for c in t["labels"]], dtype=torch.int64) for t in targets]
                with torch.autocast(device.type, dtype=torch.bfloat16, enabled=use_amp):
                    maps = model(images.to(device, non_blocking=True))
                loss = centernet_loss(maps, boxes, classes, [t["masks"] for t in targets] if with_masks else None)
                optimizer.zero_grad(set_to_none=True)
                loss["total"].backward()
                torch.nn.utils.clip_grad_norm_(model.parameters(), 10.0)
                optimizer.step()
                scheduler.step()
                step += 1
                value = float(loss["total"].detach())
                losses.append((step, value))
                for name, v in loss.items():
                    writer.add_scalar(f"loss/{name}", float(v.detach()), step)
                writer.add_scalar("lr", scheduler.get_last_lr()[0], step)
                bar.set_postfix(loss=f"{value:.3f}")
                bar.update(1)
            bar.close()
            last = epoch == cfg.epochs - 1
            if last or (cfg.eval_every_epochs and (epoch + 1) % cfg.eval_every_epochs == 0):
                metrics = evaluate_all(coco, held_ids,
                                       predict_coco(model, eval_loader, device, category_ids, image_sizes))
                evaluations.append({"epoch": epoch, "step": step, **metrics})
                for prefix, m in (("", metrics), ("mask_", metrics.get("mask"))):
                    if m is None:
                        continue
                    writer.add_scalar(f"eval/{prefix}mAP", m["mAP"], step)
                    writer.add_scalar(f"eval/{prefix}mAP50", m["mAP50"], step)
                    for name, ap in m["per_class"].items():
                        writer.add_scalar(f"eval_{prefix}ap/{name}", ap, step)
                atomic_write_json(run_dir / "metrics.json", evaluations, indent=1)
            save_checkpoint(run_dir / CHECKPOINT, model, optimizer, scheduler, step=step, epoch=epoch, cfg=cfg,
                            model_cfg=model_cfg, categories=[c["name"] for c in categories],
                            category_ids=category_ids, canvas_hw=canvas, evaluations=evaluations)
    finally:
        writer.close()
    return TrainResult(run_dir=run_dir, step=step, epoch=epoch, losses=losses, evaluations=evaluations)


def save_checkpoint(path: Path, model, optimizer, scheduler, *, step: int, epoch: int, cfg: TrainCfg,
                    model_cfg: ModelCfg, categories: list[str], category_ids: list[int],
                    canvas_hw: tuple[int, int], evaluations: list[dict]) -> None:
    """Everything a resume or an export needs, written atomically (a crash leaves the previous one)."""
    buffer = io.BytesIO()
    torch.save({"model": model.state_dict(), "optimizer": optimizer.state_dict(), "scheduler": scheduler.state_dict(),
                "step": step, "epoch": epoch, "train_cfg": json.loads(json.dumps(asdict(cfg))),
                "model_cfg": asdict(model_cfg), "categories": categories, "category_ids": category_ids,
                "canvas_hw": list(canvas_hw), "evaluations": evaluations}, buffer)
    atomic_write_bytes(path, buffer.getvalue())


def load_trained(path: str | Path, device: str = "cpu"):
    """(model in eval mode, checkpoint dict) of a checkpoint written by ``train``."""
    state = torch.load(path, map_location=device, weights_only=False)
    model = build_model(ModelCfg(**state["model_cfg"])).to(device)
    model.load_state_dict(state["model"])
    return model.eval(), state


__all__ = ["CHECKPOINT", "TrainCfg", "TrainResult", "load_trained", "no_augment", "train"]
