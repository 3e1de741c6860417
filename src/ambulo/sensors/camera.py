"""Pinhole camera sensor: rgb, depth, segmentation, normals, 2D/3D boxes, batched over worlds.

The camera sits on a mount (a body or site) at an offset that can differ per
world (pose jitter, ``set_camera_view``). Each world is rendered with one
reused ``OffscreenRenderer``; ground truth comes from ``annotators``.

``renderer`` picks what draws the colour image: ``"raster"`` (MuJoCo's rasterizer),
``"pbr"`` (Filament: physically based materials, image-based lighting, shadows;
``ambulo.render.pbr``) or ``"path"`` (path tracing, ``ambulo.render.path``). Labels
(depth, ids, boxes, normals) always come from the rasterizer's id pass, from the
same camera, so they are identical pixel for pixel whichever tier draws the colours.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Literal

import mujoco
import numpy as np
import torch
from mujoco import batch as mujoco_batch

from ambulo.render import OffscreenRenderer, RenderSettings, fast_render_settings
from ambulo.utils.checks import (
    InvalidValueError,
    check_int,
    check_positive,
    check_quat,
    check_range,
    check_vector,
)
from ambulo.utils.rotations import mat_to_quat, quat_to_mat
from ambulo.utils.validate import Checked

from . import annotators as ann
from .base import MountPose, Sensor, spec_body
from .frames import GL_IN, check_convention, look_at_gl
from .geom_shapes import surface_normals_w

ANNOTATORS = (
    "rgb", "depth", "distance_to_camera", "semantic_segmentation", "instance_segmentation",
    "normals", "bounding_box_2d_tight", "bounding_box_2d_loose", "bounding_box_3d",
    "visible_fraction", "poses_w",
)
# Isaac Replicator names for the same outputs
ALIASES = {"distance_to_image_plane": "depth", "rgba": "rgb", "occlusion": "visible_fraction"}
_NEEDS_IDS = {"semantic_segmentation", "instance_segmentation", "bounding_box_2d_tight",
              "visible_fraction"}
_NEEDS_DEPTH = {"depth", "distance_to_camera", "normals"}
RENDERERS = ("raster", "pbr", "path")
"""What can draw a camera's colour image (see the module doc)."""


@dataclass(kw_only=True)
class PinholeCfg(Checked):
    """Where a pinhole camera sits and what it sees: shared by ``CameraCfg`` (the CPU renderer)
    and ``TiledCameraCfg`` (MuJoCo Warp), so both give the same intrinsics for the same fields."""

    prim_path: str
    """The camera's prim path; its mount is the longest prefix naming a body or site."""
    width: int = 320
    """Image width (px)."""
    height: int = 240
    """Image height (px)."""
    fovy_deg: float = 60.0
    """Vertical field of view (deg); ignored when ``focal_length_px`` is set."""
    focal_length_px: float | None = None
    """Focal length (px, square pixels); sets the field of view from ``height``."""
    offset_pos: tuple[float, float, float] = (0.0, 0.0, 0.0)
    """Position (m) in the mount frame."""
    offset_quat: tuple[float, float, float, float] = (1.0, 0.0, 0.0, 0.0)
    """Orientation (w, x, y, z) in the mount frame, in ``offset_convention`` axes."""
    offset_convention: str = "world"
    """'world' (x forward, z up), 'opengl' (MuJoCo: looks along -z) or 'opencv'/'ros'."""
    clipping_range_m: tuple[float, float] = (0.05, 100.0)
    """Near and far clip distances (m); depth resolution is best with a far-away near plane."""
    renderer: Literal["raster", "pbr", "path"] = "raster"
    """What draws the colour image: 'raster' (MuJoCo's rasterizer), 'pbr' (Filament, physically
    based) or 'path' (path traced); labels come from the raster id pass whichever it is."""

    def __post_init__(self):
        """Refuse sizes, angles and ranges no camera can have (one line: the field, why, the fix)."""
        for name in ("width", "height"):
            check_int(name, getattr(self, name), f"pass whole pixels >= 1, e.g. {name}=320", minimum=1)
        if self.focal_length_px is not None:
            check_positive("focal_length_px", self.focal_length_px, "pass pixels > 0, or None to use fovy_deg")
        else:
            fovy = check_positive("fovy_deg", self.fovy_deg, "pass degrees in (0, 180), e.g. 60")
            if fovy >= 180:
                raise InvalidValueError("fovy_deg", fovy, "a pinhole camera sees less than 180 deg",
                                        "pass degrees in (0, 180), e.g. 60")
        check_range("clipping_range_m", self.clipping_range_m,
                    "pass (near, far) m with 0 < near < far, e.g. (0.05, 100.0)")
        if self.clipping_range_m[0] <= 0:
            raise InvalidValueError("clipping_range_m", self.clipping_range_m, "the near plane must be > 0",
                                    "pass (near, far) m with 0 < near < far, e.g. (0.05, 100.0)")
        check_vector("offset_pos", self.offset_pos, 3, "pass (x, y, z) m in the mount frame")
        check_quat("offset_quat", self.offset_quat)
        super().__post_init__()

    def image_fovy_deg(self) -> float:
        """The image's vertical field of view (deg): from ``focal_length_px`` when set."""
        if self.focal_length_px:
            return math.degrees(2 * math.atan(self.height / 2 / self.focal_length_px))
        return float(self.fovy_deg)

    def intrinsics_matrix(self) -> np.ndarray:
        """(3, 3) float64 K (OpenCV: pixel centres at integer coordinates, square pixels)."""
        f = self.height / 2 / math.tan(math.radians(self.image_fovy_deg()) / 2)
        return np.array([[f, 0, self.width / 2 - 0.5], [0, f, self.height / 2 - 0.5], [0, 0, 1]])


