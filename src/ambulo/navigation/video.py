"""``EpisodeVideo``: a navigator observer that films an episode and draws its final map.

    video = EpisodeVideo("out/episode.mp4", map_png="out/episode_map.png", title="apartment 3, full")
    nav.add_observer(video)          # images=True: the head camera is rendered for it
    nav.run()
    video.close()                    # the MP4 (atomically, ``render.video.VideoWriter``) and the PNG

Each frame (every ``every_n_frames``-th navigator frame, 10 Hz by default) is the head camera's RGB
beside the top-down map (``topdown``: the map as the robot knows it, route, footstep plan, walked
true and estimated paths, goal, robot) over a one-line caption (time, status, replans when known).
The PNG is the final map at ``map_png_px_per_m`` with the whole episode drawn on it.
"""

from __future__ import annotations

import math
import os
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..render.video import MACRO_BLOCK, VideoWriter
from ..utils.atomic import atomic_write_bytes
from ..utils.validate import Checked
from .navigator import NavSnapshot
from .topdown import TopDown


@dataclass(kw_only=True)
class VideoCfg(Checked):
    fps: float = 10.0
    """Playback rate; the navigator's 10 Hz frames at 10 fps play in real time."""
    every_n_frames: int = 1
    """Film every n-th navigator frame (2: half the drawing and encoding cost)."""
    panel_height_px: int = 480
    """Height of the camera and map panels, px (the camera is scaled to it)."""
    map_max_width_px: int = 800
    """The map panel's scale is chosen once, to fit this width and ``panel_height_px``."""
    caption_height_px: int = 24
    map_png_px_per_m: float = 80.0
    """Scale of the final map PNG (80 px/m: 4 px per 5 cm cell)."""


