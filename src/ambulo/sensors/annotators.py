"""Ground truth computed from a rendered geom-id image, depth and the model's geometry.

Instances are the bodies that carry a semantic label (``ambulo.core.semantics``);
an instance owns its body's geoms and those of descendants without their own
label, so labelling a robot's root labels the whole robot. Instance ids are
1..K in body order, 0 is background; semantic ids are 1..C in label order.

Image coordinates follow OpenCV: pixel (u, v) = (column, row) has its centre at
integer coordinates, and the camera frame has x right, y down, z forward.
"""

from __future__ import annotations

from dataclasses import dataclass

import mujoco
import numpy as np

from ambulo.core.semantics import semantic_labels

from . import box_kernel

# Corners of the unit cube [-1, 1]^3 and its 12 edges as corner index pairs.
_CUBE = np.array([[x, y, z] for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)], np.float64)
_EDGES = np.array([(a, b) for a in range(8) for b in range(a + 1, 8)
                   if np.abs(_CUBE[a] - _CUBE[b]).sum() == 2], np.int64)


@dataclass(kw_only=True)
class InstanceTable:
    """The labelled objects of a model and how geoms map to them."""

    body_ids: np.ndarray
    """(K,) int: the labelled body of instance k+1."""
    labels: list[str]
    """K class labels."""
    categories: list[str]
    """Sorted unique labels; semantic id of label c is categories.index(c) + 1."""
    semantic_ids: np.ndarray
    """(K+1,) int: semantic id per instance id (index 0 = background = 0)."""
    geom_instance: np.ndarray
    """(ngeom+1,) int32: instance id of geom g at index g+1; index 0 (no geom) -> 0."""
    names: list[str]
    """K body names (prim paths)."""

    @property
    def num_instances(self) -> int:
        return len(self.labels)

    def geoms_of(self, instance_id: int) -> np.ndarray:
        return np.flatnonzero(self.geom_instance[1:] == instance_id)

    @property
    def instance_geoms(self) -> tuple[np.ndarray, np.ndarray]:
        """All geoms of instances, sorted by instance, and each geom's instance id (cached)."""
        if getattr(self, "_instance_geoms", None) is None:
            geoms = np.flatnonzero(self.geom_instance[1:] > 0)
            order = np.argsort(self.geom_instance[1:][geoms], kind="stable")
            geoms = geoms[order]
            self._instance_geoms = (geoms, self.geom_instance[1:][geoms])
        return self._instance_geoms

    @property
    def instance_groups(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """``instance_geoms``' runs per instance (cached): where each instance's geoms start in
        them, that instance's id, and each geom's labelled body. Per-frame boxes reduce over
        these runs; they depend on the table alone, so they are worked out once."""
        if getattr(self, "_instance_groups", None) is None:
            _, owner = self.instance_geoms
            starts = np.flatnonzero(np.concatenate(([True], owner[1:] != owner[:-1]))) if len(owner) \
                else np.zeros(0, np.int64)
            self._instance_groups = (starts, owner[starts], self.body_ids[owner - 1])
        return self._instance_groups


def instance_table(model: mujoco.MjModel) -> InstanceTable:
    labels_by_body = semantic_labels(model)
    body_ids = np.array(sorted(labels_by_body), np.int64)
    instance_of_body = np.zeros(model.nbody, np.int32)
    for k, b in enumerate(body_ids):
        instance_of_body[b] = k + 1
    # bodies are stored parent-first, so one forward pass propagates labels down the tree
    for b in range(1, model.nbody):
        if instance_of_body[b] == 0:
            instance_of_body[b] = instance_of_body[model.body_parentid[b]]
    labels = [labels_by_body[b] for b in body_ids]
    categories = sorted(set(labels))
    semantic = np.array([0] + [categories.index(c) + 1 for c in labels], np.int32)
    geom_instance = np.concatenate([[0], instance_of_body[model.geom_bodyid]]).astype(np.int32)
    names = [mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_BODY, int(b)) or f"body{b}" for b in body_ids]
    return InstanceTable(body_ids=body_ids, labels=labels, categories=categories,
                         semantic_ids=semantic, geom_instance=geom_instance, names=names)