@dataclass(kw_only=True)
class CameraCfg(PinholeCfg):
    """A pinhole camera on a body or site."""

    frequency_hz: float | None = None
    """Update rate (Hz) in simulated time; None renders on every request."""
    annotators: tuple[str, ...] = ("rgb", "depth")
    """Outputs of ``get_current_frame``; see ``ANNOTATORS``."""
    render: RenderSettings = field(default_factory=fast_render_settings)

    def __post_init__(self):
        if self.frequency_hz is not None:
            check_positive("frequency_hz", self.frequency_hz, "pass Hz > 0, or None to render on every request")
        super().__post_init__()


def _resolution(what: str, value) -> tuple[int, int]:
    """A ``(width, height)`` pair as given (each checked by ``CameraCfg``); refuses another length."""
    if isinstance(value, (str, bytes)) or not hasattr(value, "__len__") or len(value) != 2:
        raise InvalidValueError(what, value, "expected (width, height)", "pass whole pixels, e.g. resolution=(320, 240)")
    return value[0], value[1]


def _extrinsics(pos: np.ndarray, rot_gl: np.ndarray) -> np.ndarray:
    """(N, 4, 4) world -> OpenCV camera transforms of cameras at (N, 3) with OpenGL axes (N, 3, 3)."""
    rot_cv = rot_gl @ GL_IN["opencv"]
    t = np.tile(np.eye(4), (len(pos), 1, 1))
    t[:, :3, :3] = np.swapaxes(rot_cv, 1, 2)
    t[:, :3, 3] = -np.einsum("nji,nj->ni", rot_cv, pos)
    return t


def _normalize_annotators(names) -> tuple[str, ...]:
    out = []
    for name in names:
        name = ALIASES.get(name, name)
        if name not in ANNOTATORS:
            raise ValueError(f"unknown camera annotator {name!r}; choose from {ANNOTATORS}")
        out.append(name)
    return tuple(dict.fromkeys(out))