def _caption(width: int, height: int, text: str) -> np.ndarray:
    """(height, width, 3) uint8 dark strip with ``text`` (Pillow's default font; a plain strip
    without Pillow, which is an optional package)."""
    strip = np.full((height, width, 3), 32, np.uint8)
    try:
        from PIL import Image, ImageDraw
    except ImportError:
        return strip
    img = Image.fromarray(strip)
    ImageDraw.Draw(img).text((6, max(0, (height - 11) // 2)), text, fill=(235, 235, 235))
    return np.asarray(img)


def _resize_nearest(rgb: np.ndarray, height: int) -> np.ndarray:
    """``rgb`` (h, w, 3) scaled to ``height`` rows by nearest neighbour (aspect kept)."""
    h, w = rgb.shape[:2]
    if height % h == 0:  # the usual case (240 -> 480): repeats are ~20x cheaper than a gather
        k = height // h
        return rgb.repeat(k, axis=0).repeat(k, axis=1)
    width = max(1, round(w * height / h))
    rows = np.minimum(h - 1, (np.arange(height) * h / height).astype(np.int64))
    cols = np.minimum(w - 1, (np.arange(width) * w / width).astype(np.int64))
    return rgb.take(rows, axis=0).take(cols, axis=1)


def _fit(img: np.ndarray, height: int, width: int, fill: int = 60) -> np.ndarray:
    """``img`` cropped or padded (``fill`` grey) to (height, width, 3), top-left anchored."""
    out = np.full((height, width, 3), fill, np.uint8)
    h, w = min(height, img.shape[0]), min(width, img.shape[1])
    out[:h, :w] = img[:h, :w]
    return out


class EpisodeVideo:
    """The observer (module docstring). Call it with each ``NavSnapshot``; ``close()`` writes the
    files (``abort()`` drops the video). ``last_frame`` is the latest composed frame."""

    def __init__(self, path: str | os.PathLike | None, cfg: VideoCfg | None = None, *,
                 map_png: str | os.PathLike | None = None, title: str = "", goal_tolerance_m: float = 0.3,
                 view_xy_m=None):
        self.cfg = cfg = cfg or VideoCfg()
        self.path = None if path is None else Path(path)
        self.map_png = None if map_png is None else Path(map_png)
        self.title, self.goal_tolerance_m = title, goal_tolerance_m
        self.view_xy_m = view_xy_m
        """(x0, y0, x1, y1) m: the part of the map drawn (e.g. the scene's extent), or None for all of it."""
        self._writer = None if self.path is None else VideoWriter(self.path, fps=cfg.fps)
        self._topdown: TopDown | None = None
        self._map_size: tuple[int, int] | None = None
        self._calls = 0
        self.estimated_xy_m: list[np.ndarray] = []
        """Estimated base positions, one per navigator frame, m."""
        self.true_xy_m: list[np.ndarray] = []
        """True base positions, one per navigator frame, m."""
        self.last: NavSnapshot | None = None
        self.last_frame: np.ndarray | None = None
        """(H, W, 3) uint8: the latest frame written."""
        self.frames_written = 0

    # -- observer -------------------------------------------------------------------------------
    def __call__(self, snap: NavSnapshot) -> None:
        self.estimated_xy_m.append(np.asarray(snap.estimate.xyyaw[:2], float).copy())
        self.true_xy_m.append(np.asarray(snap.true_pose[:2], float).copy())
        self.last = snap
        self._calls += 1
        if (self._calls - 1) % self.cfg.every_n_frames:
            return
        frame = self.compose(snap)
        self.last_frame = frame
        if self._writer is not None:
            self._writer.append(frame)
            self.frames_written += 1

    def compose(self, snap: NavSnapshot) -> np.ndarray:
        """One video frame: camera | map over a caption, sized to multiples of ``MACRO_BLOCK``."""
        c = self.cfg
        grid = snap.occupancy
        if self._topdown is None:  # the scale is fixed once: every frame has the first one's size
            if self.view_xy_m is None:
                span_y, span_x = (n * grid.resolution_m for n in grid.shape)
            else:
                x0, y0, x1, y1 = self.view_xy_m
                span_y, span_x = y1 - y0, x1 - x0
            self._topdown = TopDown(min(c.panel_height_px / span_y, c.map_max_width_px / span_x), self.view_xy_m)
            base = self._topdown.base(grid)
            self._map_size = (c.panel_height_px, base.shape[1])
        top = self._topdown.draw(grid, route_xy_m=snap.route_xy_m, footsteps=snap.footsteps,
                                 estimated_xy_m=np.array(self.estimated_xy_m), true_xy_m=self._true_path(snap),
                                 goal_xy_m=snap.goal_xy_m, robot_xyyaw=snap.true_pose,
                                 goal_tolerance_m=self.goal_tolerance_m)
        top = _fit(top, *self._map_size)
        if snap.frame is not None and snap.frame.rgb is not None:
            cam = _resize_nearest(np.asarray(snap.frame.rgb.cpu().numpy(), np.uint8), c.panel_height_px)
        else:
            cam = np.full((c.panel_height_px, round(c.panel_height_px * 4 / 3), 3), 60, np.uint8)
        panels = np.concatenate([cam, top], axis=1)
        width = math.ceil(panels.shape[1] / MACRO_BLOCK) * MACRO_BLOCK
        height = math.ceil((panels.shape[0] + c.caption_height_px) / MACRO_BLOCK) * MACRO_BLOCK
        text = f"{self.title}   t {snap.time_s:5.1f} s   {snap.status}"
        if snap.goal_xy_m is not None:
            gap = float(np.linalg.norm(np.asarray(snap.true_pose[:2]) - snap.goal_xy_m))
            text += f"   {gap:4.1f} m to goal"
        if not snap.estimate.tracked:
            text += "   VO LOST"
        frame = np.full((height, width, 3), 32, np.uint8)
        frame[:panels.shape[0], :panels.shape[1]] = panels
        frame[panels.shape[0]:] = _caption(width, height - panels.shape[0], text)
        return frame

    def _true_path(self, snap: NavSnapshot) -> np.ndarray:
        walked = np.asarray(snap.walked_xy_m, float).reshape(-1, 2)
        return np.concatenate([walked, np.asarray(snap.true_pose[:2], float)[None]])

    # -- the end --------------------------------------------------------------------------------
    def final_map(self, px_per_m: float | None = None) -> tuple[np.ndarray, TopDown]:
        """(H, W, 3) uint8 picture of the last snapshot's map with the whole episode, and the
        ``TopDown`` that drew it (its ``pixel_of`` places world points on the picture)."""
        if self.last is None:
            raise RuntimeError("no snapshot was observed: add the video with Navigator.add_observer and run")
        snap = self.last
        topdown = TopDown(px_per_m or self.cfg.map_png_px_per_m, self.view_xy_m)
        img = topdown.draw(snap.occupancy, route_xy_m=snap.route_xy_m, footsteps=snap.footsteps,
                           estimated_xy_m=np.array(self.estimated_xy_m), true_xy_m=self._true_path(snap),
                           goal_xy_m=snap.goal_xy_m, robot_xyyaw=snap.true_pose, goal_tolerance_m=self.goal_tolerance_m)
        return img, topdown

    def write_map_png(self, path: str | os.PathLike) -> Path:
        """Write ``final_map()`` to ``path`` (atomically)."""
        import imageio.v3 as iio

        path = Path(path)
        path.parent.mkdir(parents=True, exist_ok=True)
        atomic_write_bytes(path, iio.imwrite("<bytes>", self.final_map()[0], extension=".png"))
        return path

    def close(self, *, final_pose_xyyaw=None) -> list[Path]:
        """Finish the MP4 and write the map PNG; returns the files written. ``final_pose_xyyaw``
        (the true pose after the last frame) extends the drawn path to where the episode ended."""
        if final_pose_xyyaw is not None and self.last is not None:
            self.true_xy_m.append(np.asarray(final_pose_xyyaw[:2], float))
            self.last.true_pose = np.asarray(final_pose_xyyaw, float)
        written = []
        if self._writer is not None:
            if self.frames_written:
                written.append(self._writer.close())
            else:
                self._writer.abort()
            self._writer = None
        if self.map_png is not None and self.last is not None:
            written.append(self.write_map_png(self.map_png))
        return written

    def abort(self) -> None:
        """Drop the video (an episode that failed with an exception)."""
        if self._writer is not None:
            self._writer.abort()
            self._writer = None


__all__ = ["EpisodeVideo", "VideoCfg"]
