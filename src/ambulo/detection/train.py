"""Training a detector on an ``ambulo generate`` dataset: AMP on CUDA, checkpoints, resume, TensorBoard,
COCO evaluation on held-out frames every ``eval_every_epochs`` or ``eval_every_minutes``, a time budget.

Data (``TrainCfg.data``): ``resident`` decodes every training frame once into uint8 tensors on the
training device (``frames.ResidentFrames``; a GPU then never waits for PNG decoding), ``stream``
decodes each batch in ``num_workers`` processes (a dataset larger than the device's memory). Either
way the augmentations run on whole batches on the training device (``augment.augment_batch``).

Time (``max_minutes``): the run stops at the budget (counted from the start of the first call,
across resumes: data loading and evaluations included), evaluates and checkpoints; the learning
rate's cosine then follows the elapsed fraction of the budget (or of the epochs, whichever is
further), so a budgeted run ends annealed. ``pause_after_minutes`` stops this call earlier with a
checkpoint (no evaluation) for a ``resume`` to continue: a budget split across calls.

The run folder holds ``checkpoint.pt`` (model, optimizer, scheduler, epoch, step, elapsed seconds,
the configs and category names: all a resume or an export needs), ``metrics.json`` (every
evaluation, with ``train_loss``: the mean total loss of the steps since the one before; ``curve.py``
draws it) and the TensorBoard events (``loss/*``, ``lr``, ``eval/mAP``, ``eval/mAP50``,
``eval_ap/<class>``, and for a model with masks ``eval/mask_mAP``, ``eval/mask_mAP50``,
``eval_mask_ap/<class>``; evaluations before the last score boxes only, to stay short). A resumed
run starts at the epoch after the checkpoint's, at its step, with its optimizer state.
"""

from __future__ import annotations

import io
import json
import math
import time
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Literal

import torch
import torch.nn.functional as F
from tqdm import tqdm

from ambulo.utils.atomic import atomic_write_bytes, atomic_write_json
from ambulo.utils.validate import Checked

from .augment import AugmentCfg, augment_batch, no_augment
from .dataset import CocoFrames, canvas_size, collate, load_coco, split_image_ids
from .evaluate import evaluate_all, predict_coco
from .frames import FrameRecords, ResidentFrames, pad_collate
from .loss import centernet_loss, mask_cells
from .model import STRIDE_MAX, ModelCfg, build_model

CHECKPOINT = "checkpoint.pt"
LOG_EVERY_STEPS = 20
"""Losses are copied off the device (a synchronisation) once per this many steps; TensorBoard gets
their mean over those steps."""


@dataclass(kw_only=True)
class TrainCfg(Checked):
    model: Literal["centernet-small", "centernet-medium"] = "centernet-small"
    mask_prototypes: int = 8
    """Instance masks from the dataset's segmentation (``ModelCfg.mask_prototypes``; 0: boxes only)."""
    inputs: Literal["rgb", "rgbd", "rgbdh"] = "rgb"
    """The model's input (``ModelCfg.inputs``): colour, or colour and the dataset's depth PNGs, or those and
    each pixel's height above the floor (from the depth and the frame records' camera poses)."""
    epochs: int = 30
    batch_size: int = 16
    learning_rate: float = 2e-3
    """AdamW's peak rate; cosine decay to 5 % of it over the run, after ``warmup_steps``."""
    weight_decay: float = 1e-4
    warmup_steps: int = 100
    held_out_fraction: float = 0.1
    eval_every_epochs: int = 5
    """COCO evaluation of the held-out frames (and after the last epoch); 0: only after the last."""
    eval_every_minutes: float = 0.0
    """Also evaluate after the first epoch that ends this long after the previous evaluation (0: never)."""
    max_minutes: float = 0.0
    """Training time budget across resumes (module docstring; 0: none, the epochs decide)."""
    pause_after_minutes: float = 0.0
    """Stop this call after this long with a checkpoint, for a resume (0: never)."""
    augment: AugmentCfg = field(default_factory=AugmentCfg)
    data: Literal["resident", "stream"] = "resident"
    """Training frames decoded once into device memory, or per batch by worker processes."""
    num_workers: int = 2
    """Processes decoding PNGs (0: in the training process)."""
    device: str = "cpu"
    amp: bool = True
    """bfloat16 autocast and channels-last tensors on CUDA (no scaler needed); ignored on CPU."""
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
    elapsed_s: float = 0.0
    """Training time of the run so far, across resumes."""
    stopped: Literal["epochs", "budget", "pause"] = "epochs"
    """What ended this call: the last epoch, ``max_minutes`` or ``pause_after_minutes``."""


