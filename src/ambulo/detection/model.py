"""A small anchor-free detector (CenterNet: Zhou et al. 2019, "Objects as Points") with instance
masks (YOLACT's prototypes and coefficients: Bolya et al. 2019), pure torch.

Why not torchvision's detection models: torchvision's PyPI wheels are CUDA builds whose C++ ops
(``nms``, ``roi_align``) need torch's CUDA libraries, so ``import torchvision`` fails against the CPU
torch the project installs by default; and their box decoding ends in NMS, an op ONNX Runtime runs
slowly on CPU. CenterNet decodes with a 3x3 max-pool and top-k, plain ops that export to ONNX and
need no NMS; it trains from random weights (nothing is downloaded).

Frames: input images (B, 3, H, W) float in [0, 1] (``inputs="rgbd"``: (B, 4, H, W), the 4th channel
the depth as ``depth_channel`` encodes it; ``inputs="rgbdh"``: (B, 5, H, W), the 5th the height above the
floor as ``height_channel`` encodes it), H and W multiples of ``STRIDE_OUT * 8``;
outputs at stride ``STRIDE_OUT`` (4 px): a heatmap per class (object centres), box size (w, h) in
output cells and the centre's sub-cell offset. ``decode`` turns them into the ``max_detections``
best boxes (B, K, 4) x0 y0 x1 y1 in input pixels, scores (B, K) and 0-based class indices (B, K).

Masks (``mask_prototypes`` > 0): a branch makes P prototype maps at stride 4 for the whole image,
the head P coefficients per cell; an object's mask logits are its centre cell's coefficients times
the prototypes (a 1x1 convolution whose weights the detection chooses: CondInst's dynamic mask head
reduced to one linear layer). That costs two small convolutions and one (K, P) x (P, h*w) product,
and exports to ONNX as a MatMul. ``decode_masks`` gives (B, K, h, w) probabilities at stride 4;
``paste_masks`` turns the kept ones into full-resolution binary masks inside their boxes.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Literal

import torch
import torch.nn.functional as F
from torch import nn

from ambulo.utils.validate import Checked

STRIDE_OUT = 4
"""Output stride in input pixels (CenterNet's)."""
STRIDE_MAX = 32
"""The deepest feature's stride: input sizes must be multiples of it."""
MODELS: dict[str, tuple[int, ...]] = {
    "centernet-small": (16, 32, 64, 96, 128),
    "centernet-medium": (32, 64, 128, 192, 256),
}
"""Channels at strides 2, 4, 8, 16, 32 of each named model: 'small' runs > 10 frames/s at 320x240 on
two CPU cores (benchmarks/detector.py), 'medium' is for a GPU."""
DEPTH_MAX_M = 8.0
"""The depth channel is depth / DEPTH_MAX_M clipped to [0, 1]: the example scenes' rooms end within
~8 m, and an input in [0, 1] is what the colour channels are."""
HEIGHT_MAX_M = 2.0
"""The height channel is height above the floor / HEIGHT_MAX_M clipped to [0, 1]: the objects stand under
~0.6 m, and above 2 m is walls and racks."""
INPUT_CHANNELS = {"rgb": 3, "rgbd": 4, "rgbdh": 5}


def depth_channel(depth_m: torch.Tensor) -> torch.Tensor:
    """The model's depth input of depth (m) to the image plane, any shape: depth / ``DEPTH_MAX_M``
    clipped to [0, 1]; no return (0, NaN, as the datasets' 0 mm) is 0."""
    return torch.nan_to_num(depth_m, nan=0.0, posinf=0.0).clamp(0, DEPTH_MAX_M) / DEPTH_MAX_M


def height_channel(height_m: torch.Tensor) -> torch.Tensor:
    """The model's height input of heights above the floor (m; ``height.height_above_floor_m``), any shape:
    height / ``HEIGHT_MAX_M`` clipped to [0, 1] (below the floor, NaN: 0)."""
    return torch.nan_to_num(height_m, nan=0.0, posinf=0.0).clamp(0, HEIGHT_MAX_M) / HEIGHT_MAX_M


@dataclass(kw_only=True)
class ModelCfg(Checked):
    name: Literal["centernet-small", "centernet-medium"] = "centernet-small"
    num_classes: int = 1
    """Categories 1..C of the COCO file are classes 0..C-1 here."""
    max_detections: int = 100
    """Boxes ``decode`` returns per image (the best by score; COCO evaluation reads up to 100)."""
    head_channels: int = 32
    mask_prototypes: int = 8
    """Prototype masks of the instance-mask branch (0: boxes only)."""
    inputs: Literal["rgb", "rgbd", "rgbdh"] = "rgb"
    """Colour only, or colour and depth (``depth_channel``) as a 4th input channel: with depth the
    model can measure an object's metric size, which tells a class from clutter of its shape (issue 27);
    ``rgbdh`` adds each pixel's height above the floor (``height_channel``, from depth and the camera's
    pose: ``height``), which does not change with the camera's height or pitch."""


def _conv(c_in: int, c_out: int, stride: int = 1) -> nn.Sequential:
    return nn.Sequential(nn.Conv2d(c_in, c_out, 3, stride, 1, bias=False), nn.BatchNorm2d(c_out), nn.ReLU(inplace=True))


class CenterNet(nn.Module):
    """Backbone of strided 3x3 conv stages, a top-down feature pyramid to stride 4, three heads."""

    def __init__(self, cfg: ModelCfg):
        super().__init__()
        self.cfg = cfg
        widths = MODELS[cfg.name]
        c_in0 = INPUT_CHANNELS[cfg.inputs]
        stages, c_in = [], c_in0
        for i, c in enumerate(widths):  # the stride-2 stem is one conv: most pixels, least to see
            stages.append(_conv(c_in, c, 2) if i == 0 else nn.Sequential(_conv(c_in, c, 2), _conv(c, c)))
            c_in = c
        self.stages = nn.ModuleList(stages)
        d = cfg.head_channels
        self.lateral = nn.ModuleList([nn.Conv2d(c, d, 1) for c in widths[1:]])  # strides 4..32
        self.smooth = nn.ModuleList([_conv(d, d) for _ in widths[1:-1]])
        # one shared 3x3 conv before three 1x1 outputs: at stride 4 a 3x3 conv per head would be most
        # of the model's cost (the stride-4 map has 16x the stride-16 map's cells)
        self.head = _conv(d, d)
        self.heat = nn.Conv2d(d, cfg.num_classes, 1)
        self.size = nn.Conv2d(d, 2, 1)
        self.offset = nn.Conv2d(d, 2, 1)
        if cfg.mask_prototypes:
            self.proto = nn.Sequential(_conv(d, d), nn.Conv2d(d, cfg.mask_prototypes, 1))
            self.coef = nn.Conv2d(d, cfg.mask_prototypes, 1)
        # the heatmap starts at p = 0.1 everywhere (CenterNet's focal-loss prior), not 0.5
        nn.init.constant_(self.heat.bias, -math.log((1 - 0.1) / 0.1))
        # ImageNet's colour statistics; the depth and height channels' are the example scene's rough ones
        # (0.5-8 m; mostly floor at 0, objects under 0.6 m, walls above 2 m)
        mean, std = [0.485, 0.456, 0.406, 0.4, 0.15][:c_in0], [0.229, 0.224, 0.225, 0.2, 0.3][:c_in0]
        self.register_buffer("mean", torch.tensor(mean).view(1, -1, 1, 1), persistent=False)
        self.register_buffer("std", torch.tensor(std).view(1, -1, 1, 1), persistent=False)

    def forward(self, images: torch.Tensor) -> dict[str, torch.Tensor]:
        """Raw maps of images (B, 3 or 4, H, W) at stride 4: ``heat`` logits (B, C, h, w), ``size`` (B, 2, h, w) in cells, ``offset``
        (B, 2, h, w) in cells; with masks also ``proto`` (B, P, h, w) and ``coef`` (B, P, h, w)."""
        x = (images - self.mean) / self.std
        features = []
        for stage in self.stages:
            x = stage(x)
            features.append(x)
        top = self.lateral[-1](features[-1])
        for i in range(len(self.lateral) - 2, -1, -1):
            top = F.interpolate(top, scale_factor=2.0, mode="nearest") + self.lateral[i](features[i + 1])
            top = self.smooth[i](top)
        pyramid = top
        top = self.head(top)
        # softplus, not ReLU: a ReLU whose input starts negative at every cell never learns that side's
        # size (seen: box heights stuck at 0 after one unlucky initialisation)
        maps = {"heat": self.heat(top), "size": F.softplus(self.size(top)), "offset": self.offset(top)}
        if self.cfg.mask_prototypes:
            maps["proto"], maps["coef"] = self.proto(pyramid), self.coef(top)
        return maps


def decode(maps: dict[str, torch.Tensor], max_detections: int) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
    """(boxes (B, K, 4) x0 y0 x1 y1 px, scores (B, K), class indices (B, K) int64): the K highest
    peaks of the heatmap, a peak being a cell that equals the max of its 3x3 neighbourhood (CenterNet's
    NMS-free decoding)."""
    return _decode(maps, max_detections)[:3]


def decode_masks(maps: dict[str, torch.Tensor], max_detections: int
                 ) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor, torch.Tensor]:
    """``decode``'s three outputs plus each detection's mask probabilities (B, K, h, w) at stride 4
    (cell (i, j) is the mean over pixels [4 i, 4 i + 4) x [4 j, 4 j + 4)), not yet cut to the box."""
    boxes, scores, classes, cell = _decode(maps, max_detections)
    b, p, h, w = maps["proto"].shape
    coef = maps["coef"].float().reshape(b, p, h * w).gather(2, cell[:, None, :].expand(b, p, cell.shape[1]))
    logits = torch.matmul(coef.transpose(1, 2), maps["proto"].float().reshape(b, p, h * w))
    return boxes, scores, classes, torch.sigmoid(logits).reshape(b, -1, h, w)


