"""Isaac's layouts of 3D boxes, normals and motion vectors, computed from ambulo renders.

Replicator (``rep.AnnotatorRegistry.get_annotator(name)``, BasicWriter's files), after Replicator's
annotator documentation (``omni.replicator.core`` annotators_default: BoundingBox3D, MotionVectors):

- ``bounding_box_3d``: ``{"data": (M,) BBOX_3D_DTYPE, "info": {"bboxIds": (M,) uint32,
  "idToLabels": {"<semanticId>": {"class": label}}, "primPaths": [M paths]}}``, one row per
  labelled prim in view. ``x_min .. z_max`` (m) bound the prim's geoms in the prim's own frame
  (not centred: a prim whose geometry sits off its origin gets uneven extents, as in Isaac);
  ``transform`` (4, 4) is the prim's local-to-world matrix in USD's row-vector convention,
  ``[x, y, z, 1] @ transform`` = world point; ``occlusionRatio`` is 1 - visible / unoccluded
  pixels; ``semanticId`` counts classes from 0 (``idToLabels``' keys), as Replicator's box
  annotators do. ambulo bakes a prim's scale into its geoms' sizes, so ``transform`` is rigid and
  the extents are the scaled ones; Isaac keeps the scale in ``transform`` with unscaled extents.
  The world corners, ``corners @ transform``, are the same.
- ``normals``: (H, W, 4) float32, xyz the unit outward surface normal in the world frame (Kit's
  normals AOV is world space; Replicator's page gives only the layout), w unused (0); 0 where
  nothing is hit.
- ``motion_vectors``: (H, W, 4) float32 pixels, channel x the horizontal motion since the previous
  frame with movement to the left positive, y the vertical motion with movement up positive, z and
  w unused (0) (``ambulo.sim.camera_frame.motion_vectors``).

``SyntheticDataHelper`` (Isaac 2022's ``omni.isaac.synthetic_utils``, which reads
``omni.syntheticdata.sensors``): ``boundingBox3D`` is ``get_bounding_box_3d(parsed=True,
return_corners=True)``: LEGACY_BBOX_3D_DTYPE rows for every labelled prim, the same extents and
transform plus ``corners`` (8, 3) world points in the order LDB, RDB, LUB, RUB, LDF, RDF, LUF, RUF
(L/R: x min/max, D/U: y min/max, B/F: z min/max); ``normals`` is (H, W, 3) float32 (background
0); ``motion-vector`` is (H, W, 4) float32 as ``motion_vectors``.
"""

from __future__ import annotations

import numpy as np

from ambulo.sensors.geom_shapes import instance_extents_b

BBOX_3D_DTYPE = np.dtype([("semanticId", "<u4"), ("x_min", "<f4"), ("y_min", "<f4"), ("z_min", "<f4"),
                          ("x_max", "<f4"), ("y_max", "<f4"), ("z_max", "<f4"), ("transform", "<f4", (4, 4)),
                          ("occlusionRatio", "<f4")])
"""Rows of Replicator's ``bounding_box_3d`` ``data`` (and of BasicWriter's ``bounding_box_3d_*.npy``)."""
LEGACY_BBOX_3D_DTYPE = np.dtype([("uniqueId", "<i4"), ("name", "O"), ("semanticLabel", "O"), ("metadata", "O"),
                                 ("instanceIds", "O"), ("semanticId", "<u4"), ("x_min", "<f4"), ("y_min", "<f4"),
                                 ("z_min", "<f4"), ("x_max", "<f4"), ("y_max", "<f4"), ("z_max", "<f4"),
                                 ("transform", "<f4", (4, 4)), ("corners", "<f4", (8, 3))])
"""Rows of ``SyntheticDataHelper``'s ``boundingBox3D`` (omni.syntheticdata's reduce_bboxes_3d)."""
_EXTENTS = ("x_min", "y_min", "z_min", "x_max", "y_max", "z_max")
# corner k takes max (1) or min (0) of x, y, z: LDB, RDB, LUB, RUB, LDF, RDF, LUF, RUF
_CORNER_PICK = np.array([[(k >> 0) & 1, (k >> 1) & 1, (k >> 2) & 1] for k in range(8)], bool)