def _batches(cfg: TrainCfg, resident: ResidentFrames | None, loader, epoch: int,
             device: torch.device):
    """The training batches of one epoch on ``device`` (uint8 images, padded boxes)."""
    if resident is not None:
        order = torch.randperm(len(resident), generator=torch.Generator().manual_seed(cfg.seed * 100_003 + epoch))
        order = order.to(device)
        for start in range(0, len(order), cfg.batch_size):
            yield resident.batch(order[start:start + cfg.batch_size])
        return
    for batch in loader:
        yield {k: v.to(device, non_blocking=True) for k, v in batch.items()}


def train(dataset_dir: str | Path, run_dir: str | Path, cfg: TrainCfg, resume: bool = False,
          show_progress: bool = True) -> TrainResult:
    """Train (or with ``resume``, continue from ``run_dir/checkpoint.pt``) and return what happened."""
    from torch.utils.tensorboard import SummaryWriter

    started = time.perf_counter()
    run_dir = Path(run_dir)
    run_dir.mkdir(parents=True, exist_ok=True)
    device = torch.device(cfg.device)
    coco = load_coco(dataset_dir)
    categories = sorted(coco["categories"], key=lambda c: c["id"])
    category_ids = [c["id"] for c in categories]
    class_of = {cat_id: k for k, cat_id in enumerate(category_ids)}
    train_ids, held_ids = split_image_ids(coco, cfg.held_out_fraction)
    canvas = canvas_size(coco, STRIDE_MAX)
    with_masks = cfg.mask_prototypes > 0
    with_depth, with_height = cfg.inputs in ("rgbd", "rgbdh"), cfg.inputs == "rgbdh"
    records = FrameRecords(dataset_dir, coco, train_ids, class_of, depth=with_depth, height=with_height)
    resident, loader = None, None
    if cfg.data == "resident":
        resident = ResidentFrames(records, device, cfg.num_workers)
        batches_per_epoch = math.ceil(len(resident) / cfg.batch_size)
    else:
        loader = torch.utils.data.DataLoader(records, batch_size=cfg.batch_size, shuffle=True,
                                             num_workers=cfg.num_workers, collate_fn=pad_collate,
                                             persistent_workers=cfg.num_workers > 0, pin_memory=device.type == "cuda",
                                             generator=torch.Generator().manual_seed(cfg.seed))
        batches_per_epoch = len(loader)
    eval_set = CocoFrames(dataset_dir, coco, held_ids, canvas, depth=with_depth, height=with_height)
    image_sizes = {im["id"]: (im["height"], im["width"]) for im in coco["images"]}
    eval_loader = torch.utils.data.DataLoader(eval_set, batch_size=cfg.batch_size, num_workers=cfg.num_workers,
                                              collate_fn=collate)
    model_cfg = ModelCfg(name=cfg.model, num_classes=len(categories), mask_prototypes=cfg.mask_prototypes,
                         inputs=cfg.inputs)
    torch.manual_seed(cfg.seed)  # here: the initialisation does not depend on what loading the data drew
    model = build_model(model_cfg).to(device)
    use_amp = cfg.amp and device.type == "cuda"
    if device.type == "cuda":
        torch.backends.cudnn.benchmark = True  # one input size throughout: the fastest kernels, found once
    memory_format = torch.channels_last if use_amp else torch.contiguous_format
    model = model.to(memory_format=memory_format)
    optimizer = torch.optim.AdamW(model.parameters(), lr=cfg.learning_rate, weight_decay=cfg.weight_decay)
    steps_per_epoch = batches_per_epoch if cfg.max_steps_per_epoch == 0 else min(batches_per_epoch,
                                                                                   cfg.max_steps_per_epoch)
    total_steps = max(1, cfg.epochs * steps_per_epoch)
    step, start_epoch, evaluations, elapsed_before = 0, 0, [], 0.0

    def elapsed() -> float:
        return elapsed_before + time.perf_counter() - started

    def lr_factor(step: int) -> float:
        if step < cfg.warmup_steps:
            return (step + 1) / cfg.warmup_steps
        progress = min(1.0, (step - cfg.warmup_steps) / max(1, total_steps - cfg.warmup_steps))
        if cfg.max_minutes > 0:
            progress = max(progress, min(1.0, elapsed() / (60 * cfg.max_minutes)))
        return 0.05 + 0.95 * 0.5 * (1 + math.cos(math.pi * progress))

    scheduler = torch.optim.lr_scheduler.LambdaLR(optimizer, lr_factor)
    if resume and (run_dir / CHECKPOINT).is_file():
        state = torch.load(run_dir / CHECKPOINT, map_location=device, weights_only=False)
        model.load_state_dict(state["model"])
        optimizer.load_state_dict(state["optimizer"])
        scheduler.load_state_dict(state["scheduler"])
        step, start_epoch, evaluations = state["step"], state["epoch"] + 1, state["evaluations"]
        elapsed_before = state.get("elapsed_s", 0.0)
    # device-side draws; a resume draws anew rather than repeating the first call's
    g = torch.Generator(device=device).manual_seed(cfg.seed * 1_000_003 + start_epoch)
    writer = SummaryWriter(log_dir=str(run_dir), purge_step=step if step else None)
    losses: list[tuple[int, float]] = []
    pending: list[tuple[int, dict[str, torch.Tensor]]] = []

    def flush(bar) -> None:
        if not pending:
            return
        values = torch.stack([torch.stack(list(loss.values())) for _, loss in pending])
        names = list(pending[0][1])
        for (s, _), total in zip(pending, values[:, names.index("total")].tolist()):
            losses.append((s, total))
        for name, v in zip(names, values.mean(dim=0).tolist()):  # the window's mean: a short event file
            writer.add_scalar(f"loss/{name}", v, pending[-1][0])
        bar.set_postfix(loss=f"{losses[-1][1]:.3f}")
        pending.clear()

    epoch, stopped, last_eval_s = start_epoch - 1, "epochs", elapsed()
    saved_elapsed_s = None  # the last checkpoint's clock: what this call reports and a resume counts from
    try:
        for epoch in range(start_epoch, cfg.epochs):
            model.train()
            bar = tqdm(total=steps_per_epoch, desc=f"epoch {epoch + 1}/{cfg.epochs}", unit="batch",
                       disable=not show_progress)
            for i, batch in enumerate(_batches(cfg, resident, loader, epoch, device)):
                if i >= steps_per_epoch:
                    break
                batch = augment_batch(batch, cfg.augment, g)
                h, w = batch["images"].shape[-2:]
                pad = (0, canvas[1] - w, 0, canvas[0] - h)  # black bottom and right, as at inference
                images = F.pad(batch["images"], pad).contiguous(memory_format=memory_format)
                with torch.autocast(device.type, dtype=torch.bfloat16, enabled=use_amp):
                    maps = model(images)
                masks = mask_cells(F.pad(batch["instances"], pad), batch["boxes"].shape[1]) if with_masks else None
                loss = centernet_loss(maps, batch["boxes"], batch["classes"], masks)
                optimizer.zero_grad(set_to_none=True)
                loss["total"].backward()
                torch.nn.utils.clip_grad_norm_(model.parameters(), 10.0)
                optimizer.step()
                scheduler.step()
                step += 1
                pending.append((step, {k: v.detach() for k, v in loss.items()}))
                if step % LOG_EVERY_STEPS == 0:
                    writer.add_scalar("lr", scheduler.get_last_lr()[0], step)
                    flush(bar)
                bar.update(1)
                if cfg.max_minutes > 0 and elapsed() >= 60 * cfg.max_minutes:
                    stopped = "budget"
                    break
                if cfg.pause_after_minutes > 0 and time.perf_counter() - started >= 60 * cfg.pause_after_minutes:
                    stopped = "pause"
                    break
            flush(bar)
            bar.close()
            last = epoch == cfg.epochs - 1 or stopped == "budget"
            due = ((cfg.eval_every_epochs and (epoch + 1) % cfg.eval_every_epochs == 0)
                   or (cfg.eval_every_minutes > 0 and elapsed() - last_eval_s >= 60 * cfg.eval_every_minutes))
            if last or (due and stopped != "pause"):
                # the last evaluation scores the masks too; the ones before, boxes only (a curve, quickly)
                sizes = image_sizes if last else None
                metrics = evaluate_all(coco, held_ids, predict_coco(model, eval_loader, device, category_ids, sizes))
                last_eval_s = elapsed()
                since = evaluations[-1]["step"] if evaluations else 0
                window = [total for s, total in losses if s > since]  # this call's steps since the last one
                train_loss = {"train_loss": round(sum(window) / len(window), 4)} if window else {}
                evaluations.append({"epoch": epoch, "step": step, "elapsed_s": round(last_eval_s, 1), **train_loss,
                                    **metrics})
                for prefix, m in (("", metrics), ("mask_", metrics.get("mask"))):
                    if m is None:
                        continue
                    writer.add_scalar(f"eval/{prefix}mAP", m["mAP"], step)
                    writer.add_scalar(f"eval/{prefix}mAP50", m["mAP50"], step)
                    for name, ap in m["per_class"].items():
                        writer.add_scalar(f"eval_{prefix}ap/{name}", ap, step)
                atomic_write_json(run_dir / "metrics.json", evaluations, indent=1)
            saved_elapsed_s = elapsed()
            save_checkpoint(run_dir / CHECKPOINT, model, optimizer, scheduler, step=step, epoch=epoch, cfg=cfg,
                            model_cfg=model_cfg, categories=[c["name"] for c in categories],
                            category_ids=category_ids, canvas_hw=canvas, evaluations=evaluations,
                            elapsed_s=saved_elapsed_s)
            if stopped != "epochs":
                break
    finally:
        writer.close()
    # closing the event file can take a while on a busy disk: counted in neither the report nor the checkpoint,
    # so a resume continues from exactly the time this call reports
    return TrainResult(run_dir=run_dir, step=step, epoch=epoch, losses=losses, evaluations=evaluations,
                       elapsed_s=elapsed() if saved_elapsed_s is None else saved_elapsed_s, stopped=stopped)


