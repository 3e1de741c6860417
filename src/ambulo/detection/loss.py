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


def targets(boxes_px: torch.Tensor, classes: torch.Tensor, num_classes: int, hw_cells: tuple[int, int]
            ) -> tuple[torch.Tensor, dict[str, torch.Tensor]]:
    """(heat target (B, C, h, w), per box ``{"cell": (B, M, 2) int64 x y, "size": (B, M, 2) cells,
    "offset": (B, M, 2) cells, "valid": (B, M) bool}``) of padded boxes (B, M, 4) px and classes
    (B, M), -1 for no box."""
    h, w = hw_cells
    device = boxes_px.device
    valid = classes >= 0
    box = boxes_px.float() / STRIDE_OUT
    centre = torch.stack([(box[..., 0] + box[..., 2]) / 2, (box[..., 1] + box[..., 3]) / 2], dim=-1)  # x, y cells
    size = torch.stack([box[..., 2] - box[..., 0], box[..., 3] - box[..., 1]], dim=-1)
    cell = torch.minimum(centre.floor().clamp(min=0), torch.tensor([w - 1.0, h - 1.0], device=device))
    ys = torch.arange(h, device=device, dtype=torch.float32)[:, None]
    xs = torch.arange(w, device=device, dtype=torch.float32)[None, :]
    sigma = (GAUSSIAN_ALPHA * size / 6).clamp(min=0.5)
    g = torch.exp(-((xs - cell[..., 0, None, None]) ** 2) / (2 * sigma[..., 0, None, None] ** 2)
                  - ((ys - cell[..., 1, None, None]) ** 2) / (2 * sigma[..., 1, None, None] ** 2))  # (B, M, h, w)
    g = g * valid[..., None, None]
    heat = torch.zeros(len(box), num_classes, h, w, device=device)
    heat.scatter_reduce_(1, classes.clamp(min=0)[..., None, None].expand_as(g), g, reduce="amax")
    return heat, {"cell": cell.long(), "size": size, "offset": centre - cell, "valid": valid}


def focal_loss(logits: torch.Tensor, target: torch.Tensor) -> torch.Tensor:
    """Penalty-reduced pixel-wise focal loss summed over the map (CenterNet eq. 1 before / N)."""
    pred = torch.sigmoid(logits.float()).clamp(1e-4, 1 - 1e-4)
    positive = target.eq(1).float()
    pos = -torch.log(pred) * (1 - pred) ** 2 * positive
    neg = -torch.log(1 - pred) * pred ** 2 * (1 - target) ** 4 * (1 - positive)
    return pos.sum() + neg.sum()


def at_cells(map_: torch.Tensor, cell: torch.Tensor) -> torch.Tensor:
    """(B, M, K) values of a map (B, K, h, w) at cells (B, M, 2) x y."""
    b, k, h, w = map_.shape
    index = (cell[..., 1] * w + cell[..., 0])[:, None, :].expand(b, k, cell.shape[1])
    return map_.float().reshape(b, k, h * w).gather(2, index).transpose(1, 2)


def mask_cells(instances: torch.Tensor, num_boxes: int) -> torch.Tensor:
    """(B, M, h, w) mask targets: box k's pixels (instance id k + 1 of the maps (B, H, W)) averaged over
    each ``STRIDE_OUT`` x ``STRIDE_OUT`` cell."""
    ids = torch.arange(1, num_boxes + 1, device=instances.device)[None, :, None, None]
    return F.avg_pool2d((instances[:, None] == ids).float(), STRIDE_OUT)


def mask_loss(proto: torch.Tensor, coef: torch.Tensor, boxes: dict[str, torch.Tensor], masks: torch.Tensor
              ) -> torch.Tensor:
    """Sum over boxes of the box-cropped, area-normalised BCE of their masks (module docstring);
    ``boxes`` is ``targets``' second output, ``masks`` the (B, M, h, w) cell targets (``mask_cells``)."""
    b, p, h, w = proto.shape
    coef_at = at_cells(coef, boxes["cell"])  # (B, M, P)
    logits = torch.bmm(coef_at, proto.float().reshape(b, p, h * w)).reshape(b, -1, h, w)
    ys = torch.arange(h, device=proto.device)[None, None, :, None]
    xs = torch.arange(w, device=proto.device)[None, None, None, :]
    centre = boxes["cell"].float() + boxes["offset"]
    lo = (centre - boxes["size"] / 2).floor() - 1  # the box in cells, one cell wider on each side
    hi = (centre + boxes["size"] / 2).ceil() + 1
    inside = ((xs >= lo[..., 0, None, None]) & (xs < hi[..., 0, None, None])
              & (ys >= lo[..., 1, None, None]) & (ys < hi[..., 1, None, None])).float()
    bce = F.binary_cross_entropy_with_logits(logits, masks, reduction="none")
    per_box = (bce * inside).sum(dim=(2, 3)) / inside.sum(dim=(2, 3)).clamp(min=1)
    return (per_box * boxes["valid"]).sum()


def centernet_loss(maps: dict[str, torch.Tensor], boxes_px: torch.Tensor, classes: torch.Tensor,
                   masks: torch.Tensor | None = None) -> dict[str, torch.Tensor]:
    """``{"heat", "size", "offset", "total"}`` losses of one batch, plus ``"mask"`` when ``masks``
    (B, M, h, w) cell targets (``mask_cells``) are given and the model has a mask branch; boxes
    (B, M, 4) px and 0-based classes (B, M) are padded with class -1."""
    b, c, h, w = maps["heat"].shape
    heat_target, boxes = targets(boxes_px, classes, c, (h, w))
    # a box's own centre cell is exactly 1 (the Gaussian's peak), the positives of the focal loss
    valid = boxes["valid"][..., None]
    n = boxes["valid"].sum().clamp(min=1)
    size_loss = ((at_cells(maps["size"], boxes["cell"]) - boxes["size"]).abs() * valid).sum() / n
    offset_loss = ((at_cells(maps["offset"], boxes["cell"]) - boxes["offset"]).abs() * valid).sum() / n
    heat = focal_loss(maps["heat"], heat_target) / n
    out = {"heat": heat, "size": size_loss, "offset": offset_loss,
           "total": heat + SIZE_WEIGHT * size_loss + OFFSET_WEIGHT * offset_loss}
    if masks is not None and "proto" in maps:
        out["mask"] = mask_loss(maps["proto"], maps["coef"], boxes, masks) / n
        out["total"] = out["total"] + MASK_WEIGHT * out["mask"]
    return out
