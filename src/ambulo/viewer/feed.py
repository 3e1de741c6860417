"""What features hand the viewer to draw: the navigator's map, plan, footsteps and walked path,
point clouds (a lidar's), images and detections. Each ``put`` copies its values and swaps them in
under a lock held for the swap (the caller, a simulation or navigation loop, never waits for the
page); the streaming thread takes what changed since it last drew (``take``).

The navigator's hook is ``navigator_observer``: ``Navigator.add_observer(viewer.navigator_observer,
images=False)`` hands each ``NavSnapshot`` over (duck-typed: the viewer sits below navigation and
does not import it).
"""

from __future__ import annotations

import threading
from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class MapLayer:
    """A 2-D occupancy map: ``occupancy`` (num_y, num_x) int8 -1 unknown, 0..100 occupied %, row 0
    at y = ``origin_xy_m[1]`` (``maps.Grid2D``'s convention), cells ``resolution_m`` wide."""

    occupancy: np.ndarray
    origin_xy_m: tuple[float, float]
    resolution_m: float


@dataclass(frozen=True)
class Footsteps:
    """Planned foot poses (K, 3) x m, y m, yaw rad (world), sides (K,) +1 left / -1 right, and the
    sole's (length, width), m."""

    poses_xyyaw_w: np.ndarray
    sides: np.ndarray
    foot_size_m: tuple[float, float]


@dataclass(frozen=True)
class FedImage:
    """An image a feature showed (H, W, 3) uint8, with optional detections drawn on it."""

    rgb: np.ndarray
    detections: tuple[np.ndarray, list[str], np.ndarray] | None = None


class OverlayFeed:
    """Latest value per overlay layer, each with a version number the drawing side compares."""

    def __init__(self) -> None:
        self._lock = threading.Lock()
        self._values: dict[str, object] = {}
        self._versions: dict[str, int] = {}

    def put(self, layer: str, value) -> None:
        with self._lock:
            self._values[layer] = value
            self._versions[layer] = self._versions.get(layer, 0) + 1

    def take(self, seen: dict[str, int]) -> dict[str, object]:
        """Layers whose version passed ``seen`` (updated in place): {layer: value}."""
        with self._lock:
            changed = {k: v for k, v in self._values.items() if self._versions[k] != seen.get(k)}
            seen.update({k: self._versions[k] for k in changed})
        return changed

    def get(self, layer: str):
        with self._lock:
            return self._values.get(layer)

    def layers(self) -> list[str]:
        with self._lock:
            return list(self._values)


def as_points_w(points, what: str) -> np.ndarray:
    """(K, 3) float32 world points from (K, 2) (z = 0) or (K, 3) arrays or tensors (copied)."""
    if hasattr(points, "detach"):
        points = points.detach().cpu().numpy()
    points = np.array(points, dtype=np.float32, copy=True)
    if points.ndim != 2 or points.shape[1] not in (2, 3):
        raise ValueError(f"{what}: expected (K, 2) or (K, 3) world points in m, got shape {points.shape}")
    if points.shape[1] == 2:
        points = np.concatenate([points, np.zeros((len(points), 1), np.float32)], axis=1)
    return points


def as_image(image, what: str) -> np.ndarray:
    """(H, W, 3) uint8 copy of an RGB image (array or tensor); (H, W) grey is expanded."""
    if hasattr(image, "detach"):
        image = image.detach().cpu().numpy()
    image = np.array(image, copy=True)
    if image.ndim == 2:
        image = np.repeat(image[..., None], 3, axis=2)
    if image.ndim != 3 or image.shape[2] not in (3, 4):
        raise ValueError(f"{what}: expected an (H, W, 3) RGB image, got shape {image.shape}")
    if image.dtype != np.uint8:
        scale = 255.0 if image.max(initial=0) <= 1.0 else 1.0
        image = np.clip(image * scale, 0, 255).astype(np.uint8)
    return np.ascontiguousarray(image[..., :3])