def instance_map(geom_ids: np.ndarray, table: InstanceTable) -> np.ndarray:
    """(H, W) geom ids (-1 = none) -> (H, W) int32 instance ids (0 = background)."""
    # the lookup table rotated by one, so geom id -1 reads its last entry (index 0: background);
    # np.take of the ids as they are costs half of fancy indexing with ``geom_ids + 1``
    lut = table.geom_instance
    return np.take(np.concatenate((lut[1:], lut[:1])), geom_ids)


def tight_boxes(instances: np.ndarray, num_instances: int) -> tuple[np.ndarray, np.ndarray]:
    """Box of each instance's visible pixels and its pixel count.

    Returns ``boxes`` (K, 4) int [x_min, y_min, x_max, y_max] inclusive pixel
    indices (-1 where invisible) and ``pixels`` (K,) int visible pixel counts.

    One pass over the image finds its runs of equal ids in row order; a run spans
    rows r0..r1 and, within a row, columns c0..c1 (all columns when it wraps onto
    the next row). Each instance's box is the min/max over its runs: a few thousand
    runs instead of one pass over the pixels per instance.
    """
    h, w = instances.shape
    flat = instances.ravel()
    change = np.flatnonzero(flat[1:] != flat[:-1]) + 1
    starts = np.concatenate(([0], change))
    ends = np.concatenate((change, [flat.size]))
    values = flat[starts]
    fg = values > 0
    order = np.argsort(values[fg], kind="stable")
    return boxes_of_runs(starts[fg][order], ends[fg][order], values[fg][order], w, num_instances)


def boxes_of_runs(starts: np.ndarray, ends: np.ndarray, ids: np.ndarray, line_px: int, num_instances: int,
                  column_major: bool = False) -> tuple[np.ndarray, np.ndarray]:
    """``tight_boxes`` from an image's runs of equal ids: (R,) ``starts`` and ``ends`` (exclusive) in the
    flattened image (lines of ``line_px`` pixels: rows, or columns when ``column_major``), ``ids`` > 0,
    grouped by id (sorted). A run spans lines l0..l1 and, within a line, positions p0..p1 (the whole
    line when it wraps onto the next); each id's box is the min/max over its runs."""
    k = num_instances
    boxes = np.full((k, 4), -1, np.int64)
    pixels = np.bincount(ids, weights=ends - starts, minlength=k + 1)[1:k + 1].astype(np.int64)
    if len(ids) == 0:
        return boxes, pixels
    l0, p0 = np.divmod(starts, line_px)
    l1, p1 = np.divmod(ends - 1, line_px)
    wraps = l1 > l0  # covers the end of line l0 and the start of line l1: every position
    p0[wraps], p1[wraps] = 0, line_px - 1
    x0, y0, x1, y1 = (l0, p0, l1, p1) if column_major else (p0, l0, p1, l1)
    first = np.flatnonzero(np.concatenate(([True], ids[1:] != ids[:-1])))
    rows = ids[first] - 1
    boxes[rows, 0] = np.minimum.reduceat(x0, first)
    boxes[rows, 1] = np.minimum.reduceat(y0, first)
    boxes[rows, 2] = np.maximum.reduceat(x1, first)
    boxes[rows, 3] = np.maximum.reduceat(y1, first)
    return boxes, pixels


def instance_boxes_3d(table: InstanceTable, model: mujoco.MjModel, body_pos_w: np.ndarray,
                      body_rot_w: np.ndarray, geom_pos_w: np.ndarray, geom_rot_w: np.ndarray,
                      corners_w: np.ndarray | None = None):
    """Oriented 3D box of each instance, aligned with its labelled body's frame.

    The box encloses the bounding boxes (``geom_aabb``) of the instance's geoms.
    Inputs are one world's poses: body (nbody, 3) and (nbody, 3, 3), geom
    (ngeom, 3) and (ngeom, 3, 3); ``corners_w``: ``geom_corners_w`` of the instances' geoms
    for these poses, when the caller has them already (the loose boxes use the same).
    Returns ``center_w`` (K, 3) m, ``rot_w`` (K, 3, 3) (box axes as columns) and
    ``half_extent`` (K, 3) m.
    """
    k = table.num_instances
    center_w, half = np.zeros((k, 3)), np.zeros((k, 3))
    rot_w = np.zeros((k, 3, 3))
    rot_w[:, [0, 1, 2], [0, 1, 2]] = 1.0
    geoms, owner = table.instance_geoms
    if len(geoms) == 0:
        return center_w, rot_w, half
    starts, ids, bodies = table.instance_groups
    corners = geom_corners_w(geoms, model, geom_pos_w, geom_rot_w) if corners_w is None else corners_w  # (G, 8, 3)
    local = np.einsum("gcj,gji->gci", corners - body_pos_w[bodies][:, None], body_rot_w[bodies])
    if box_kernel.active():  # the same minima and maxima in one compiled loop
        lo, hi = box_kernel.extents_of_corners(local, starts)
    else:
        lo = np.minimum.reduceat(local.min(1), starts)
        hi = np.maximum.reduceat(local.max(1), starts)
    idx = ids - 1
    b = table.body_ids[idx]
    center_w[idx] = body_pos_w[b] + np.einsum("kij,kj->ki", body_rot_w[b], (lo + hi) / 2)
    rot_w[idx], half[idx] = body_rot_w[b], (hi - lo) / 2
    return center_w, rot_w, half


