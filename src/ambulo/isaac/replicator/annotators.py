"""``rep.AnnotatorRegistry`` and ``rep.annotators``: one ground-truth output per rendered frame.

As in Replicator, ``rep.AnnotatorRegistry.get_annotator(name)`` (or ``rep.annotators.get(name)``)
returns an ``Annotator``; ``attach(render_product)`` subscribes it to the frames the orchestrator
renders for that product, and ``get_data()`` returns the latest frame's output (None before the
first). Outputs follow Replicator's layouts (``ground_truth.py`` for the 3D ones):

- ``rgb`` / ``LdrColor``: (H, W, 4) uint8 RGBA.
- ``distance_to_image_plane``, ``distance_to_camera``: (H, W) float32 m, inf where nothing is hit.
- ``semantic_segmentation``, ``instance_segmentation``: ``{"data": (H, W) uint32, "info": ...}``
  (``ambulo.sim.camera_frame``: 0 BACKGROUND, 1 UNLABELLED, labels from 2).
- ``bounding_box_3d``: ``{"data": (M,) rows, "info": {"bboxIds", "idToLabels", "primPaths"}}``.
- ``normals``: (H, W, 4) float32 world-frame unit normals, w unused.
- ``motion_vectors`` / ``MotionVectors``: (H, W, 4) float32 px since the previous frame.
- ``camera_params`` / ``CameraParams``: BasicWriter's ``camera_params`` dict.

Other names fail in one line. An annotator attached after frames were rendered rebuilds the scene
on the next frame so the renders include what it needs; motion then starts from rest again.
"""

from __future__ import annotations

from ambulo.sim import camera_frame as frame_fmt

from .basic_writer import camera_params
from .errors import Namespace, unsupported
from .graph import current_graph
from .ground_truth import normals_rgba, prim_boxes, replicator_bounding_box_3d

_CANONICAL = {"LdrColor": "rgb", "MotionVectors": "motion_vectors", "CameraParams": "camera_params"}
NEEDS: dict[str, tuple[str, ...]] = {
    "rgb": ("rgb",),
    "distance_to_image_plane": ("depth",),
    "distance_to_camera": ("distance_to_camera",),
    "semantic_segmentation": ("semantic_segmentation",),
    "instance_segmentation": ("instance_segmentation",),
    "bounding_box_3d": ("poses_w", "bounding_box_2d_loose", "visible_fraction"),
    "normals": ("normals",),
    "motion_vectors": ("depth", "poses_w"),
    "camera_params": (),
}
"""Annotator -> the ambulo ``Camera`` annotators its output is computed from."""


class Annotator:
    """One Replicator annotator: ``attach``, then ``get_data()`` after each rendered frame."""

    def __init__(self, name: str, init_params: dict | None = None):
        self.name = _CANONICAL.get(name, name)
        self.init_params = dict(init_params or {})
        if self.init_params.get("colorize"):
            raise unsupported(f"annotator {name!r} with colorize=True",
                              "ambulo gives the id images; colour them with BasicWriter(colorize_...=True)")
        self.render_products: list = []
        self._data = None
        self._previous = None
        """(body poses, camera) of the previous frame: what motion vectors compare against."""

    @property
    def needs(self) -> tuple[str, ...]:
        return NEEDS[self.name]

    def get_name(self) -> str:
        return self.name

    def attach(self, render_products, **_kwargs) -> None:
        """Give this annotator the frames of ``render_products`` (one product, or a list of one)."""
        products = list(render_products) if isinstance(render_products, (list, tuple)) else [render_products]
        if len(products) != 1:
            raise unsupported("annotators on several render products", "attach one render product per annotator")
        graph = current_graph()
        self.render_products = products
        if self not in graph.annotators:
            graph.annotators.append(self)
        session = graph.session
        if session is not None and not set(self.needs) <= set(session.camera_annotators):
            session.close()  # the next frame rebuilds the scene with renders that include these
            graph.session = None

    def detach(self, render_products=None) -> None:
        graph = current_graph()
        self.render_products = []
        if self in graph.annotators:
            graph.annotators.remove(self)

    def get_data(self, device: str | None = None, do_array_copy: bool = True):
        """The latest frame's output (None before the first frame); NumPy on the CPU."""
        if device not in (None, "cpu"):
            raise unsupported(f"get_data(device={device!r})", "outputs are NumPy on the CPU; drop device")
        return self._data

    def update(self, capture: dict, table, model, created_camera: dict) -> None:
        """Compute this annotator's output of one frame (called by the orchestrator's session)."""
        name = self.name
        if name == "rgb":
            self._data = frame_fmt.rgba(capture["rgb"])
        elif name == "bounding_box_3d":
            in_view = capture["bounding_box_2d_loose"]["instance_id"]
            occluded = 1.0 - capture["visible_fraction"]
            self._data = replicator_bounding_box_3d(in_view, table, prim_boxes(table, model, capture["poses_w"]),
                                                    occluded)
        elif name == "normals":
            self._data = normals_rgba(capture["normals"])
        elif name == "motion_vectors":
            poses = capture["poses_w"]
            bodies = (poses["body_pos"], poses["body_rot"])
            self._data = frame_fmt.motion_vectors(capture, model.geom_bodyid, bodies, self._previous)
            self._previous = (bodies, capture["camera"])
        elif name == "camera_params":
            self._data = camera_params(capture["camera"], created_camera)
        else:
            self._data = frame_fmt.annotate(name, capture, table, self.init_params)

    def reset(self) -> None:
        """A new scene: no previous frame to move from."""
        self._previous = None

    def __repr__(self) -> str:
        return f"<omni.replicator.core Annotator {self.name!r} (ambulo)>"


def get_annotator(name: str, init_params: dict | None = None, render_product_idxs=None, device: str | None = None,
                  do_array_copy: bool = True) -> Annotator:
    """The annotator ``name`` (see the module doc), not yet attached."""
    if _CANONICAL.get(name, name) not in NEEDS:
        raise unsupported(f"annotator {name!r}", f"ambulo provides {', '.join(sorted(NEEDS))}")
    if device not in (None, "cpu"):
        raise unsupported(f"annotator device={device!r}", "outputs are NumPy on the CPU; drop device")
    return Annotator(name, init_params)


def get_registered_annotators() -> list[str]:
    return sorted(NEEDS)


_HINTS = {"register": "custom annotators are not supported; use the built-in ones",
          "register_annotator_from_node": "custom annotators are not supported; use the built-in ones",
          "register_annotator_from_aov": "custom annotators are not supported; use the built-in ones"}
AnnotatorRegistry = Namespace("AnnotatorRegistry", {
    "get_annotator": get_annotator, "get_registered_annotators": get_registered_annotators}, _HINTS)
annotators = Namespace("annotators", {"get": get_annotator, "get_registered_annotators": get_registered_annotators},
                       _HINTS)
