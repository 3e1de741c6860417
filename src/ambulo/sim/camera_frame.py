"""Isaac Replicator's annotator outputs (what ``Camera.get_current_frame()`` holds) from one
ambulo capture (``ambulo.sensors.Camera.capture``), NumPy, one world.

Id conventions follow Replicator: in ``semantic_segmentation`` and ``instance_segmentation``
id 0 is BACKGROUND (no geometry: sky, beyond the far plane) and 1 is UNLABELLED (geometry
without a semantic label); labelled classes / instances follow from 2, and the ``idToLabels``
dicts have string keys. Pixel coordinates: column x, row y; boxes hold inclusive pixel indices.
"""

from __future__ import annotations

import numpy as np

from ambulo.sensors import annotators as ann

BACKGROUND, UNLABELLED = 0, 1
_FIRST_LABEL = 2  # Replicator's first id after BACKGROUND and UNLABELLED

BBOX_2D_DTYPE = np.dtype([("semanticId", "<u4"), ("x_min", "<i4"), ("y_min", "<i4"), ("x_max", "<i4"),
                          ("y_max", "<i4"), ("occlusionRatio", "<f4")])
"""Rows of Replicator's ``bounding_box_2d_tight`` ``data``."""

ANNOTATOR_NEEDS = {
    "distance_to_image_plane": ("depth",),
    "distance_to_camera": ("distance_to_camera",),
    "semantic_segmentation": ("semantic_segmentation",),
    "instance_segmentation": ("instance_segmentation",),
    "bounding_box_2d_tight": ("bounding_box_2d_tight", "visible_fraction"),
    "pointcloud": ("depth", "rgb", "instance_segmentation"),
    "motion_vectors": ("depth",),
}
"""Isaac annotator -> the ambulo camera annotators its output is computed from."""


def rgba(rgb: np.ndarray) -> np.ndarray:
    """(H, W, 3) uint8 -> (H, W, 4) uint8 with an opaque alpha channel, as Isaac's ``rgb``."""
    alpha = np.full(rgb.shape[:2] + (1,), 255, np.uint8)
    return np.concatenate([rgb, alpha], -1)


def semantic_ids(capture: dict, table) -> np.ndarray:
    """(H, W) uint32 Replicator semantic ids of a capture with ``geom_ids`` and instances."""
    instances = capture["instance_segmentation"] if "instance_segmentation" in capture else \
        ann.instance_map(capture["geom_ids"], table)
    ids = table.semantic_ids[instances] + (_FIRST_LABEL - 1)  # unlabelled geometry: 0 + 1 = UNLABELLED
    return np.where(capture["geom_ids"] < 0, BACKGROUND, ids).astype(np.uint32)


def instance_ids(capture: dict, table) -> np.ndarray:
    """(H, W) uint32 Replicator instance ids: ambulo instance k -> k + 1."""
    instances = capture["instance_segmentation"] if "instance_segmentation" in capture else \
        ann.instance_map(capture["geom_ids"], table)
    ids = instances + (_FIRST_LABEL - 1)  # unlabelled geometry (instance 0) -> UNLABELLED
    return np.where(capture["geom_ids"] < 0, BACKGROUND, ids).astype(np.uint32)


def _base_labels() -> dict:
    return {str(BACKGROUND): {"class": "BACKGROUND"}, str(UNLABELLED): {"class": "UNLABELLED"}}


def semantic_segmentation(capture: dict, table) -> dict:
    """``{"data": (H, W) uint32, "info": {"idToLabels": {"id": {"class": label}}}}``."""
    labels = _base_labels()
    for c, category in enumerate(table.categories):
        labels[str(c + _FIRST_LABEL)] = {"class": category}
    return {"data": semantic_ids(capture, table), "info": {"idToLabels": labels}}


def instance_segmentation(capture: dict, table) -> dict:
    """``{"data": (H, W) uint32, "info": {"idToLabels": {"id": prim path}, "idToSemantics":
    {"id": {"class": label}}}}``; an instance is a labelled body with its unlabelled children."""
    to_labels = {str(BACKGROUND): "BACKGROUND", str(UNLABELLED): "UNLABELLED"}
    to_semantics = _base_labels()
    for k, (path, label) in enumerate(zip(table.names, table.labels)):
        to_labels[str(k + _FIRST_LABEL)] = path
        to_semantics[str(k + _FIRST_LABEL)] = {"class": label}
    return {"data": instance_ids(capture, table),
            "info": {"idToLabels": to_labels, "idToSemantics": to_semantics}}


def bounding_box_2d_tight(capture: dict, table) -> dict:
    """Boxes of the visible labelled instances: ``data`` (M,) of ``BBOX_2D_DTYPE`` (semanticId as
    in ``semantic_segmentation``; ``occlusionRatio`` = 1 - visible / unoccluded pixels), ``info``
    with ``bboxIds`` (M,) uint32 instance ids, ``idToLabels`` and ``primPaths``."""
    boxes = capture["bounding_box_2d_tight"]
    instance = np.asarray(boxes["instance_id"], np.int64)
    data = np.zeros(len(instance), BBOX_2D_DTYPE)
    data["semanticId"] = boxes["semantic_id"] + (_FIRST_LABEL - 1)
    for i, key in enumerate(("x_min", "y_min", "x_max", "y_max")):
        data[key] = boxes["box"][:, i]
    data["occlusionRatio"] = 1.0 - capture["visible_fraction"][instance - 1]
    labels = {str(c + _FIRST_LABEL): {"class": category} for c, category in enumerate(table.categories)}
    info = {"bboxIds": (instance + (_FIRST_LABEL - 1)).astype(np.uint32), "idToLabels": labels,
            "primPaths": [table.names[k - 1] for k in instance]}
    return {"data": data, "info": info}


