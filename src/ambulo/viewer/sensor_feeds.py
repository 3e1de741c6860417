"""Sensors of the watched simulation drawn without the program feeding them: each lidar's last
scan of the watched world becomes the "points" overlay ``lidar<prim path, / as _>``
(``/overlay/points/lidar_World_Jetbot_chassis_lidar``).

The simulation side adds the scan's rows (``points_w`` and ``hit`` of the watched world) to the
frame it copies anyway (``frames.copy_world``: sliced on the device, copied off it without a sync),
only when the stream asked for a frame; it never scans: the viewer shows the scan the program last
made (``Lidar.last_frame``), so it costs no ray casts. The page's side keeps the hits and feeds
them to its overlays (``points``).
"""

from __future__ import annotations

import numpy as np
import torch

from ..sensors.lidar import Lidar
from .feed import OverlayFeed

LIDAR_COLOUR = (255, 140, 0)
"""Lidar returns are orange: apart from the green of points a program shows (``show_points``)."""
PREFIX = "lidar:"
"""Frame extras that are a lidar's scan: ``lidar:<name>:points`` (R, 3) m and ``lidar:<name>:hit`` (R,)."""


class SensorFeeds:
    """The lidars among a simulation's components, and their rows of one world."""

    def __init__(self) -> None:
        self.lidars: dict[str, Lidar] = {}

    def set_sensors(self, components) -> None:
        """Find the lidars (Isaac-style wrappers hold theirs as ``sensor``)."""
        self.lidars = {}
        for c in components:
            sensor = c if isinstance(c, Lidar) else getattr(c, "sensor", None)
            if isinstance(sensor, Lidar):
                self.lidars["lidar" + sensor.prim_path.replace("/", "_")] = sensor

    def rows(self, world: int) -> dict[str, torch.Tensor]:
        """The watched world's last scan of each lidar that scanned: frame extras (``PREFIX``)."""
        rows = {}
        for name, lidar in self.lidars.items():
            scan = lidar.last_frame
            if scan is not None:
                rows[f"{PREFIX}{name}:points"] = scan.points_w[world]
                rows[f"{PREFIX}{name}:hit"] = scan.hit[world].reshape(-1)
        return rows


def feed_scans(extras: dict[str, np.ndarray], feed: OverlayFeed) -> None:
    """Put each lidar scan in ``extras`` (host arrays of a frame) into ``feed`` as its hits' points,
    float32 world m, when it changed since the last put."""
    for key, points_w in extras.items():
        if not (key.startswith(PREFIX) and key.endswith(":points")):
            continue
        name = key[len(PREFIX):-len(":points")]
        hits = np.asarray(points_w, dtype=np.float32)[np.asarray(extras[f"{PREFIX}{name}:hit"], dtype=bool)]
        layer = f"points/{name}"
        last = feed.get(layer)
        if last is None or last[0].shape != hits.shape or not np.array_equal(last[0], hits):
            feed.put(layer, (hits, LIDAR_COLOUR))