def geom_corners_w(geoms: np.ndarray, model: mujoco.MjModel, geom_pos_w: np.ndarray,
                   geom_rot_w: np.ndarray) -> np.ndarray:
    """(G, 8, 3) world corners of the geoms' local bounding boxes (``geom_aabb``)."""
    aabb = model.geom_aabb[geoms].reshape(-1, 2, 3)
    local = aabb[:, None, 0] + _CUBE[None] * aabb[:, None, 1]
    return geom_pos_w[geoms, None] + np.einsum("gij,gcj->gci", geom_rot_w[geoms], local)


def loose_boxes(table: InstanceTable, model: mujoco.MjModel, geom_pos_w: np.ndarray, geom_rot_w: np.ndarray,
                extrinsics_cw: np.ndarray, k_matrix: np.ndarray, width: int, height: int,
                near_m: float, corners_w: np.ndarray | None = None) -> list[np.ndarray | None]:
    """Loose 2D box per instance, all instances' geoms at once: [x_min, y_min, x_max, y_max]
    (float px, clipped to the image) around the projected corners of the instance's geoms'
    bounding boxes, or None when nothing is in front of the camera or inside the image.

    ``extrinsics_cw`` maps world to the OpenCV camera frame. Box edges crossing the near
    plane are cut there, so boxes partly behind the camera still project correctly.
    ``corners_w``: ``geom_corners_w`` of the instances' geoms, when the caller has them.
    """
    out: list[np.ndarray | None] = [None] * table.num_instances
    ids, boxes = loose_box_array(table, model, geom_pos_w, geom_rot_w, extrinsics_cw, k_matrix, width, height,
                                 near_m, corners_w)
    for inst, box in zip(ids.tolist(), boxes):
        out[inst - 1] = box
    return out


