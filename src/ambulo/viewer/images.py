"""Images for the page: a world's cameras rendered on the viewer thread (RGB, depth, segmentation),
depth and segmentation colour-mapped, detections drawn on them.

``CameraRenders`` owns one ``render.OffscreenRenderer``, created on the streaming thread that uses
it (a GL context belongs to a thread), and renders the model's cameras from the viewer's own
``MjData`` (the copied state, ``physics_overlay.StateReplay``): the simulation renders nothing
for the page. The cameras are the compiled model's (``<camera>`` elements, and the cameras
``sensors.Camera`` adds to the model, posed where the sensor put them in the watched world: the
viewer copies that world's ``cam_pos`` / ``cam_quat`` rows with the state).
"""

from __future__ import annotations

import mujoco
import numpy as np
from PIL import Image, ImageDraw

IMAGE_KINDS = ("rgb", "depth", "segmentation")
DEPTH_RANGE_M = (0.1, 8.0)
"""Depth mapped to the colour scale (nearer: warm, farther: cool); beyond it: black."""
BOX_COLOUR = (255, 220, 0)


def colour_depth(depth_m: np.ndarray, range_m: tuple[float, float] = DEPTH_RANGE_M) -> np.ndarray:
    """(H, W, 3) uint8 of an (H, W) depth image, m: near red through yellow, green to blue far;
    no return (inf, NaN, beyond the range) black."""
    near, far = range_m
    depth = np.asarray(depth_m, dtype=np.float32)
    valid = np.isfinite(depth) & (depth >= near) & (depth <= far)
    t = np.clip((np.where(valid, depth, far) - near) / (far - near), 0.0, 1.0)
    # a 4-stop ramp: red (0), yellow (1/3), green (2/3), blue (1)
    stops = np.array([[230, 40, 30], [240, 220, 40], [40, 190, 80], [40, 70, 220]], dtype=np.float32)
    x = t * (len(stops) - 1)
    i = np.minimum(x.astype(int), len(stops) - 2)
    f = (x - i)[..., None]
    rgb = stops[i] * (1 - f) + stops[i + 1] * f
    rgb[~valid] = 0
    return rgb.astype(np.uint8)


def colour_ids(ids: np.ndarray) -> np.ndarray:
    """(H, W, 3) uint8 of an (H, W) integer label image: each id its own stable colour (a hash of
    the id), -1 or 0 (nothing) black."""
    ids = np.asarray(ids, dtype=np.int64)
    h = (ids * 2654435761) & 0xFFFFFF  # Knuth's multiplicative hash spreads neighbouring ids
    rgb = np.stack([(h >> 16) & 255, (h >> 8) & 255, h & 255], axis=-1)
    rgb = 60 + (rgb * 195) // 255  # never darker than the background
    rgb[ids <= 0] = 0
    return rgb.astype(np.uint8)


def draw_detections(rgb: np.ndarray, boxes_px: np.ndarray, labels: list[str], scores: np.ndarray) -> np.ndarray:
    """A copy of ``rgb`` (H, W, 3) uint8 with each box (N, 4) x0 y0 x1 y1 px (``detection.Detections``'
    ``boxes_px``) outlined and labelled "label score"."""
    image = Image.fromarray(np.ascontiguousarray(rgb, dtype=np.uint8))
    draw = ImageDraw.Draw(image)
    for box, label, score in zip(np.asarray(boxes_px, dtype=float).reshape(-1, 4), labels, scores):
        x0, y0, x1, y1 = (float(v) for v in box)
        draw.rectangle((x0, y0, x1, y1), outline=BOX_COLOUR, width=2)
        draw.text((x0 + 2, max(0.0, y0 - 11)), f"{label} {float(score):.2f}", fill=BOX_COLOUR)
    return np.asarray(image)


def camera_names(model: mujoco.MjModel) -> list[str]:
    """The model's cameras by name (``camera_<id>`` for an unnamed one)."""
    return [mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_CAMERA, c) or f"camera_{c}" for c in range(model.ncam)]


class CameraRenders:
    """Renders camera ``cam_id`` of ``model`` from an ``MjData`` (viewer thread only).

    Args:
      model: the compiled model.
      width, height: image size, px (a page panel's thumbnail: small keeps the viewer cheap).
    """

    def __init__(self, model: mujoco.MjModel, width: int = 320, height: int = 240):
        from ..render.offscreen import OffscreenRenderer

        self.model = model
        self.renderer = OffscreenRenderer(model, width, height)
        self._camera = mujoco.MjvCamera()
        self._camera.type = mujoco.mjtCamera.mjCAMERA_FIXED

    def render(self, data: mujoco.MjData, cam_id: int, kind: str, model: mujoco.MjModel | None = None) -> np.ndarray:
        """(H, W, 3) uint8: the camera's ``kind`` image ("rgb"; "depth" colour-mapped; "segmentation":
        one colour per body). ``model``: one of the same structure with the world's own values
        (default the one it was made for)."""
        model = self.model if model is None else model
        if kind not in IMAGE_KINDS:
            raise ValueError(f"image kind {kind!r}: pass one of {IMAGE_KINDS}")
        self._camera.fixedcamid = int(cam_id)
        self.renderer.update_view(model, data, self._camera)
        if kind == "rgb":
            return self.renderer.render_rgb().copy()
        geom_ids, depth = self.renderer.render_ids(want_depth=kind == "depth")
        if kind == "depth":
            return colour_depth(depth)
        body = np.where(geom_ids >= 0, model.geom_bodyid[np.maximum(geom_ids, 0)], -1)
        return colour_ids(body + 1)

    def close(self) -> None:
        self.renderer.close()
