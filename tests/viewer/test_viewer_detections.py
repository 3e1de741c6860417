"""``ShownDetector`` (what ``ambulo bridge --detector RUN --viewer web`` wraps the bridge's detector in):
each call returns the detector's result unchanged and the page shows that frame with its boxes
outlined. Read from viser's server-side GUI (no browser); waits are on conditions."""

from __future__ import annotations

import time

import numpy as np
import pytest

pytest.importorskip("viser")
import ambulo.viewer
from ambulo.detection.detector import Detections
from ambulo.sim import World
from ambulo.viewer.detections import IMAGE_NAME, ShownDetector
from ports import free_port

LIMIT_S = 120.0



class BoxFinder:
    """A detector stand-in: one 'box' around the frame's white pixels; ``canvas_hw`` as a Detector has."""

    canvas_hw = (48, 64)

    def __call__(self, rgb: np.ndarray) -> Detections:
        ys, xs = np.nonzero(rgb.min(axis=2) > 200)
        boxes = np.array([[xs.min(), ys.min(), xs.max() + 1, ys.max() + 1]], np.float32)
        return Detections(boxes_px=boxes, labels=["box"], category_ids=np.array([1]), scores=np.array([0.9], np.float32))


def test_each_detected_frame_is_shown_with_its_boxes(box_world):
    world = box_world((0.0, 0.0, 0.1), physics_dt=0.01)
    world.reset()
    viewer = ambulo.viewer.serve(world, port=free_port(), announce=False, process=False)
    try:
        viewer.controls.speed = None
        detector = ShownDetector(BoxFinder(), viewer)
        frame = np.zeros((48, 64, 3), np.uint8)
        frame[10:30, 20:44] = 255
        found = detector(frame)
        np.testing.assert_array_equal(found.boxes_px, [[20, 10, 44, 30]])  # the detector's own result
        assert detector.canvas_hw == (48, 64)
        handles = viewer.page.overlays._image_handles
        deadline = time.monotonic() + LIMIT_S
        while IMAGE_NAME not in handles:
            assert time.monotonic() < deadline, "the detected frame was not shown"
            world.step(render=False)
            time.sleep(0.005)
        shown = np.asarray(handles[IMAGE_NAME].image)
        assert shown.shape == (48, 64, 3)
        assert shown[20, 20].tolist() != [255, 255, 255]  # the box's outline on its left edge
        assert shown[20, 32].tolist() == [255, 255, 255]  # inside: the frame as it was
        assert shown[40, 5].tolist() == [0, 0, 0]
    finally:
        viewer.close()
        World.clear_instance()
