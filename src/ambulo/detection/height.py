"""Height above the floor of every pixel, from its depth and the camera's pose: the input channel of
``inputs="rgbdh"`` models.

Why: a detector that reads depth learns the floor's depth row by row for the camera height it was trained
at; a camera 0.25-0.45 m higher (issue 27's split (b)) changes the depth of everything, and its objects'
depths at each row. The height of a point above the floor does not depend on where the camera stands or how
it is pitched: an object's pixels read the same heights from any viewpoint. The robot knows its camera's pose
(the datasets record it per frame: the ``camera`` of its line in ``frames/records-*.jsonl``), so the channel
costs one matrix
product per pixel.

The math is ``sensors.floor_height.height_above_floor_m`` (its conventions: OpenCV camera, K, world ->
camera extrinsics, world z up, the floor at z 0), re-exported here.
"""

from __future__ import annotations

import numpy as np

from ambulo.sensors.floor_height import height_above_floor_m


def camera_of_record(record: dict) -> tuple[np.ndarray, np.ndarray]:
    """(intrinsics (3, 3), extrinsics_cw (4, 4)) of a frame record (``replicator.writers``' ``camera``)."""
    camera = record["camera"]
    return np.asarray(camera["intrinsics"], np.float64), np.asarray(camera["extrinsics_cw"], np.float64)


__all__ = ["camera_of_record", "height_above_floor_m"]
