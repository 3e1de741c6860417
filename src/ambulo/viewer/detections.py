"""``ShownDetector``: a detector whose every result is also drawn on the web viewer's page.

``ambulo bridge ... --detector RUN --viewer web`` wraps the bridge's detector in it: the bridge runs
the detector on the published camera frames (on its detector thread, or with --detector-inline on its
physics thread) and the page shows each detected frame with the boxes, labels and scores
(``WebViewer.show_image``/``show_detections``, which copy and return at once, from either thread: the
viewer's feed is locked). The page draws; the detector's cost is the bridge's either way.
"""

from __future__ import annotations

import numpy as np

IMAGE_NAME = "detections"
"""The page's image of the detector's frames."""


class ShownDetector:
    """Calls ``detector`` (an ``ambulo.detection.Detector``, or any callable of an (H, W, 3) uint8
    frame returning ``Detections``) and shows the frame and what it found on ``viewer``; every other
    attribute is the detector's (``canvas_hw``, ``categories``)."""

    def __init__(self, detector, viewer, name: str = IMAGE_NAME):
        self.detector, self.viewer, self.name = detector, viewer, name

    def __call__(self, rgb: np.ndarray, depth_m: np.ndarray | None = None, height_m: np.ndarray | None = None):
        """``depth_m``: the frame's depth (H, W) m, passed on to an RGB-D detector (``needs_depth``);
        ``height_m``: its height above the floor (H, W) m, passed on to an RGB-D-height one (``needs_height``)."""
        extra = () if depth_m is None else (depth_m,) if height_m is None else (depth_m, height_m)
        found = self.detector(rgb, *extra)
        self.viewer.show_image(self.name, rgb)
        self.viewer.show_detections(self.name, found)
        return found

    def __getattr__(self, name: str):
        return getattr(self.detector, name)