class Camera(Sensor):
    """Camera(CameraCfg(...)) or, as in the Isaac tutorials, Camera(prim_path=..., resolution=(w, h))."""

    def __init__(self, cfg: CameraCfg | None = None, **kwargs):
        if cfg is None:
            if "resolution" in kwargs:
                resolution = kwargs.pop("resolution")
                kwargs["width"], kwargs["height"] = _resolution("resolution", resolution)
            if "frequency" in kwargs:
                kwargs["frequency_hz"] = kwargs.pop("frequency")
            cfg = CameraCfg(**kwargs)
        elif kwargs:
            raise TypeError("pass either a CameraCfg or keyword arguments, not both")
        check_convention(cfg.offset_convention)
        self.cfg = cfg
        self.annotators = _normalize_annotators(cfg.annotators)
        period = 0.0 if not cfg.frequency_hz else 1.0 / cfg.frequency_hz
        super().__init__(cfg.prim_path, period)
        self.name = cfg.prim_path
        self._renderer: OffscreenRenderer | None = None
        self._color_renderer = None
        """The pbr or path tier's renderer (None for raster: the rasterizer draws the colours)."""
        self._pending = None
        self._frames: list[dict | None] = []

    # -- lifecycle ------------------------------------------------------------
    def build(self, spec: mujoco.MjSpec) -> None:
        super().build(spec)
        if spec.camera(self.name) is not None:
            raise ValueError(f"a camera named {self.name!r} already exists; give each camera its own prim path")
        pos, rot = self._offset_in_body(np.asarray(spec.site(self.mount.site).pos, float) if self.mount.site else None,
                                        np.asarray(spec.site(self.mount.site).quat, float) if self.mount.site else None)
        spec_body(spec, self.mount).add_camera(
            name=self.name, pos=pos, quat=mat_to_quat(rot), fovy=self.fovy_deg)

    def initialize(self, engine) -> None:
        super().initialize(engine)
        model = engine.model
        self.cam_id = model.camera(self.name).id
        self._mount_pose = MountPose(engine, self.mount)
        n = engine.num_worlds
        site = self.mount.site
        pos, rot = self._offset_in_mount()
        self._offset_pos = np.tile(pos, (n, 1))
        """(N, 3) m: camera position in the mount frame, per world."""
        self._offset_rot_gl = np.tile(rot, (n, 1, 1))
        """(N, 3, 3): camera OpenGL axes in the mount frame, per world."""
        self._default_offset = (pos, rot)
        self._site_local = None
        if site is not None:
            sid = model.site(site).id
            self._site_local = (model.site_pos[sid].copy(), quat_to_mat(model.site_quat[sid]))
        self.table = ann.instance_table(model)
        self._geom_semantic = self.table.semantic_ids[self.table.geom_instance]
        """(ngeom+1,) int32: semantic id of geom g at index g+1 (the id pass maps pixels through it)."""
        self._model_buf = engine.get_model(0)
        self._data_buf = engine.get_data(0)
        self._frames = [None] * n
        self._sync_model_camera()

    @property
    def renderer(self) -> OffscreenRenderer:
        if self._renderer is None:
            self._require_initialized()
            self._renderer = OffscreenRenderer(self.engine.model, self.cfg.width, self.cfg.height,
                                               self.cfg.render)
        return self._renderer

    @property
    def color_renderer(self):
        """What draws the colour image: the rasterizer, a ``PbrRenderer`` or a ``PathTracer``."""
        if self.cfg.renderer == "raster":
            return self.renderer
        if self._color_renderer is None:
            self._require_initialized()
            self._color_renderer = make_color_renderer(self.cfg.renderer, self._model_buf,
                                                       self.cfg.width, self.cfg.height)
        return self._color_renderer

    @property
    def renderer_name(self) -> str:
        """The colour tier and its device, recorded with datasets: e.g. 'raster: llvmpipe (...)'."""
        name = f"raster: {self.renderer.gl_renderer}"
        if self.cfg.renderer != "raster":
            name = f"{self.cfg.renderer}: {getattr(self.color_renderer, 'gl_renderer', '')}; labels {name}"
        return name

    def close(self) -> None:
        if self._renderer is not None:
            self._renderer.close()
            self._renderer = None
        if self._color_renderer is not None:
            close = getattr(self._color_renderer, "close", None)
            if close is not None:
                close()
            self._color_renderer = None

    # -- intrinsics / extrinsics ------------------------------------------------
    @property
    def resolution(self) -> tuple[int, int]:
        return self.cfg.width, self.cfg.height

    @property
    def fovy_deg(self) -> float:
        return self.cfg.image_fovy_deg()

    def get_intrinsics_matrix(self) -> np.ndarray:
        """(3, 3) float64 K (OpenCV: pixel centres at integer coordinates, square pixels)."""
        return self.cfg.intrinsics_matrix()

    def get_world_pose(self, convention: str = "world") -> tuple[torch.Tensor, torch.Tensor]:
        """Camera position (N, 3) m and orientation (N, 4) wxyz in the world, in ``convention`` axes."""
        pos, rot_gl = self._pose_gl()
        rot = rot_gl @ check_convention(convention).T
        return torch.from_numpy(pos), torch.from_numpy(mat_to_quat(rot))

    def get_extrinsics_matrix(self) -> np.ndarray:
        """(N, 4, 4) float64 world -> OpenCV camera transform T_cw (p_c = R p_w + t)."""
        return _extrinsics(*self._pose_gl())

    # -- posing -----------------------------------------------------------------
    def set_local_pose(self, pos=None, quat=None, convention: str = "world", world_ids=None) -> None:
        """Set the offset from the mount (m, wxyz) for ``world_ids`` (default all)."""
        ids = self._ids(world_ids)
        if pos is not None:
            self._offset_pos[ids] = np.asarray(pos, float)
        if quat is not None:
            self._offset_rot_gl[ids] = quat_to_mat(np.asarray(quat, float)) @ check_convention(convention)
        self._sync_model_camera(ids)

    def set_world_pose(self, pos, rot_w_gl, world_ids=None) -> None:
        """Place the camera at world position (.., 3) with OpenGL axes rot_w_gl (.., 3, 3)."""
        ids = self._ids(world_ids)
        mount_pos, mount_rot = self._mount_frame()
        r_t = np.swapaxes(mount_rot[ids], -1, -2)
        pos = np.broadcast_to(np.asarray(pos, float), (len(ids), 3))
        rot = np.broadcast_to(np.asarray(rot_w_gl, float), (len(ids), 3, 3))
        self._offset_pos[ids] = np.einsum("nij,nj->ni", r_t, pos - mount_pos[ids])
        self._offset_rot_gl[ids] = r_t @ rot
        self._sync_model_camera(ids)

    def set_camera_view(self, eye, target, up=(0.0, 0.0, 1.0), world_ids=None) -> None:
        """Put the camera at ``eye`` (m, world) looking at ``target``, as in Isaac's set_camera_view."""
        self.set_world_pose(eye, look_at_gl(eye, target, up), world_ids)

    def reset_pose(self, world_ids=None) -> None:
        """Back to the configured offset (what pose jitter perturbs)."""
        ids = self._ids(world_ids)
        self._offset_pos[ids], self._offset_rot_gl[ids] = self._default_offset
        self._sync_model_camera(ids)

    # -- capture ----------------------------------------------------------------
    def capture(self, world: int = 0, annotators=None) -> dict:
        """Render world ``world`` now and return its annotator outputs (NumPy, see module doc)."""
        self.begin_capture(world, annotators)
        return self.end_capture()

    def begin_capture(self, world: int = 0, annotators=None, geom_ids: bool = True) -> None:
        """Render the colour image and queue the id/depth pass of world ``world``.

        The rasterizer works on the queued pass while the caller does other
        things (e.g. randomizing the next frame): the engine may change before
        ``end_capture``, which uses only what was recorded here. ``geom_ids`` False: the capture
        holds no ``geom_ids`` (H, W) map unless an annotator needs it (a lookup of every pixel,
        ~2 % of a dataset frame that no dataset file reads).
        """
        self._require_initialized()
        names = self.annotators if annotators is None else _normalize_annotators(annotators)
        r = self.renderer
        model = self.engine.get_model(world, self._model_buf)
        # the state with what a picture shows computed; the camera pose comes from that same data,
        # so callers need no kinematics pass of their own before capturing
        data = self._render_state(world, model)
        mount_pos, mount_rot = self._mount_pose.of_data(data)
        pos = mount_pos + mount_rot @ self._offset_pos[world]
        rot_gl = mount_rot @ self._offset_rot_gl[world]
        r.update(model, data, self.cam_id, pos, rot_gl, self.cfg.clipping_range_m)
        k_matrix = self.get_intrinsics_matrix()
        extr = _extrinsics(pos[None], rot_gl[None])[0]
        out: dict = {"camera": {
            "intrinsics": k_matrix, "extrinsics_cw": extr, "pos_w": pos,
            "quat_w_opengl": mat_to_quat(rot_gl), "width": self.cfg.width, "height": self.cfg.height}}
        if "rgb" in names:
            if self.cfg.renderer == "raster":
                out["rgb"] = r.render_rgb().copy()
            elif self.cfg.renderer == "pbr":  # the raster pass's own camera: the same intrinsics and pose
                out["rgb"] = np.array(self.color_renderer.render(data, r.scene.camera[0]), np.uint8, copy=True)
            else:  # the path tracer reads the model camera's intrinsics and takes this pose
                out["rgb"] = self.color_renderer.render(data, self.cam_id, pose=(pos, rot_gl))
        if "poses_w" in names:  # the state this frame shows: 3D boxes in a prim's frame, motion vectors
            out["poses_w"] = {"body_pos": data.xpos.copy(), "body_rot": data.xmat.reshape(-1, 3, 3).copy(),
                              "geom_pos": data.geom_xpos.copy(), "geom_rot": data.geom_xmat.reshape(-1, 3, 3).copy(),
                              "geom_size": model.geom_size.copy()}
        need = set(names)
        wants_ids = bool(need & (_NEEDS_IDS | _NEEDS_DEPTH | {"bounding_box_2d_loose", "bounding_box_3d"}))
        want_depth = bool(need & _NEEDS_DEPTH)
        if wants_ids:
            r.queue_ids()
        self._pending = (out, names, wants_ids, want_depth, data, geom_ids or "normals" in need)

    def _render_state(self, world: int, model: mujoco.MjModel) -> mujoco.MjData:
        """World ``world``'s state with every field a render and the annotators read computed.

        On the CPU engine, only the position stages a picture depends on: poses of bodies, geoms,
        sites, cameras and lights (``mj_kinematics``, ``mj_comPos`` for tracking cameras and
        lights, ``mj_camlight``), tendon paths and flex vertices; the same values as
        ``mj_forward``, which also detects contacts and solves dynamics for ~40x the cost.
        Elsewhere the engine's ``get_data`` (``mj_forward``).
        """
        batch = getattr(self.engine, "batch", None)
        if not isinstance(batch, mujoco_batch.Batch):
            return self.engine.get_data(world, self._data_buf)
        data = batch.get_data(int(world), self._data_buf)
        mujoco.mj_kinematics(model, data)
        mujoco.mj_comPos(model, data)
        mujoco.mj_camlight(model, data)
        if model.nflex:
            mujoco.mj_flex(model, data)
        if model.ntendon:
            mujoco.mj_tendon(model, data)
        return data

    def end_capture(self) -> dict:
        """Finish the capture started by ``begin_capture`` and compute the annotations."""
        out, names, wants_ids, want_depth, data, keep_geom_ids = self._pending
        self._pending = None
        if wants_ids:
            # instance and semantic ids straight from the id pass (the same values as instance_map
            # and a lookup of the instances, at a third of the cost); the semantic map only when
            # asked for (a lookup of every pixel, ~1 % of a frame the default annotators never read)
            tables = (self.table.geom_instance,)
            if "semantic_segmentation" in names:
                tables += (self._geom_semantic,)
            geom_ids, depth, (instances, *semantic) = self.renderer.read_ids(want_depth, per_geom=tables,
                                                                              geom_ids=keep_geom_ids)
            semantic = semantic[0] if semantic else None
            if keep_geom_ids:
                out["geom_ids"] = geom_ids
            cam = out["camera"]
            self._annotate(out, names, instances, depth, cam["intrinsics"], cam["extrinsics_cw"], data, semantic)
        return out

    def _annotate(self, out, names, instances, depth, k_matrix, extr, data, semantic) -> None:
        table = self.table
        if "depth" in names:
            out["depth"] = depth
        if "distance_to_camera" in names:
            out["distance_to_camera"] = ann.distance_from_depth(depth, k_matrix).astype(np.float32)
        if "normals" in names:  # world frame, exact from each geom's shape (geom_shapes)
            out["normals"] = surface_normals_w(out["geom_ids"], depth, k_matrix, extr, self._model_buf,
                                               data.geom_xpos, data.geom_xmat.reshape(-1, 3, 3))
        if "instance_segmentation" in names:
            out["instance_segmentation"] = instances
        if "semantic_segmentation" in names:
            out["semantic_segmentation"] = semantic
        pixels = None
        if "bounding_box_2d_tight" in names or "visible_fraction" in names:
            boxes, pixels = ann.tight_boxes(instances, table.num_instances)
            if "bounding_box_2d_tight" in names:
                out["bounding_box_2d_tight"] = tight_box_output(table, boxes, pixels)
        if not {"bounding_box_2d_loose", "bounding_box_3d", "visible_fraction"} & set(names):
            return
        geom_pos = data.geom_xpos
        geom_rot = data.geom_xmat.reshape(-1, 3, 3)
        # the instances' geom box corners in the world, shared by the loose and the 3D boxes
        corners_w = ann.geom_corners_w(table.instance_geoms[0], self.engine.model, geom_pos, geom_rot)
        if "bounding_box_2d_loose" in names or "visible_fraction" in names:
            # the in-view instances' ids (ascending) and boxes as arrays: no per-instance list
            ids, boxes = ann.loose_box_array(table, self.engine.model, geom_pos, geom_rot, extr, k_matrix,
                                             self.cfg.width, self.cfg.height, self.renderer.near_far()[0], corners_w)
            if "bounding_box_2d_loose" in names:
                out["bounding_box_2d_loose"] = {"instance_id": ids, "semantic_id": table.semantic_ids[ids],
                                                "box": boxes}
            if "visible_fraction" in names:
                in_view = np.zeros(table.num_instances, bool)
                in_view[ids - 1] = True
                out["visible_fraction"] = self._visible_fraction(pixels, in_view)
        if "bounding_box_3d" in names:
            center_w, rot_w, half = ann.instance_boxes_3d(
                table, self.engine.model, data.xpos, data.xmat.reshape(-1, 3, 3), geom_pos, geom_rot, corners_w)
            out["bounding_box_3d"] = {
                "instance_id": np.arange(1, table.num_instances + 1), "semantic_id": table.semantic_ids[1:],
                "center_w": center_w, "rot_w": rot_w, "half_extent": half,
                "center_c": center_w @ extr[:3, :3].T + extr[:3, 3], "rot_c": extr[:3, :3] @ rot_w}

    def _visible_fraction(self, pixels: np.ndarray, in_view: np.ndarray) -> np.ndarray:
        """(K,) visible / unoccluded pixels in the image; 0 for objects out of view."""
        fraction = np.zeros(self.table.num_instances)
        for i in np.flatnonzero(in_view):
            if pixels[i] == 0:
                continue
            alone = self.renderer.render_ids_isolated(self.table.geoms_of(i + 1))
            total = np.count_nonzero(self.table.geom_instance[alone + 1] == i + 1)
            fraction[i] = min(1.0, pixels[i] / max(total, 1))
        return fraction

    def get_current_frame(self, world_ids=None) -> dict:
        """Latest outputs of ``world_ids`` (default all), re-rendered where an update is due.

        Images are stacked into torch tensors (N, H, W, ...); per-object outputs
        (boxes, visible fraction) are lists with one entry per world.
        """
        self._require_initialized()
        ids = self._ids(world_ids)
        due = self._due().cpu().numpy()
        rendered = np.zeros(self.num_worlds, bool)
        for w in ids:
            if due[w] or self._frames[w] is None:
                self._frames[w] = self.capture(int(w))
                rendered[w] = True
        if rendered.any():
            self._mark_updated(torch.from_numpy(rendered).to(self._last_update_s.device))
        frames = [self._frames[w] for w in ids]
        out = {}
        for key in frames[0]:
            values = [f[key] for f in frames]
            if isinstance(values[0], np.ndarray):
                out[key] = torch.from_numpy(np.stack(values))
            else:
                out[key] = values
        return out

    # -- helpers ----------------------------------------------------------------
    def _ids(self, world_ids) -> np.ndarray:
        self._require_initialized()
        if world_ids is None:
            return np.arange(self.engine.num_worlds)
        if isinstance(world_ids, torch.Tensor):
            world_ids = world_ids.cpu().numpy()
        return np.atleast_1d(np.asarray(world_ids, np.int64))

    def _offset_in_mount(self) -> tuple[np.ndarray, np.ndarray]:
        rot = quat_to_mat(np.asarray(self.cfg.offset_quat, float)) @ check_convention(self.cfg.offset_convention)
        return np.asarray(self.cfg.offset_pos, float), rot

    def _offset_in_body(self, site_pos, site_quat) -> tuple[np.ndarray, np.ndarray]:
        pos, rot = self._offset_in_mount()
        if site_pos is None:
            return pos, rot
        site_rot = quat_to_mat(site_quat)
        return site_pos + site_rot @ pos, site_rot @ rot

    def _mount_frame(self) -> tuple[np.ndarray, np.ndarray]:
        # rendering runs on the host (MuJoCo's renderer), so the pose math does too
        return (self._mount_pose.pos_w().detach().cpu().numpy(),
                self._mount_pose.rot_w().detach().cpu().numpy())

    def _pose_gl(self) -> tuple[np.ndarray, np.ndarray]:
        """World position (N, 3) and OpenGL axes (N, 3, 3) of the camera."""
        mount_pos, mount_rot = self._mount_frame()
        pos = mount_pos + np.einsum("nij,nj->ni", mount_rot, self._offset_pos)
        return pos, mount_rot @ self._offset_rot_gl

    def _sync_model_camera(self, ids=None) -> None:
        # keep the model's camera (what viewers show) on the same pose as the renders
        cam_pos, cam_quat = self.engine.model_field("cam_pos"), self.engine.model_field("cam_quat")
        ids = np.arange(self.engine.num_worlds) if ids is None else ids
        pos, rot = self._offset_pos[ids], self._offset_rot_gl[ids]
        if self._site_local is not None:
            site_pos, site_rot = self._site_local
            pos, rot = site_pos + pos @ site_rot.T, site_rot @ rot
        quat = mat_to_quat(rot[0])[None] if len(rot) == 1 else mat_to_quat(rot)  # one: MuJoCo's C routine
        if cam_pos.device.type == "cpu":  # NumPy views of the host tensors: ~10x cheaper per call
            cam_pos.numpy()[ids, self.cam_id] = pos
            cam_quat.numpy()[ids, self.cam_id] = quat
            return
        ids_t = torch.as_tensor(ids, device=cam_pos.device)
        cam_pos[ids_t, self.cam_id] = torch.from_numpy(np.ascontiguousarray(pos)).to(cam_pos)
        cam_quat[ids_t, self.cam_id] = torch.from_numpy(quat).to(cam_quat)