def _decode(maps: dict[str, torch.Tensor], max_detections: int):
    heat = torch.sigmoid(maps["heat"].float())
    b, c, h, w = heat.shape
    peaks = heat * (F.max_pool2d(heat, 3, stride=1, padding=1) == heat).to(heat.dtype)
    k = min(max_detections, c * h * w)
    scores, index = peaks.reshape(b, -1).topk(k, dim=1)
    classes = torch.div(index, h * w, rounding_mode="floor")
    cell = index - classes * (h * w)
    cy = torch.div(cell, w, rounding_mode="floor")
    cx = cell - cy * w
    size = maps["size"].float().reshape(b, 2, h * w).gather(2, cell[:, None, :].expand(b, 2, k))
    offset = maps["offset"].float().reshape(b, 2, h * w).gather(2, cell[:, None, :].expand(b, 2, k))
    x = (cx.to(heat.dtype) + offset[:, 0]) * STRIDE_OUT
    y = (cy.to(heat.dtype) + offset[:, 1]) * STRIDE_OUT
    half_w, half_h = size[:, 0] * STRIDE_OUT / 2, size[:, 1] * STRIDE_OUT / 2
    boxes = torch.stack([x - half_w, y - half_h, x + half_w, y + half_h], dim=2)
    return boxes, scores, classes, cell