def loose_box_array(table: InstanceTable, model: mujoco.MjModel, geom_pos_w: np.ndarray, geom_rot_w: np.ndarray,
                    extrinsics_cw: np.ndarray, k_matrix: np.ndarray, width: int, height: int,
                    near_m: float, corners_w: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    """``loose_boxes`` of the instances in view only, as arrays: their ids (n,) int64, ascending, and
    boxes (n, 4) float [x_min, y_min, x_max, y_max] (the same numbers). What a dataset frame keeps:
    no list of K entries to build and turn back into arrays (a Python step per instance)."""
    starts, ids, _ = table.instance_groups
    if len(starts) == 0:
        return np.zeros(0, np.int64), np.zeros((0, 4))
    geoms, _ = table.instance_geoms
    corners = geom_corners_w(geoms, model, geom_pos_w, geom_rot_w) if corners_w is None else corners_w
    corners_c = corners @ extrinsics_cw[:3, :3].T + extrinsics_cw[:3, 3]
    if box_kernel.active():  # the steps below in one compiled loop, the same floats (box_kernel)
        boxes = box_kernel.loose_boxes_of_corners(corners_c, starts, near_m, k_matrix, width, height)
    else:
        boxes = _loose_boxes_numpy(corners_c, starts, near_m, k_matrix, width, height)
    seen = np.all(boxes[:, 2:] > boxes[:, :2], 1)
    return ids[seen].astype(np.int64), boxes[seen]


def _loose_boxes_numpy(corners_c: np.ndarray, starts: np.ndarray, near_m: float, k_matrix: np.ndarray,
                       width: int, height: int) -> np.ndarray:
    """(n, 4) [x_min, y_min, x_max, y_max] of each instance's geoms' corners (G, 8, 3) in the camera
    frame (m), cut at the near plane, projected and clipped to the image (``box_kernel`` compiles it)."""
    points, valid = _near_clipped(corners_c, near_m)
    zs = np.where(valid, points[..., 2], 1.0)
    uv = points[..., :2] / zs[..., None] * np.diag(k_matrix)[:2] + k_matrix[:2, 2]
    lo = np.where(valid[..., None], uv, np.inf).min(1)
    hi = np.where(valid[..., None], uv, -np.inf).max(1)
    lo_i = np.minimum.reduceat(lo, starts)
    hi_i = np.maximum.reduceat(hi, starts)
    lo_i = np.maximum(lo_i, -0.5)
    hi_i = np.minimum(hi_i, [width - 0.5, height - 0.5])
    return np.concatenate([lo_i, hi_i], 1)


def _near_clipped(corners_c: np.ndarray, near_m: float) -> tuple[np.ndarray, np.ndarray]:
    """Box corners (G, 8, 3) plus the points where the 12 edges cross the near plane, (G, 20, 3),
    and which of them are in front of it (G, 20): the outline a camera can see."""
    z = corners_c[..., 2]
    a, b = corners_c[:, _EDGES[:, 0]], corners_c[:, _EDGES[:, 1]]
    za, zb = a[..., 2], b[..., 2]
    crossing = (za - near_m) * (zb - near_m) < 0
    t = np.where(crossing, (near_m - za) / np.where(crossing, zb - za, 1.0), 0.0)
    cut = a + t[..., None] * (b - a)
    return np.concatenate([corners_c, cut], 1), np.concatenate([z >= near_m, crossing], 1)


def distance_from_depth(depth: np.ndarray, k_matrix: np.ndarray) -> np.ndarray:
    """(H, W) distance to the camera centre (m) from distance to the image plane."""
    h, w = depth.shape
    x = (np.arange(w) - k_matrix[0, 2]) / k_matrix[0, 0]
    y = (np.arange(h) - k_matrix[1, 2]) / k_matrix[1, 1]
    return depth * np.sqrt(1.0 + x[None, :] ** 2 + y[:, None] ** 2)


def points_from_depth(depth: np.ndarray, k_matrix: np.ndarray) -> np.ndarray:
    """(H, W, 3) points in the OpenCV camera frame (m) from depth to the image plane."""
    h, w = depth.shape
    x = (np.arange(w) - k_matrix[0, 2]) / k_matrix[0, 0]
    y = (np.arange(h) - k_matrix[1, 2]) / k_matrix[1, 1]
    return np.stack([depth * x[None, :], depth * y[:, None], depth], -1)


def normals_from_depth(depth: np.ndarray, k_matrix: np.ndarray) -> np.ndarray:
    """(H, W, 3) unit surface normals in the OpenCV camera frame, facing the camera.

    Cross product of back-projected point differences along x and y; of the two
    neighbours on each axis the one at the closer depth is used, so normals stay
    exact on planar faces up to depth discontinuities. Zero where depth is infinite.
    """
    p = points_from_depth(np.where(np.isfinite(depth), depth, np.nan), k_matrix)
    dx = _one_sided_difference(p, axis=1)
    dy = _one_sided_difference(p, axis=0)
    n = np.cross(dy, dx)
    n /= np.linalg.norm(n, axis=-1, keepdims=True)
    n = np.where(np.sum(n * p, -1, keepdims=True) > 0, -n, n)
    return np.nan_to_num(n, nan=0.0).astype(np.float32)


def _one_sided_difference(p: np.ndarray, axis: int) -> np.ndarray:
    fwd = np.full_like(p, np.nan)
    bwd = np.full_like(p, np.nan)
    ahead = [slice(None)] * 3
    behind = [slice(None)] * 3
    ahead[axis], behind[axis] = slice(1, None), slice(None, -1)
    ahead, behind = tuple(ahead), tuple(behind)
    fwd[behind] = p[ahead] - p[behind]
    bwd[ahead] = p[ahead] - p[behind]
    use_fwd = ~(np.abs(bwd[..., 2]) < np.abs(fwd[..., 2])) & ~np.isnan(fwd[..., 2])
    return np.where(use_fwd[..., None], fwd, bwd)
