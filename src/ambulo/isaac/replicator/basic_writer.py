"""BasicWriter's file layout, written from ambulo captures: what Replicator scripts' datasets look like.

Per frame ``NNNN`` (``frame_padding`` digits, from 0), in ``output_dir``:

- ``rgb_NNNN.png``: RGBA uint8.
- ``bounding_box_2d_tight_NNNN.npy`` (and ``_loose``): structured rows ``semanticId`` (u4),
  ``x_min, y_min, x_max, y_max`` (i4, inclusive pixels), ``occlusionRatio`` (f4, occluded share
  of the prim's in-image pixels); ``..._labels_NNNN.json`` ``{semanticId: {"class": label}}``;
  ``..._prim_paths_NNNN.json``, one prim path per row.
- ``bounding_box_3d_NNNN.npy``: the ``bounding_box_3d`` annotator's rows (``ground_truth.py``):
  ``semanticId, x_min..z_max`` (the prim's geoms' box in its frame, m), ``transform`` (4x4
  prim-to-world, USD row-vector convention), ``occlusionRatio``; labels and prim paths.
- ``semantic_segmentation_NNNN.png`` (RGBA by default; ``colorize_semantic_segmentation=False``:
  uint16 ids, PNG having no 32-bit grey) + ``semantic_segmentation_labels_NNNN.json``; id 0 is
  BACKGROUND (no geometry), 1 UNLABELLED (geometry without a class), then one id per class.
- ``instance_segmentation_NNNN.png`` + ``_mapping_NNNN.json`` (id -> prim path) +
  ``_semantics_mapping_NNNN.json`` (id -> labels).
- ``distance_to_image_plane_NNNN.npy`` / ``distance_to_camera_NNNN.npy``: float32 m, inf where
  nothing is hit (``colorize_depth``: also a grey PNG, near = bright).
- ``normals_NNNN.png``: world normals as (n + 1) / 2 colours.
- ``camera_params_NNNN.json``: aperture and focal length (mm), near/far, 4x4 view and projection
  matrices (row-vector convention, flattened), resolution.

Each file is written atomically (``ambulo.utils.atomic``): a killed run leaves no partial file.
"""

from __future__ import annotations

import colorsys
from pathlib import Path

import numpy as np

from ambulo.replicator.io import encode_png
from ambulo.utils.atomic import atomic_save_npy, atomic_write_bytes, atomic_write_json

from .errors import Namespace, unsupported
from .ground_truth import prim_boxes, replicator_bounding_box_3d

BBOX_2D_DTYPE = np.dtype([("semanticId", "<u4"), ("x_min", "<i4"), ("y_min", "<i4"), ("x_max", "<i4"),
                          ("y_max", "<i4"), ("occlusionRatio", "<f4")])
BACKGROUND, UNLABELLED = 0, 1
_UNSUPPORTED_FLAGS = {
    "instance_id_segmentation": "use instance_segmentation=True",
    "occlusion": "read occlusionRatio in the bounding box files",
    "motion_vectors": "frames are independent draws; there is no motion",
    "pointcloud": "back-project distance_to_image_plane with camera_params",
    "skeleton_data": "ambulo scenes have no skeletons",
    "pointcloud_include_unlabelled": "back-project distance_to_image_plane with camera_params",
    "use_common_output_dir": "one render product per run writes into output_dir",
}
# annotators of ambulo's Camera each flag needs
_NEEDS = {"rgb": ("rgb",), "bounding_box_2d_tight": ("bounding_box_2d_tight", "visible_fraction"),
          "bounding_box_2d_loose": ("bounding_box_2d_loose", "visible_fraction"),
          "bounding_box_3d": ("poses_w", "bounding_box_2d_loose", "visible_fraction"),
          "semantic_segmentation": ("semantic_segmentation",), "instance_segmentation": ("instance_segmentation",),
          "distance_to_image_plane": ("depth",), "distance_to_camera": ("distance_to_camera",),
          "normals": ("normals",), "camera_params": ()}


def palette(ids: np.ndarray) -> np.ndarray:
    """(N, 4) uint8 RGBA per id: 0 transparent black, 1 opaque black, then distinct hues."""
    ids = np.asarray(ids, np.int64)
    out = np.zeros((len(ids), 4), np.uint8)
    for k, i in enumerate(ids):
        if i == UNLABELLED:
            out[k] = (0, 0, 0, 255)
        elif i > UNLABELLED:
            rgb = colorsys.hsv_to_rgb((i * 0.618033988749895) % 1.0, 0.75, 0.95)
            out[k] = (*(int(round(255 * c)) for c in rgb), 255)
    return out


