"""``omni.isaac.synthetic_utils.SyntheticDataHelper``: ground truth of the viewport, older scripts' way.

``get_groundtruth(sensor_names, viewport)`` renders the current World's world 0 from the
viewport camera at the viewport's resolution and returns Isaac's sensor outputs: ``rgb``
(H, W, 4) uint8; ``depth`` (distance to the image plane) and ``depthLinear`` (to the camera),
float32 m, inf where nothing is hit; ``semanticSegmentation`` (H, W) uint32 semantic ids (0 =
none); ``instanceSegmentation`` (ids, mapping); ``boundingBox2DTight``/``Loose`` (Isaac's
structured rows, inclusive pixels); ``camera`` (pose, fov, intrinsics); ``pose`` (labelled prims'
world transforms); ``boundingBox3D`` (each labelled prim's box in its own frame, its transform
and world corners), ``normals`` (H, W, 3) float32 world frame and ``motion-vector`` (H, W, 4)
float32 pixels since the previous rendered frame, in ``ground_truth``'s layouts; ``occlusion``
(instanceId, semanticId, occlusionRatio) rows of the prims in view (Isaac 2022's helper names). Labels are the World's (``add_update_semantics``).
"""

from __future__ import annotations

import math
from collections import deque

import numpy as np

from ambulo.isaac.hook import IsaacNameError
from ambulo.render import OffscreenRenderer
from ambulo.sensors import annotators as ann
from ambulo.sensors.geom_shapes import surface_normals_w
from ambulo.sim.camera_frame import motion_vectors
from ambulo.sim.current import current_world

from .ground_truth import legacy_bounding_box_3d, prim_boxes, row_transform
from .viewport import ViewportAPI, get_active_viewport

SENSORS = ("rgb", "depth", "depthLinear", "instanceSegmentation", "semanticSegmentation", "boundingBox2DTight",
           "boundingBox2DLoose", "boundingBox3D", "normals", "motion-vector", "occlusion", "camera", "pose")
BBOX_DTYPE = np.dtype([("uniqueId", "<i4"), ("name", "O"), ("semanticLabel", "O"), ("metadata", "O"),
                       ("instanceIds", "O"), ("semanticId", "<u4"), ("x_min", "<i4"), ("y_min", "<i4"),
                       ("x_max", "<i4"), ("y_max", "<i4")])
"""omni.syntheticdata's reduce_bboxes_2d rows (inclusive pixels)."""
OCCLUSION_DTYPE = np.dtype([("instanceId", "<u4"), ("semanticId", "<u4"), ("occlusionRatio", "<f4")])
"""omni.syntheticdata's get_occlusion rows: 0 fully visible .. 1 fully hidden."""
MAPPING_DTYPE = np.dtype([("uniqueId", "<i4"), ("name", "O"), ("semanticId", "<u4"), ("semanticLabel", "O"),
                          ("instanceIds", "O"), ("metadata", "O")])
KIT_APERTURE_MM = 20.955
"""Horizontal aperture of Kit's viewport camera (mm); with the field of view it gives a focal length."""


def free_camera_pose(cam) -> tuple[np.ndarray, np.ndarray]:
    """Position (3,) m and OpenGL axes (3, 3) of MuJoCo's free camera ``cam`` (lookat, distance,
    azimuth, elevation in deg), as ``mjv_updateCamera`` places it: what the viewport showed."""
    az, el = np.radians(cam.azimuth), np.radians(cam.elevation)
    forward = np.array([np.cos(el) * np.cos(az), np.cos(el) * np.sin(az), np.sin(el)])
    up = np.array([-np.sin(el) * np.cos(az), -np.sin(el) * np.sin(az), np.cos(el)])
    pos = np.asarray(cam.lookat, float) - cam.distance * forward
    return pos, np.stack([np.cross(forward, up), up, -forward], axis=1)


def _extrinsics_cw(pos: np.ndarray, rot_gl: np.ndarray) -> np.ndarray:
    """(4, 4) world -> OpenCV camera of a camera at ``pos`` with OpenGL axes ``rot_gl``."""
    rot_cv = rot_gl @ np.diag([1.0, -1.0, -1.0])
    extr = np.eye(4)
    extr[:3, :3], extr[:3, 3] = rot_cv.T, -rot_cv.T @ pos
    return extr