def row_transform(rot_w: np.ndarray, pos_w: np.ndarray) -> np.ndarray:
    """(..., 4, 4) local-to-world in USD's row-vector convention from rotations (..., 3, 3)
    (local axes as columns) and positions (..., 3)."""
    m = np.zeros(rot_w.shape[:-2] + (4, 4))
    m[..., :3, :3] = np.swapaxes(rot_w, -1, -2)
    m[..., 3, :3], m[..., 3, 3] = pos_w, 1.0
    return m


def prim_boxes(table, model, poses: dict) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Each labelled prim's box: ``lo``, ``hi`` (K, 3) m in the prim frame and ``transform``
    (K, 4, 4) row-vector local-to-world. ``poses`` is a capture's ``poses_w`` (bodies and geoms
    at the rendered instant, ``ambulo.sensors.Camera``) and ``model`` the compiled model."""
    body_pos, body_rot = poses["body_pos"], poses["body_rot"]
    lo, hi = instance_extents_b(table, model, body_pos, body_rot, poses["geom_pos"], poses["geom_rot"],
                                geom_size=poses.get("geom_size"))
    b = table.body_ids
    return lo, hi, row_transform(body_rot[b], body_pos[b])


def box_corners_w(lo: np.ndarray, hi: np.ndarray, transform: np.ndarray) -> np.ndarray:
    """(K, 8, 3) world corners in Isaac's order (LDB, RDB, LUB, RUB, LDF, RDF, LUF, RUF)."""
    local = np.where(_CORNER_PICK[None], hi[:, None], lo[:, None])
    return np.einsum("kcj,kji->kci", local, transform[:, :3, :3]) + transform[:, None, 3, :3]


def replicator_bounding_box_3d(instance_ids: np.ndarray, table, boxes, occluded: np.ndarray | None) -> dict:
    """Replicator's ``bounding_box_3d`` output for instances ``instance_ids`` (1-based, the prims
    in view); ``boxes`` from ``prim_boxes``; ``occluded`` (K,) occluded share per instance."""
    ids = np.asarray(instance_ids, np.int64)
    k = ids - 1
    lo, hi, transform = boxes
    rows = np.zeros(len(ids), BBOX_3D_DTYPE)
    rows["semanticId"] = table.semantic_ids[ids] - 1  # classes from 0, as Replicator's box annotators
    for axis, name in enumerate("xyz"):
        rows[f"{name}_min"], rows[f"{name}_max"] = lo[k, axis], hi[k, axis]
    rows["transform"] = transform[k]
    rows["occlusionRatio"] = 0.0 if occluded is None else occluded[k]
    labels = {str(int(s)): {"class": table.categories[int(s)]} for s in sorted(set(rows["semanticId"].tolist()))}
    info = {"bboxIds": (ids + 1).astype(np.uint32),  # the instance_segmentation id of the prim
            "idToLabels": labels, "primPaths": [table.names[i] for i in k]}
    return {"data": rows, "info": info}


def legacy_bounding_box_3d(table, boxes) -> np.ndarray:
    """``SyntheticDataHelper``'s ``boundingBox3D``: (K,) LEGACY_BBOX_3D_DTYPE, every labelled prim;
    ``uniqueId``/``instanceIds`` are its instance id, ``semanticId`` as ``semanticSegmentation``."""
    lo, hi, transform = boxes
    corners = box_corners_w(lo, hi, transform)
    rows = np.zeros(table.num_instances, LEGACY_BBOX_3D_DTYPE)
    for k in range(table.num_instances):
        rows[k] = (k + 1, table.names[k], table.labels[k], None, [k + 1], table.semantic_ids[k + 1],
                   *lo[k], *hi[k], transform[k], corners[k])
    return rows


def normals_rgba(normals_w: np.ndarray) -> np.ndarray:
    """Replicator's ``normals``: (H, W, 3) world normals -> (H, W, 4) float32, w unused (0)."""
    return np.concatenate([normals_w, np.zeros(normals_w.shape[:2] + (1,))], -1).astype(np.float32)


__all__ = ["BBOX_3D_DTYPE", "LEGACY_BBOX_3D_DTYPE", "box_corners_w", "legacy_bounding_box_3d", "normals_rgba",
           "prim_boxes", "replicator_bounding_box_3d", "row_transform"]
