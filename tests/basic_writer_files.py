"""Reading a BasicWriter output folder in tests: a frame's files and where world points project."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np


def load(out: Path, stem: str, frame: int, ext: str):
    """``<stem>_<frame:04d>.<ext>`` of ``out``: an array (npy, structured ones included) or JSON."""
    path = out / f"{stem}_{frame:04d}.{ext}"
    return np.load(path, allow_pickle=True) if ext == "npy" else json.loads(path.read_text())


def project(points_w: np.ndarray, params: dict) -> np.ndarray:
    """Pixel (u, v) (pixel centres at integers) of world points (P, 3) through Replicator's row-vector
    view and projection matrices (a frame's ``camera_params``)."""
    view = np.reshape(params["cameraViewTransform"], (4, 4))
    proj = np.reshape(params["cameraProjection"], (4, 4))
    clip = np.c_[points_w, np.ones(len(points_w))] @ view @ proj
    ndc = clip[:, :3] / clip[:, 3:]
    width, height = params["renderProductResolution"]
    return np.c_[(ndc[:, 0] + 1) / 2 * width - 0.5, (1 - ndc[:, 1]) / 2 * height - 0.5]