def _key(rgba) -> str:
    return "(" + ", ".join(str(int(c)) for c in rgba) + ")"


class BasicWriter:
    """``rep.WriterRegistry.get("BasicWriter")``: ``initialize(output_dir=..., rgb=True, ...)``, then
    ``attach([render_product])``; the orchestrator hands it every rendered frame."""

    def __init__(self):
        self.output_dir: Path | None = None
        self.flags: dict[str, bool] = {}
        self.render_products: list = []

    def initialize(self, output_dir: str | None = None, semantic_types=None, rgb: bool = False,
                   bounding_box_2d_tight: bool = False, bounding_box_2d_loose: bool = False,
                   semantic_segmentation: bool = False, instance_segmentation: bool = False,
                   distance_to_camera: bool = False, distance_to_image_plane: bool = False,
                   bounding_box_3d: bool = False, normals: bool = False, camera_params: bool = False,
                   image_output_format: str = "png", colorize_semantic_segmentation: bool = True,
                   colorize_instance_segmentation: bool = True, colorize_instance_id_segmentation: bool = True,
                   colorize_depth: bool = False, frame_padding: int = 4, semantic_filter_predicate=None,
                   s3_bucket=None, s3_region=None, s3_endpoint=None, backend=None, **flags) -> None:
        for name, on in flags.items():
            if name not in _UNSUPPORTED_FLAGS:
                raise TypeError(f"BasicWriter.initialize() got an unexpected keyword argument {name!r}")
            if on:
                raise unsupported(f"BasicWriter({name}=True)", _UNSUPPORTED_FLAGS[name])
        if s3_bucket or backend is not None:
            raise unsupported("BasicWriter backends", "ambulo writes to a local output_dir")
        if not output_dir:
            raise ValueError("No `backend`, `output_dir` or `s3_` parameter specified, unable to initialize writer.")
        if image_output_format.lower() != "png":
            raise unsupported(f"BasicWriter(image_output_format={image_output_format!r})", "rgb is written as png")
        if semantic_types not in (None, ["class"], ("class",)) or semantic_filter_predicate not in (None, "class:*"):
            raise unsupported("BasicWriter semantic filters other than class", "label prims with ('class', label)")
        self.output_dir = Path(output_dir).expanduser()
        self.flags = {"rgb": rgb, "bounding_box_2d_tight": bounding_box_2d_tight,
                      "bounding_box_2d_loose": bounding_box_2d_loose, "bounding_box_3d": bounding_box_3d,
                      "semantic_segmentation": semantic_segmentation, "instance_segmentation": instance_segmentation,
                      "distance_to_image_plane": distance_to_image_plane, "distance_to_camera": distance_to_camera,
                      "normals": normals, "camera_params": camera_params}
        self.colorize = {"semantic": colorize_semantic_segmentation, "instance": colorize_instance_segmentation,
                         "depth": colorize_depth}
        self.frame_padding = int(frame_padding)
        self.frame_id = 0

    def attach(self, render_products, **_trigger_args) -> None:
        """Write the frames of ``render_products`` (one product, or a list of one)."""
        from .graph import current_graph  # the graph imports writers lazily too

        if self.output_dir is None:
            raise RuntimeError("call writer.initialize(output_dir=..., ...) before writer.attach(...)")
        products = list(render_products) if isinstance(render_products, (list, tuple)) else [render_products]
        if len(products) != 1:
            raise unsupported("BasicWriter on several render products", "attach one render product per writer")
        self.render_products = products
        graph = current_graph()
        if self not in graph.writers:
            graph.writers.append(self)

    def detach(self) -> None:
        from .graph import current_graph

        self.render_products = []
        graph = current_graph()
        if self in graph.writers:
            graph.writers.remove(self)

    @property
    def annotators(self) -> tuple[str, ...]:
        """ambulo Camera annotators this writer's flags need."""
        return tuple(dict.fromkeys(a for flag, on in self.flags.items() if on for a in _NEEDS[flag]))

    # -- one frame ----------------------------------------------------------------
    def write(self, capture: dict, table, camera: dict, model=None) -> None:
        """Write one frame: ``capture`` from ambulo's Camera, ``table`` its InstanceTable,
        ``camera`` the created camera's focal_length/horizontal_aperture (mm), ``model`` the
        compiled scene (its geoms bound the 3D boxes)."""
        self.output_dir.mkdir(parents=True, exist_ok=True)
        n = f"{self.frame_id:0{self.frame_padding}d}"
        f = self.flags
        if f["rgb"]:
            rgb = capture["rgb"]
            rgba = np.concatenate([rgb, np.full(rgb.shape[:2] + (1,), 255, np.uint8)], axis=2)
            self._bytes(f"rgb_{n}.png", encode_png(rgba))
        occluded = 1.0 - capture["visible_fraction"] if "visible_fraction" in capture else None
        for kind in ("2d_tight", "2d_loose"):
            if f[f"bounding_box_{kind}"]:
                self._boxes_2d(kind, n, capture[f"bounding_box_{kind}"], table, occluded)
        if f["bounding_box_3d"]:
            self._boxes_3d(n, capture, table, model, occluded)
        if f["semantic_segmentation"]:
            self._semantic(n, capture, table)
        if f["instance_segmentation"]:
            self._instance(n, capture, table)
        for flag, key in (("distance_to_image_plane", "depth"), ("distance_to_camera", "distance_to_camera")):
            if f[flag]:
                self._npy(f"{flag}_{n}.npy", capture[key].astype(np.float32))
                if self.colorize["depth"]:
                    self._bytes(f"{flag}_{n}.png", encode_png(_grey_depth(capture[key])))
        if f["normals"]:
            normals = np.nan_to_num(capture["normals"])
            rgb = np.clip((normals * 0.5 + 0.5) * 255.0, 0, 255).astype(np.uint8)
            alpha = np.where(np.isfinite(capture["depth"] if "depth" in capture else normals[..., 0]), 255, 0)
            self._bytes(f"normals_{n}.png", encode_png(np.dstack([rgb, alpha.astype(np.uint8)])))
        if f["camera_params"]:
            atomic_write_json(self.output_dir / f"camera_params_{n}.json", camera_params(capture["camera"], camera))
        self.frame_id += 1

    def _bytes(self, name: str, data: bytes) -> None:
        atomic_write_bytes(self.output_dir / name, data)

    def _npy(self, name: str, array: np.ndarray) -> None:
        atomic_save_npy(self.output_dir / name, array)

    def _boxes_2d(self, kind, n, boxes, table, occluded) -> None:
        ids = np.asarray(boxes["instance_id"], np.int64)
        rows = np.zeros(len(ids), BBOX_2D_DTYPE)
        rows["semanticId"] = np.asarray(boxes["semantic_id"]) - 1
        xyxy = np.asarray(boxes["box"], float).reshape(-1, 4)
        for col, field in enumerate(("x_min", "y_min", "x_max", "y_max")):
            rows[field] = np.rint(xyxy[:, col])
        rows["occlusionRatio"] = 0.0 if occluded is None else occluded[ids - 1]
        self._box_files(f"bounding_box_{kind}", n, rows, ids, table)

    def _boxes_3d(self, n, capture, table, model, occluded) -> None:
        ids = capture["bounding_box_2d_loose"]["instance_id"]  # in view, as Replicator
        boxes = replicator_bounding_box_3d(ids, table, prim_boxes(table, model, capture["poses_w"]), occluded)
        self._box_files("bounding_box_3d", n, boxes["data"], np.asarray(ids, np.int64), table)

    def _box_files(self, stem, n, rows, ids, table) -> None:
        self._npy(f"{stem}_{n}.npy", rows)
        labels = {str(int(s)): {"class": table.categories[int(s)]} for s in sorted(set(rows["semanticId"].tolist()))}
        atomic_write_json(self.output_dir / f"{stem}_labels_{n}.json", labels)
        atomic_write_json(self.output_dir / f"{stem}_prim_paths_{n}.json", [table.names[i - 1] for i in ids])

    def _semantic(self, n, capture, table) -> None:
        sem = capture["semantic_segmentation"].astype(np.int64)
        ids = np.where(sem > 0, sem + 1, np.where(capture["geom_ids"] >= 0, UNLABELLED, BACKGROUND))
        names = {BACKGROUND: {"class": "BACKGROUND"}, UNLABELLED: {"class": "UNLABELLED"}}
        names.update({c + 2: {"class": label} for c, label in enumerate(table.categories)})
        self._segmentation("semantic_segmentation", "labels", n, ids, names, self.colorize["semantic"])

    def _instance(self, n, capture, table) -> None:
        inst = capture["instance_segmentation"].astype(np.int64)
        ids = np.where(inst > 0, inst + 1, np.where(capture["geom_ids"] >= 0, UNLABELLED, BACKGROUND))
        paths = {BACKGROUND: "BACKGROUND", UNLABELLED: "UNLABELLED"}
        paths.update({k + 2: name for k, name in enumerate(table.names)})
        present = self._segmentation("instance_segmentation", "mapping", n, ids, paths, self.colorize["instance"])
        semantics = {key: {"class": table.labels[i - 2]} for key, i in present.items() if i > UNLABELLED}
        atomic_write_json(self.output_dir / f"instance_segmentation_semantics_mapping_{n}.json", semantics)

    def _segmentation(self, stem, suffix, n, ids, names, colorize) -> dict[str, int]:
        """Write the id image (colours or uint16 ids) and the map of the ids present; returns key -> id."""
        present = np.unique(ids)
        if colorize:
            colors = palette(np.arange(int(present.max()) + 1))
            self._bytes(f"{stem}_{n}.png", encode_png(colors[ids]))
            keys = {_key(colors[i]): int(i) for i in present}
        else:
            self._bytes(f"{stem}_{n}.png", encode_png(ids.astype(np.uint16)))
            keys = {str(int(i)): int(i) for i in present}
        atomic_write_json(self.output_dir / f"{stem}_{suffix}_{n}.json", {k: names[i] for k, i in keys.items()})
        return keys