def camera_points(depth: np.ndarray, k_matrix: np.ndarray) -> np.ndarray:
    """(H, W, 3) points in the ROS camera frame (x right, y down, z forward; m) from depth to
    the image plane, with ambulo's K (pixel centres at integer coordinates)."""
    return ann.points_from_depth(depth, k_matrix)


def to_world(points_c: np.ndarray, extrinsics_cw: np.ndarray) -> np.ndarray:
    """(..., 3) ROS-camera-frame points -> world frame, given T_cw (p_c = R p_w + t)."""
    rot, t = extrinsics_cw[:3, :3], extrinsics_cw[:3, 3]
    return (points_c - t) @ rot


def pointcloud(capture: dict, table, include_unlabelled: bool) -> dict:
    """Replicator's ``pointcloud``: ``data`` (P, 3) float32 world points (m) of the pixels that
    see geometry (labelled ones only unless ``include_unlabelled``), ``info`` with
    ``pointRgb`` (P, 4) uint8, ``pointSemantic`` and ``pointInstance`` (P,) uint32."""
    depth = capture["depth"]
    keep = np.isfinite(depth)
    instances = instance_ids(capture, table)
    if not include_unlabelled:
        keep &= instances > UNLABELLED
    cam = capture["camera"]
    points = to_world(camera_points(depth, cam["intrinsics"])[keep], cam["extrinsics_cw"])
    return {"data": points.astype(np.float32),
            "info": {"pointRgb": rgba(capture["rgb"])[keep], "pointSemantic": semantic_ids(capture, table)[keep],
                     "pointInstance": instances[keep]}}


def distance_to_camera(capture: dict) -> np.ndarray:
    """(H, W) float32 m from the camera centre (inf where nothing is hit)."""
    return capture["distance_to_camera"].astype(np.float32)


def motion_vectors(capture: dict, geom_body: np.ndarray, bodies: tuple, previous: tuple | None) -> np.ndarray:
    """Replicator's ``motion_vectors``: (H, W, 4) float32; channels x, y are where each pixel's
    surface point was in the previous render minus where it is now, in pixels (x > 0: it moved
    left, y > 0: it moved up, as Replicator documents); z, w unused (0). Each point moves with
    the body its geom belongs to, and the camera's own motion counts. Zero at the first render,
    where nothing is hit, and where the point was behind the previous camera.

    ``bodies`` is (xpos (nbody, 3), xmat (nbody, 3, 3)) now; ``previous`` is (bodies, camera
    dict of the capture) of the previous render, or None."""
    depth = capture["depth"]
    out = np.zeros(depth.shape + (4,), np.float32)
    if previous is None:
        return out
    cam = capture["camera"]
    hit = np.isfinite(depth) & (capture["geom_ids"] >= 0)
    rows, cols = np.nonzero(hit)
    p_w = to_world(camera_points(depth, cam["intrinsics"])[hit], cam["extrinsics_cw"])
    body = geom_body[capture["geom_ids"][hit]]
    (pos, mat), ((pos_prev, mat_prev), cam_prev) = bodies, previous
    local = np.einsum("pji,pj->pi", mat[body], p_w - pos[body])
    p_w_prev = np.einsum("pij,pj->pi", mat_prev[body], local) + pos_prev[body]
    extr = cam_prev["extrinsics_cw"]
    p_c_prev = p_w_prev @ extr[:3, :3].T + extr[:3, 3]
    uvw = p_c_prev @ np.asarray(cam_prev["intrinsics"], float).T
    ahead = uvw[:, 2] > 1e-9
    out[rows[ahead], cols[ahead], 0] = uvw[ahead, 0] / uvw[ahead, 2] - cols[ahead]
    out[rows[ahead], cols[ahead], 1] = uvw[ahead, 1] / uvw[ahead, 2] - rows[ahead]
    return out


def annotate(name: str, capture: dict, table, params: dict) -> object:
    """The Isaac output of annotator ``name`` (a key of ``ANNOTATOR_NEEDS``) from ``capture``."""
    if name == "distance_to_image_plane":
        return capture["depth"].astype(np.float32)
    if name == "distance_to_camera":
        return distance_to_camera(capture)
    if name == "semantic_segmentation":
        return semantic_segmentation(capture, table)
    if name == "instance_segmentation":
        return instance_segmentation(capture, table)
    if name == "bounding_box_2d_tight":
        return bounding_box_2d_tight(capture, table)
    if name == "pointcloud":
        return pointcloud(capture, table, params.get("includeUnlabelled", True))
    raise KeyError(name)


__all__ = ["ANNOTATOR_NEEDS", "BBOX_2D_DTYPE", "annotate", "camera_points", "instance_segmentation",
           "motion_vectors", "pointcloud", "rgba", "semantic_segmentation", "to_world"]
