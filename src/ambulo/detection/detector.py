"""``Detector``: frames in, detections out, from a training checkpoint (torch) or an exported ONNX file.

    detector = Detector("runs/det/model.onnx")          # or "runs/det/checkpoint.pt"
    result = detector(rgb)                              # rgb: (H, W, 3) uint8, H, W <= the canvas
    result = detector(rgb, depth_m)                     # an rgbd model (``inputs``): depth (H, W) m too
    result = detector(rgb, depth_m, height_m)           # an rgbdh model: and the height above the floor (H, W) m
                                                        # (``height.height_above_floor_m(depth_m, K, T_cw)``)
    result.boxes_px, result.labels, result.scores, result.masks   # masks: (N, H, W) bool, or None
    result.semantic_image()                             # (H, W) uint8 category ids, or None

A frame smaller than the training canvas is padded black at the bottom and right (as in training),
so boxes are in the frame's own pixels; a larger one is an error (resize it, or train on that size).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np


@dataclass
class Detections:
    boxes_px: np.ndarray
    """(N, 4) float32 x0 y0 x1 y1 in the frame's pixels."""
    labels: list[str]
    """N category names."""
    category_ids: np.ndarray
    """(N,) int64 COCO category ids of the dataset."""
    scores: np.ndarray
    """(N,) float32 in [0, 1], descending."""
    masks: np.ndarray | None = None
    """(N, H, W) bool instance masks in the frame's pixels, for a model trained with masks."""

    def semantic_image(self, threshold: float = 0.0) -> np.ndarray | None:
        """(H, W) uint8 class ids (0 background, else the COCO category id, highest score on top:
        ``semantic.semantic_image``) of the detections scoring ``threshold`` or more, or None for a
        model without masks. The ROS 2 bridge publishes it (it may not import this package)."""
        from .semantic import semantic_image

        return None if self.masks is None else semantic_image(self, self.masks.shape[1:], threshold)


class Detector:
    """Runs a trained detector on single frames; ``score_threshold`` drops weak boxes."""

    def __init__(self, path: str | Path, score_threshold: float = 0.3, device: str = "cpu"):
        self.path, self.score_threshold = Path(path), score_threshold
        if not self.path.is_file():
            raise FileNotFoundError(f"{path}: no such detector; train one with `ambulo train-detector`")
        if self.path.suffix == ".onnx":
            import onnxruntime as ort

            from .export import read_sidecar

            meta = read_sidecar(self.path)
            self._session = ort.InferenceSession(str(self.path), providers=["CPUExecutionProvider"])
            names = meta.get("outputs", ["boxes", "scores", "classes"])
            self.inputs: str = meta.get("inputs", "rgb")  # exports before RGB-D models were rgb
            self._run = lambda x: self._session.run(names, {"images": x})
        else:
            import torch

            from .model import ExportedDetector
            from .train import load_trained

            model, meta = load_trained(self.path, device)
            self.inputs = model.cfg.inputs
            graph = ExportedDetector(model).eval()

            def run(x: np.ndarray):
                with torch.no_grad():
                    return [t.cpu().numpy() for t in graph(torch.from_numpy(x).to(device))]

            self._run = run
        self.categories: list[str] = list(meta["categories"])
        self.category_ids = np.asarray(meta["category_ids"], np.int64)
        self.canvas_hw: tuple[int, int] = tuple(meta["canvas_hw"])

    @property
    def needs_depth(self) -> bool:
        """Whether frames must come with their depth (a model trained with ``inputs="rgbd"`` or ``"rgbdh"``)."""
        return self.inputs in ("rgbd", "rgbdh")

    @property
    def needs_height(self) -> bool:
        """Whether frames must come with their height above the floor too (``inputs="rgbdh"``)."""
        return self.inputs == "rgbdh"

    def __call__(self, rgb: np.ndarray, depth_m: np.ndarray | None = None,
                 height_m: np.ndarray | None = None) -> Detections:
        """Detections in ``rgb`` (H, W, 3) uint8; ``depth_m`` (H, W) float depth to the image plane (m;
        0 or NaN: no return), the same camera's, required by an rgbd model and ignored by an rgb one;
        ``height_m`` (H, W) each pixel's height above the floor (m; ``height.height_above_floor_m`` of that
        depth and the camera's pose), required by an rgbdh model and ignored by the others."""
        if rgb.ndim != 3 or rgb.shape[2] < 3 or rgb.dtype != np.uint8:
            raise ValueError(f"a frame must be (H, W, 3) uint8, got {rgb.shape} {rgb.dtype}")
        h, w = rgb.shape[:2]
        ch, cw = self.canvas_hw
        if h > ch or w > cw:
            raise ValueError(f"a {w}x{h} frame is larger than the detector's {cw}x{ch} canvas; resize it or "
                             "train on frames of that size")
        canvas = np.zeros((1, 3 + self.needs_depth + self.needs_height, ch, cw), np.float32)
        canvas[0, :3, :h, :w] = rgb[..., :3].transpose(2, 0, 1) / np.float32(255)
        if self.needs_depth:
            if depth_m is None or np.shape(depth_m)[:2] != (h, w):
                raise ValueError(f"{self.path} is an RGB-D detector: give each frame's depth (H, W) in m as well, "
                                 f"the frame's size {w}x{h} (got {None if depth_m is None else np.shape(depth_m)})")
            import torch

            from .model import depth_channel

            depth = np.asarray(depth_m, np.float32).reshape(h, w)
            canvas[0, 3, :h, :w] = depth_channel(torch.from_numpy(depth)).numpy()
        if self.needs_height:
            if height_m is None or np.shape(height_m)[:2] != (h, w):
                raise ValueError(f"{self.path} is an RGB-D-height detector: give each frame's height above the floor "
                                 f"(H, W) in m as well (ambulo.detection.height.height_above_floor_m of its depth and "
                                 f"the camera's pose), the frame's size {w}x{h} "
                                 f"(got {None if height_m is None else np.shape(height_m)})")
            import torch

            from .model import height_channel

            height = np.asarray(height_m, np.float32).reshape(h, w)
            canvas[0, 4, :h, :w] = height_channel(torch.from_numpy(height)).numpy()
        boxes, scores, classes, *masks = (a[0] for a in self._run(canvas))
        keep = scores >= self.score_threshold
        boxes = boxes[keep].astype(np.float32)
        boxes[:, 0::2] = boxes[:, 0::2].clip(0, w)
        boxes[:, 1::2] = boxes[:, 1::2].clip(0, h)
        classes = classes[keep].astype(np.int64)
        pasted = None
        if masks:  # stride-4 probabilities of every detection: only the kept ones become pixels
            import torch

            from .model import paste_masks

            pasted = paste_masks(torch.from_numpy(np.ascontiguousarray(masks[0][keep])), torch.from_numpy(boxes),
                                 (h, w)).numpy()
        return Detections(boxes_px=boxes, labels=[self.categories[k] for k in classes],
                          category_ids=self.category_ids[classes], scores=scores[keep].astype(np.float32),
                          masks=pasted)