class SyntheticDataHelper:
    """Isaac's helper: ``initialize(sensor_names, viewport)`` then ``get_groundtruth(names, viewport)``."""

    def __init__(self):
        self._renderer: OffscreenRenderer | None = None
        self._key = None
        self._watched = None
        self._rendered: deque = deque(maxlen=2)
        """(body xpos, xmat, camera pos, OpenGL axes) at the World's last two renders."""

    def initialize(self, sensor_names, viewport_api: ViewportAPI | None = None, viewport=None) -> None:
        """Check the sensor names; rendering starts at the first ``get_groundtruth``. With
        ``motion-vector``, start recording the World's renders (Kit's frames) to compare with."""
        _check(sensor_names)
        if "motion-vector" in sensor_names:
            self._watch_renders()

    def get_groundtruth(self, sensor_names, viewport_api: ViewportAPI | None = None, verify_sensor_init: bool = True,
                        wait_for_sensor_data: float = 0.1, viewport=None) -> dict:
        """Render the World now and return each sensor's output (no wait: ambulo renders on request)."""
        _check(sensor_names)
        if "motion-vector" in sensor_names:
            self._watch_renders()
        view = viewport_api or viewport or get_active_viewport()
        frame = self._render(view)
        gt = {name: frame[name] if name in frame else self._derived(name, frame) for name in sensor_names}
        gt["state"] = {name: True for name in sensor_names}
        return gt

    # -- Isaac's id helpers ----------------------------------------------------------
    def get_semantic_ids(self, semantic_data) -> list[int]:
        return [int(i) for i in np.unique(semantic_data)]

    def get_semantic_id_map(self, semantic_labels=()) -> dict[str, int]:
        table = self._table()
        return {label: table.categories.index(label) + 1 for label in semantic_labels if label in table.categories}

    def get_semantic_label_map(self, semantic_ids=()) -> dict[int, str]:
        table = self._table()
        return {int(i): table.categories[int(i) - 1] for i in semantic_ids if 0 < int(i) <= len(table.categories)}

    def get_mapped_semantic_data(self, semantic_data, user_semantic_label_map: dict, remap_using_base_class=False):
        data = np.array(semantic_data)
        out = data.copy()
        for sid, label in self.get_semantic_label_map(np.unique(data)).items():
            label = label.split(":")[-1] if remap_using_base_class else label
            if label in user_semantic_label_map:
                out[data == sid] = user_semantic_label_map[label]
        return out.tolist()

    # -- the frames motion vectors compare ------------------------------------------
    def _watch_renders(self) -> None:
        world = current_world("recording frames for motion vectors")
        name = f"ambulo_synthetic_data_helper_{id(self)}"
        if self._watched is not world or not world.render_callback_exists(name):
            world.add_render_callback(name, self._on_render)
            self._watched = world
            self._rendered.clear()

    def _on_render(self, event) -> None:
        engine = event["world"].engine
        pos, rot = free_camera_pose(event["world"].viewport_camera)
        self._rendered.append((engine.field("xpos")[0].cpu().numpy().astype(float),
                               engine.field("xmat")[0].reshape(-1, 3, 3).cpu().numpy().astype(float), pos, rot))

    def _motion_vectors(self, f: dict) -> np.ndarray:
        """Where each pixel's point was at the World's previous render, as Kit's frame before."""
        data = f["data"]
        capture = {"depth": f["depth"], "geom_ids": f["geom_ids"],
                   "camera": {"intrinsics": f["k"], "extrinsics_cw": _extrinsics_cw(f["pos"], f["rot_gl"])}}
        previous = None
        if len(self._rendered) == 2:
            xpos, xmat, pos, rot = self._rendered[0]
            previous = ((xpos, xmat), {"intrinsics": f["k"], "extrinsics_cw": _extrinsics_cw(pos, rot)})
        bodies = (np.asarray(data.xpos, float), np.asarray(data.xmat, float).reshape(-1, 3, 3))
        return motion_vectors(capture, f["model"].geom_bodyid, bodies, previous)

    # -- rendering -------------------------------------------------------------------
    def _table(self):
        world = current_world("reading semantic labels")
        if world.model is None:
            raise RuntimeError("call world.reset() before reading ground truth")
        return ann.instance_table(world.model)

    def _render(self, view: ViewportAPI) -> dict:
        world = current_world("rendering ground truth")
        if world.engine is None:
            raise RuntimeError("call world.reset() before get_groundtruth: the stage is not compiled yet")
        width, height = view.resolution
        key = (id(world.model), width, height)
        if self._key != key:
            if self._renderer is not None:
                self._renderer.close()
            self._renderer, self._key = OffscreenRenderer(world.model, width, height), key
            self._instances = ann.instance_table(world.model)
        r, table = self._renderer, self._instances
        data = world.engine.get_data(0)
        r.update_view(world.engine.get_model(0), data, world.viewport_camera)
        rgb = r.render_rgb()
        geom_ids, depth = r.render_ids(want_depth=True)
        instances = ann.instance_map(geom_ids, table)
        k, pos, rot_gl = self._camera(width, height)
        return {"rgb": np.dstack([rgb, np.full((height, width), 255, np.uint8)]), "depth": depth,
                "geom_ids": geom_ids, "instances": instances, "table": table, "k": k, "pos": pos, "rot_gl": rot_gl,
                "data": data, "model": world.model, "width": width, "height": height}

    def _camera(self, width: int, height: int):
        """Intrinsics from the frustum MuJoCo used, and the camera's position and OpenGL axes."""
        cams = self._renderer.scene.camera
        cam = cams[0]
        f = cam.frustum_near * height / (cam.frustum_top - cam.frustum_bottom)
        k = np.array([[f, 0, width / 2 - 0.5], [0, f, height / 2 - 0.5], [0, 0, 1]])
        pos = (np.asarray(cams[0].pos) + np.asarray(cams[1].pos)) / 2
        forward, up = np.asarray(cam.forward, float), np.asarray(cam.up, float)
        rot_gl = np.stack([np.cross(forward, up), up, -forward], axis=1)
        return k, pos, rot_gl

    def _derived(self, name: str, f: dict):
        table, instances = f["table"], f["instances"]
        if name == "depthLinear":
            return ann.distance_from_depth(f["depth"], f["k"]).astype(np.float32)
        if name == "semanticSegmentation":
            return table.semantic_ids[instances].astype(np.uint32)
        if name == "instanceSegmentation":
            rows = [(k + 1, table.names[k], table.semantic_ids[k + 1], table.labels[k], [k + 1], None)
                    for k in range(table.num_instances)]
            return instances.astype(np.uint32), np.array(rows, MAPPING_DTYPE)
        if name == "boundingBox2DTight":
            boxes, pixels = ann.tight_boxes(instances, table.num_instances)
            return self._bbox_rows(table, [(k, boxes[k]) for k in np.flatnonzero(pixels > 0)])
        data, extr = f["data"], _extrinsics_cw(f["pos"], f["rot_gl"])
        if name == "boundingBox3D":
            poses = {"body_pos": data.xpos, "body_rot": data.xmat.reshape(-1, 3, 3), "geom_pos": data.geom_xpos,
                     "geom_rot": data.geom_xmat.reshape(-1, 3, 3)}
            return legacy_bounding_box_3d(table, prim_boxes(table, f["model"], poses))
        if name == "normals":
            return surface_normals_w(f["geom_ids"], f["depth"], f["k"], extr, f["model"], data.geom_xpos,
                                     data.geom_xmat.reshape(-1, 3, 3))
        if name == "motion-vector":
            return self._motion_vectors(f)
        if name == "occlusion":
            return self._occlusion(table, instances)
        if name == "boundingBox2DLoose":
            loose = ann.loose_boxes(table, f["model"], f["data"].geom_xpos, f["data"].geom_xmat.reshape(-1, 3, 3),
                                    extr, f["k"], f["width"], f["height"], self._renderer.near_far()[0])
            return self._bbox_rows(table, [(k, np.rint(b)) for k, b in enumerate(loose) if b is not None])
        if name == "camera":
            return self._camera_params(f)
        if name == "pose":
            return [(table.names[k], int(table.semantic_ids[k + 1]), table.labels[k],
                     row_transform(data.xmat[b].reshape(3, 3), data.xpos[b]))
                    for k, b in enumerate(table.body_ids)]
        return f[name]

    def _occlusion(self, table, instances: np.ndarray) -> np.ndarray:
        """A row per labelled prim in view: 1 - its visible pixels / the pixels it covers alone."""
        _boxes, visible = ann.tight_boxes(instances, table.num_instances)
        rows = []
        for k in range(table.num_instances):
            alone = self._renderer.render_ids_isolated(table.geoms_of(k + 1))  # the prim with no occluder
            total = int(np.count_nonzero(table.geom_instance[alone + 1] == k + 1))
            if total:
                rows.append((k + 1, table.semantic_ids[k + 1], 1.0 - min(1.0, visible[k] / total)))
        return np.array(rows, OCCLUSION_DTYPE)

    @staticmethod
    def _bbox_rows(table, boxes) -> np.ndarray:
        rows = [(k + 1, table.names[k], table.labels[k], None, [k + 1], table.semantic_ids[k + 1], *map(int, box))
                for k, box in boxes]
        return np.array(rows, BBOX_DTYPE)

    def _camera_params(self, f: dict) -> dict:
        width, height, k = f["width"], f["height"], f["k"]
        near, far = self._renderer.near_far()
        hfov = 2 * math.atan(width / (2 * k[0, 0]))
        return {"pose": row_transform(f["rot_gl"], f["pos"]), "fov": hfov,
                "focal_length": k[0, 0] * KIT_APERTURE_MM / width, "horizontal_aperture": KIT_APERTURE_MM,
                "intrinsics": k, "resolution": {"width": width, "height": height}, "clipping_range": (near, far)}


def _check(sensor_names) -> None:
    for name in sensor_names:
        if name not in SENSORS:
            raise IsaacNameError(f"ambulo does not provide the SyntheticDataHelper sensor {name!r}; "
                                 f"it provides {', '.join(SENSORS)}", name="omni.isaac.synthetic_utils")