def tight_box_output(table: ann.InstanceTable, boxes: np.ndarray, pixels: np.ndarray) -> dict:
    """The ``bounding_box_2d_tight`` output of ``tight_boxes``' (K, 4) ``boxes`` and (K,) ``pixels``:
    the visible instances' ids, semantic ids, boxes and pixel counts."""
    visible = np.flatnonzero(pixels > 0)
    return {"instance_id": visible + 1, "semantic_id": table.semantic_ids[visible + 1],
            "box": boxes[visible], "pixels": pixels[visible]}


def make_color_renderer(renderer: str, model: mujoco.MjModel, width: int, height: int):
    """The pbr or path tier's renderer of ``model`` at ``width`` x ``height``: a ``PbrRenderer``
    (``render(data, gl_camera)``) or a ``PathTracer`` (``render(data, cam_id, pose=...)``), each
    returning (H, W, 3) uint8."""
    if renderer == "pbr":
        from ambulo.render.pbr import PbrRenderer

        return PbrRenderer(model, width, height)
    if renderer == "path":
        try:
            from ambulo.render.path import PathTracer, PathTracerCfg
        except ImportError as err:
            raise RuntimeError(f"the path tier is not available here ({err}); use renderer='pbr' or 'raster'") from err
        return PathTracer(model, PathTracerCfg(width=width, height=height))
    raise ValueError(f"unknown renderer {renderer!r}; choose from {RENDERERS}")
