"""CenterNet's training targets and loss (Zhou et al. 2019, eqs. 1-3; TTFNet's elliptical Gaussians).

Each box puts a Gaussian on its class's heatmap at its centre, with standard deviations of
``GAUSSIAN_ALPHA * (w, h) / 6`` cells (TTFNet, Liu et al. 2020: an object-shaped peak, so long thin
boxes are not over-penalised along their short side); the loss is the penalty-reduced focal loss
on the heatmap (alpha 2, beta 4) plus L1 on size (weight 0.1) and offset (weight 1) at each box's
centre cell, all normalised by the number of boxes.

Masks (YOLACT's loss, Bolya et al. 2019): each box's mask logits are its centre cell's
coefficients times the prototypes; the target is its binary mask averaged over each 4x4 cell (a
soft edge, exactly what ``paste_masks`` up-samples back); binary cross-entropy over the cells of its
box widened by one cell, divided by that area, so a small object counts as much as a large one
(weight ``MASK_WEIGHT``, averaged over the boxes).
"""

from __future__ import annotations

import torch
import torch.nn.functional as F

from .model import STRIDE_OUT

GAUSSIAN_ALPHA = 0.54
SIZE_WEIGHT = 0.1
OFFSET_WEIGHT = 1.0
MASK_WEIGHT = 1.0


def targets(boxes_px: list[torch.Tensor], classes: list[torch.Tensor], num_classes: int,
            hw_cells: tuple[int, int], device: torch.device) -> tuple[torch.Tensor, list[tuple]]:
    """(heat target (B, C, h, w), per image (centre cells (N, 2) int yx, size (N, 2) cells, offset (N, 2) cells))."""
    h, w = hw_cells
    heat = torch.zeros(len(boxes_px), num_classes, h, w, device=device)
    ys = torch.arange(h, device=device, dtype=torch.float32)[:, None]
    xs = torch.arange(w, device=device, dtype=torch.float32)[None, :]
    per_image = []
    for i, (box, cls) in enumerate(zip(boxes_px, classes)):
        box, cls = box.to(device).float() / STRIDE_OUT, cls.to(device)
        centre = torch.stack([(box[:, 0] + box[:, 2]) / 2, (box[:, 1] + box[:, 3]) / 2], dim=1)  # x, y cells
        size = torch.stack([box[:, 2] - box[:, 0], box[:, 3] - box[:, 1]], dim=1)
        cell = centre.floor().clamp(min=0)
        cell[:, 0].clamp_(max=w - 1)
        cell[:, 1].clamp_(max=h - 1)
        if len(box):
            sigma = (GAUSSIAN_ALPHA * size / 6).clamp(min=0.5)
            g = torch.exp(-((xs[None] - cell[:, 0, None, None]) ** 2) / (2 * sigma[:, 0, None, None] ** 2)
                          - ((ys[None] - cell[:, 1, None, None]) ** 2) / (2 * sigma[:, 1, None, None] ** 2))
            index = cls[:, None, None].expand_as(g)
            heat[i].scatter_reduce_(0, index, g, reduce="amax")
        per_image.append((cell.long(), size, centre - cell))
    return heat, per_image


def focal_loss(logits: torch.Tensor, target: torch.Tensor) -> torch.Tensor:
    """Penalty-reduced pixel-wise focal loss summed over the map (CenterNet eq. 1 before / N)."""
    pred = torch.sigmoid(logits.float()).clamp(1e-4, 1 - 1e-4)
    positive = target.eq(1).float()
    pos = -torch.log(pred) * (1 - pred) ** 2 * positive
    neg = -torch.log(1 - pred) * pred ** 2 * (1 - target) ** 4 * (1 - positive)
    return pos.sum() + neg.sum()


def mask_loss(proto: torch.Tensor, coef: torch.Tensor, per_image: list[tuple], masks: list[torch.Tensor]
              ) -> torch.Tensor:
    """Sum over boxes of the box-cropped, area-normalised BCE of their masks (module docstring);
    ``per_image`` is ``targets``' (so each box's centre cell), ``masks`` (N, H, W) bool per image."""
    total = proto.new_zeros((), dtype=torch.float32)
    b, p, h, w = proto.shape
    ys = torch.arange(h, device=proto.device)[None, :, None]
    xs = torch.arange(w, device=proto.device)[None, None, :]
    for i, ((cell, size, offset), mask) in enumerate(zip(per_image, masks)):
        if not len(cell):
            continue
        c = coef[i, :, cell[:, 1], cell[:, 0]].float().T  # (N, P)
        logits = (c @ proto[i].float().reshape(p, h * w)).reshape(-1, h, w)
        target = F.avg_pool2d(mask.to(proto.device, torch.float32)[:, None], STRIDE_OUT)[:, 0]
        centre = cell.float() + offset
        lo = (centre - size / 2).floor() - 1  # the box in cells, one cell wider on each side
        hi = (centre + size / 2).ceil() + 1
        inside = ((xs >= lo[:, 0, None, None]) & (xs < hi[:, 0, None, None])
                  & (ys >= lo[:, 1, None, None]) & (ys < hi[:, 1, None, None])).float()
        bce = F.binary_cross_entropy_with_logits(logits, target, reduction="none")
        total = total + ((bce * inside).sum(dim=(1, 2)) / inside.sum(dim=(1, 2)).clamp(min=1)).sum()
    return total


def centernet_loss(maps: dict[str, torch.Tensor], boxes_px: list[torch.Tensor], classes: list[torch.Tensor],
                   masks: list[torch.Tensor] | None = None) -> dict[str, torch.Tensor]:
    """``{"heat", "size", "offset", "total"}`` losses of one batch, plus ``"mask"`` when ``masks``
    (N, H, W) bool per image are given and the model has a mask branch; ``classes`` are 0-based."""
    b, c, h, w = maps["heat"].shape
    heat_target, per_image = targets(boxes_px, classes, c, (h, w), maps["heat"].device)
    # a box's own centre cell is exactly 1 (the Gaussian's peak), the positives of the focal loss
    n = max(1, sum(len(cell) for cell, _, _ in per_image))
    size_loss = maps["size"].new_zeros((), dtype=torch.float32)
    offset_loss = size_loss.clone()
    for i, (cell, size, offset) in enumerate(per_image):
        if len(cell):
            size_loss = size_loss + F.l1_loss(maps["size"][i, :, cell[:, 1], cell[:, 0]].float().T, size, reduction="sum")
            offset_loss = offset_loss + F.l1_loss(maps["offset"][i, :, cell[:, 1], cell[:, 0]].float().T, offset,
                                                  reduction="sum")
    heat = focal_loss(maps["heat"], heat_target) / n
    size_loss, offset_loss = size_loss / n, offset_loss / n
    out = {"heat": heat, "size": size_loss, "offset": offset_loss,
           "total": heat + SIZE_WEIGHT * size_loss + OFFSET_WEIGHT * offset_loss}
    if masks is not None and "proto" in maps:
        out["mask"] = mask_loss(maps["proto"], maps["coef"], per_image, masks) / n
        out["total"] = out["total"] + MASK_WEIGHT * out["mask"]
    return out