def save_checkpoint(path: Path, model, optimizer, scheduler, *, step: int, epoch: int, cfg: TrainCfg,
                    model_cfg: ModelCfg, categories: list[str], category_ids: list[int],
                    canvas_hw: tuple[int, int], evaluations: list[dict], elapsed_s: float = 0.0) -> None:
    """Everything a resume or an export needs, written atomically (a crash leaves the previous one)."""
    buffer = io.BytesIO()
    torch.save({"model": model.state_dict(), "optimizer": optimizer.state_dict(), "scheduler": scheduler.state_dict(),
                "step": step, "epoch": epoch, "train_cfg": json.loads(json.dumps(asdict(cfg))),
                "model_cfg": asdict(model_cfg), "categories": categories, "category_ids": category_ids,
                "canvas_hw": list(canvas_hw), "evaluations": evaluations,
                "elapsed_s": elapsed_s}, buffer)
    atomic_write_bytes(path, buffer.getvalue())


def load_trained(path: str | Path, device: str = "cpu"):
    """(model in eval mode, checkpoint dict) of a checkpoint written by ``train``."""
    state = torch.load(path, map_location=device, weights_only=False)
    model = build_model(ModelCfg(**state["model_cfg"])).to(device)
    model.load_state_dict(state["model"])
    return model.eval(), state


__all__ = ["CHECKPOINT", "TrainCfg", "TrainResult", "load_trained", "no_augment", "train"]