def _grey_depth(depth: np.ndarray) -> np.ndarray:
    """uint8 inverse depth scaled to the frame's nearest hit (near = 255, nothing hit = 0)."""
    finite = np.isfinite(depth) & (depth > 0)
    out = np.zeros(depth.shape, np.uint8)
    if finite.any():
        out[finite] = np.clip(255.0 * depth[finite].min() / depth[finite], 0, 255).astype(np.uint8)
    return out


def camera_params(cam: dict, created: dict) -> dict:
    """Replicator's camera_params: view (world -> camera, OpenGL axes) and projection, row-vector form."""
    width, height = int(cam["width"]), int(cam["height"])
    k = cam["intrinsics"]
    near, far = created["clipping_range"]
    t_cw = np.asarray(cam["extrinsics_cw"], float)  # world -> OpenCV camera
    view = np.diag([1.0, -1.0, -1.0, 1.0]) @ t_cw  # OpenCV -> OpenGL camera axes
    proj = np.zeros((4, 4))
    proj[0, 0], proj[1, 1] = 2 * k[0, 0] / width, 2 * k[1, 1] / height
    proj[2, 2], proj[2, 3], proj[3, 2] = -(far + near) / (far - near), -2 * far * near / (far - near), -1.0
    aperture_h = created["horizontal_aperture"]
    return {"cameraAperture": [aperture_h, aperture_h * height / width], "cameraApertureOffset": [0.0, 0.0],
            "cameraFocalLength": created["focal_length"], "cameraModel": "pinhole", "cameraNearFar": [near, far],
            "cameraProjection": proj.T.ravel().tolist(), "cameraViewTransform": view.T.ravel().tolist(),
            "metersPerSceneUnit": 1.0, "renderProductResolution": [width, height]}


def get(name: str, init_params: dict | None = None, render_products=None):
    """A writer by name (``BasicWriter``), initialized and attached when those are given."""
    if name != "BasicWriter":
        raise unsupported(f"writer {name!r}", "ambulo provides BasicWriter (COCO and KITTI: ambulo generate)")
    writer = BasicWriter()
    if init_params is not None:
        writer.initialize(**init_params)
    if render_products is not None:
        writer.attach(render_products)
    return writer


WriterRegistry = Namespace("WriterRegistry", {"get": get}, {
    "register": "custom Writer classes are not supported; use BasicWriter",
})
writers = Namespace("writers", {"get": get}, {"register": "custom Writer classes are not supported; use BasicWriter"})