def paste_masks(masks_cells: torch.Tensor, boxes_px: torch.Tensor, out_hw: tuple[int, int],
                threshold: float = 0.5) -> torch.Tensor:
    """Binary masks (K, H, W) bool of ``out_hw`` pixels from stride-4 probabilities (K, h, w): bilinear
    up-sampling (a cell's value sits at its pixels' centre, as the average pooling of the targets
    put it), thresholded, and cut to each box (K, 4) x0 y0 x1 y1 px widened to whole pixels (YOLACT
    crops the same way: the box branch is sharper than a stride-4 mask at an object's edge)."""
    k, h, w = masks_cells.shape
    if k == 0:
        return torch.zeros(0, *out_hw, dtype=torch.bool, device=masks_cells.device)
    full = F.interpolate(masks_cells[None].float(), size=(h * STRIDE_OUT, w * STRIDE_OUT), mode="bilinear",
                         align_corners=False)[0, :, :out_hw[0], :out_hw[1]]
    ys = torch.arange(out_hw[0], dtype=torch.float32, device=masks_cells.device)[None, :, None] + 0.5
    xs = torch.arange(out_hw[1], dtype=torch.float32, device=masks_cells.device)[None, None, :] + 0.5
    b = boxes_px.float()
    inside = ((xs >= b[:, 0, None, None].floor()) & (xs <= b[:, 2, None, None].ceil())
              & (ys >= b[:, 1, None, None].floor()) & (ys <= b[:, 3, None, None].ceil()))
    return (full > threshold) & inside


class ExportedDetector(nn.Module):
    """The model plus ``decode``: images (B, 3 or 4, H, W) in [0, 1] -> (boxes, scores, classes) and, for a
    model with masks, ``decode_masks``' stride-4 mask probabilities; the graph ONNX export traces."""

    def __init__(self, model: CenterNet):
        super().__init__()
        self.model = model

    def forward(self, images: torch.Tensor) -> tuple[torch.Tensor, ...]:
        maps = self.model(images)
        if self.model.cfg.mask_prototypes:
            return decode_masks(maps, self.model.cfg.max_detections)
        return decode(maps, self.model.cfg.max_detections)


def build_model(cfg: ModelCfg) -> CenterNet:
    return CenterNet(cfg)
