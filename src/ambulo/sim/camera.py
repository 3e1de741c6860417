"""Isaac Sim's ``Camera`` (``isaacsim.sensors.camera`` / ``omni.isaac.sensor``) on ambulo.

A thin face over ``ambulo.sensors.Camera``, which renders (MuJoCo's rasterizer) and computes
ground truth; this class keeps Isaac's names, units and outputs: NumPy arrays of one world,
``(H, W, 4)`` uint8 RGBA, depth to the image plane in m, Replicator's annotator dicts, poses
in the ``"world"``/``"ros"``/``"usd"`` camera axes (``camera_axes``), focal length and
apertures in Isaac's stage units (tenths of the USD attribute), and an intrinsics matrix with
the principal point at ``(W/2, H/2)`` (pixel centres at half-integers, as Isaac).

``renderer`` (an ambulo argument) picks the colour tier, ``"raster"``, ``"pbr"`` or ``"path"``;
left out, the process default, which ``SimulationApp({"renderer": ...})`` sets
(``set_default_renderer``): Isaac's ``RayTracedLighting`` is ``"pbr"`` and ``PathTracing`` is
``"path"``. Labels are the same in every tier.

The frame is refreshed lazily (rendering costs milliseconds): the first read in each period of
``1/frequency`` s of simulated time renders, later reads in that period return that render
(every read at a new time renders when no frequency is given), as Isaac's frame holds its
last render.
"""

from __future__ import annotations

import copy
import logging
import math

import mujoco
import numpy as np

from ambulo.sensors import Camera as _Camera
from ambulo.sensors import CameraCfg
from ambulo.sensors.camera import RENDERERS
from ambulo.utils.checks import check_quat
from ambulo.utils.rotations import mat_to_quat, quat_to_mat

from . import camera_frame as frame_fmt
from .base_sensor import BaseSensor, due, period_from
from .camera_axes import rot_from_usd, rot_to_usd

log = logging.getLogger(__name__)

# A new USD camera prim's attributes (UsdGeom.Camera defaults); Isaac reports lengths in
# tenths of the attribute (USD_CAMERA_TENTHS_TO_STAGE_UNIT), so 50 -> 5.0 and 20.955 -> 2.0955.
DEFAULT_FOCAL_LENGTH = 5.0
DEFAULT_HORIZONTAL_APERTURE = 2.0955
DEFAULT_CLIPPING_RANGE = (1.0, 1.0e6)
DEFAULT_RESOLUTION = (128, 128)

SUPPORTED_ANNOTATORS = ("distance_to_image_plane", "distance_to_camera", "semantic_segmentation",
                        "instance_segmentation", "bounding_box_2d_tight", "pointcloud", "motion_vectors")
_UNSUPPORTED: dict[str, str] = {}

_default_renderer = "raster"
"""The colour tier of cameras made without ``renderer=`` (``set_default_renderer``)."""


def set_default_renderer(renderer: str) -> None:
    """Make ``renderer`` ('raster', 'pbr' or 'path') the tier of cameras created from now on."""
    global _default_renderer
    if renderer not in RENDERERS:
        raise ValueError(f"unknown renderer {renderer!r}; choose from {RENDERERS}")
    _default_renderer = renderer


def default_renderer() -> str:
    """The tier cameras made without ``renderer=`` use (``set_default_renderer``; 'raster' at start)."""
    return _default_renderer



def _check_resolution(value) -> tuple[int, int]:
    """(width, height) as whole pixels >= 1, else a one-line error."""
    try:
        width, height = value
        ok = all(float(v) == int(v) and int(v) >= 1 for v in (width, height))
    except (TypeError, ValueError):
        ok = False
    if not ok:
        raise ValueError(f"resolution {value!r} must be (width, height) in whole pixels >= 1, e.g. (640, 480)")
    return int(width), int(height)

class Camera(BaseSensor):
    """Isaac's ``Camera(prim_path, name, frequency, dt, resolution, position, orientation, translation)``.

    The camera hangs from the body or site its prim path's parent names (``/World`` or no
    parent: the world). ``position`` is in the world frame, ``translation`` in the parent's;
    ``orientation`` (wxyz) is in ``"world"`` camera axes (+X forward, +Z up), relative to the
    world with ``position`` and to the parent otherwise.
    """

    def __init__(self, prim_path: str, name: str = "camera", frequency: float | None = None,
                 dt: float | None = None, resolution: tuple[int, int] | None = None, position=None,
                 orientation=None, translation=None, render_product_path: str | None = None,
                 annotator_device: str | None = None, renderer: str | None = None):
        if render_product_path is not None:
            raise ValueError("render_product_path is not supported: each ambulo camera renders itself; drop it")
        if annotator_device not in (None, "cpu"):
            raise ValueError(f"annotator_device={annotator_device!r} is not supported; outputs are NumPy on "
                             "the CPU, drop the argument")
        width, height = _check_resolution(resolution or DEFAULT_RESOLUTION)
        period = period_from(frequency, dt, "Camera")
        self._focal_length = DEFAULT_FOCAL_LENGTH
        self._horizontal_aperture = DEFAULT_HORIZONTAL_APERTURE
        cfg = CameraCfg(prim_path=prim_path, width=int(width), height=int(height),
                        fovy_deg=_fovy_deg(self._focal_length, self._horizontal_aperture, width, height),
                        clipping_range_m=DEFAULT_CLIPPING_RANGE, offset_convention="opengl",
                        frequency_hz=None if period is None else 1.0 / period, annotators=("rgb",),
                        renderer=default_renderer() if renderer is None else renderer)
        self._pending_world_pose = None
        if translation is not None or (orientation is not None and position is None):
            cfg.offset_pos = tuple(float(v) for v in (translation if translation is not None else (0, 0, 0)))
            if orientation is not None:
                cfg.offset_quat = tuple(_usd_quat(orientation, "world"))
        if position is not None:
            self._pending_world_pose = (np.asarray(position, float),
                                        None if orientation is None else quat_to_mat(_usd_quat(orientation, "world")))
        self._annotators: dict[str, dict] = {}
        self._rgb = True
        self._frame: dict = {"rendering_time": 0.0, "rendering_frame": 0}
        self._frame_time: float | None = None
        self._stale = True
        self._renders = 0
        self._previous_render = None
        """(body poses, camera) of the last render: what motion vectors compare against."""
        super().__init__(_Camera(cfg), name)

    @property
    def cfg(self) -> CameraCfg:
        return self.sensor.cfg

    # -- lifecycle hooks -------------------------------------------------------------
    def _before_initialize(self, engine) -> None:
        if self._pending_world_pose is None:
            return
        # Isaac authors `position` before the simulation runs: the mount's pose at qpos0
        mount_pos, mount_rot = _mount_pose_at_rest(engine.model, self.sensor.mount)
        pos, rot_usd = self._pending_world_pose
        if rot_usd is None:
            rot_usd = mount_rot @ quat_to_mat(np.asarray(self.cfg.offset_quat, float))
        self._store_offset(mount_rot.T @ (pos - mount_pos), mount_rot.T @ rot_usd)
        self._pending_world_pose = None

    def _after_initialize(self) -> None:
        self._stale = True
        self._previous_render = None

    def initialize(self, physics_sim_view=None, attach_rgb_annotator: bool = True) -> None:
        """Isaac's ``initialize()`` after ``world.reset()`` (attaches the rgb annotator unless told
        not to); ``world.reset()`` itself calls ``initialize(engine)`` when it compiles the stage."""
        if physics_sim_view is not None:
            super().initialize(physics_sim_view)
            return
        super().initialize()
        if attach_rgb_annotator:
            self.attach_annotator("rgb")

    def _on_reset(self) -> None:
        self._stale = True
        self._previous_render = None  # motion vectors start from rest after a reset

    # -- frame -----------------------------------------------------------------------
    def get_current_frame(self, clone: bool = False) -> dict:
        """``{"rendering_time": s, "rendering_frame": int, "rgba"/"rgb": (H, W, 4) uint8, <annotator>: ...}``.

        Both ``rgba`` (Isaac <= 4.2) and ``rgb`` (Isaac >= 4.5) hold the same RGBA image.
        """
        self._refresh()
        return copy.deepcopy(self._frame) if clone else self._frame

    def _refresh(self) -> None:
        if not self.initialized or self._paused:
            return
        now = self._sim_time()
        if not (self._stale or due(self._frame_time, now, self.sensor.update_period_s)):
            return
        needs = {"rgb"} if self._rgb else set()
        for key in self._annotators:
            needs.update(frame_fmt.ANNOTATOR_NEEDS[key])
        capture = self.sensor.capture(0, annotators=tuple(needs)) if needs else {}
        self._capture = capture
        self._frame_time, self._stale = now, False
        self._renders += 1
        world = self._world
        step = world.get_rendering_dt() if world is not None else self.sensor.engine.model.opt.timestep
        self._frame["rendering_time"] = now
        self._frame["rendering_frame"] = int(round(now / step))
        if self._rgb:
            self._frame["rgba"] = self._frame["rgb"] = frame_fmt.rgba(capture["rgb"])
        bodies = self._body_poses() if "motion_vectors" in self._annotators else None
        for key, params in self._annotators.items():
            if key == "motion_vectors":
                self._frame[key] = frame_fmt.motion_vectors(capture, self.sensor.engine.model.geom_bodyid, bodies,
                                                            self._previous_render)
            else:
                self._frame[key] = frame_fmt.annotate(key, capture, self.sensor.table, params)
        if bodies is not None:
            self._previous_render = (bodies, capture["camera"])

    def _body_poses(self) -> tuple[np.ndarray, np.ndarray]:
        """World 0's body positions (nbody, 3) and rotations (nbody, 3, 3) now."""
        engine = self.sensor.engine
        return (engine.field("xpos")[0].cpu().numpy().astype(float),
                engine.field("xmat")[0].reshape(-1, 3, 3).cpu().numpy().astype(float))

    # -- annotators --------------------------------------------------------------------
    @property
    def supported_annotators(self) -> list[str]:
        return ["rgb", *SUPPORTED_ANNOTATORS]

    def attach_annotator(self, annotator_name: str, **kwargs) -> None:
        """Add Replicator annotator ``annotator_name`` (``_fast`` variants alike) to the frame."""
        key = annotator_name.replace("_fast", "")
        if key in _UNSUPPORTED:
            raise NotImplementedError(_UNSUPPORTED[key])
        if key == "rgb":
            self._rgb = True
        elif key in self._annotators:
            log.warning("annotator %s is already attached to camera %s", key, self.prim_path)
            return
        elif key in SUPPORTED_ANNOTATORS:
            self._annotators[key] = dict(kwargs)
            self._frame.setdefault(key, None)
        else:
            raise ValueError(f"annotator {annotator_name!r} is not supported; choose from {self.supported_annotators}")
        self._stale = True

    def detach_annotator(self, annotator_name: str) -> None:
        key = annotator_name.replace("_fast", "")
        if key == "rgb":
            self._rgb = False
            self._frame.pop("rgb", None)
            self._frame.pop("rgba", None)
        elif key in self._annotators:
            del self._annotators[key]
            self._frame.pop(key, None)
        else:
            log.warning("annotator %s is not attached to camera %s", key, self.prim_path)

    def add_rgb_to_frame(self, init_params: dict | None = None) -> None:
        self.attach_annotator("rgb", **(init_params or {}))

    def remove_rgb_from_frame(self) -> None:
        self.detach_annotator("rgb")

    def add_distance_to_image_plane_to_frame(self, init_params: dict | None = None) -> None:
        """Frame key ``distance_to_image_plane``: (H, W) float32 m along the optical axis (inf: no hit)."""
        self.attach_annotator("distance_to_image_plane", **(init_params or {}))

    def remove_distance_to_image_plane_from_frame(self) -> None:
        self.detach_annotator("distance_to_image_plane")

    def add_distance_to_camera_to_frame(self, init_params: dict | None = None) -> None:
        """Frame key ``distance_to_camera``: (H, W) float32 m from the camera centre."""
        self.attach_annotator("distance_to_camera", **(init_params or {}))

    def remove_distance_to_camera_from_frame(self) -> None:
        self.detach_annotator("distance_to_camera")

    def add_pointcloud_to_frame(self, include_unlabelled: bool = True, init_params: dict | None = None) -> None:
        """Frame key ``pointcloud``: ``{"data": (P, 3) float32 world points, "info": {...}}``."""
        params = {"includeUnlabelled": include_unlabelled, **(init_params or {})}
        self.attach_annotator("pointcloud", **params)

    def remove_pointcloud_from_frame(self) -> None:
        self.detach_annotator("pointcloud")

    def add_semantic_segmentation_to_frame(self, init_params: dict | None = None) -> None:
        """Frame key ``semantic_segmentation``: ``{"data": (H, W) uint32, "info": {"idToLabels": ...}}``."""
        self._no_colorize(init_params)
        self.attach_annotator("semantic_segmentation", **(init_params or {}))

    def remove_semantic_segmentation_from_frame(self) -> None:
        self.detach_annotator("semantic_segmentation")

    def add_instance_segmentation_to_frame(self, init_params: dict | None = None) -> None:
        """Frame key ``instance_segmentation``: ``{"data": (H, W) uint32, "info": {"idToLabels",
        "idToSemantics"}}``."""
        self._no_colorize(init_params)
        self.attach_annotator("instance_segmentation", **(init_params or {}))

    def remove_instance_segmentation_from_frame(self) -> None:
        self.detach_annotator("instance_segmentation")

    def add_bounding_box_2d_tight_to_frame(self, init_params: dict | None = None) -> None:
        """Frame key ``bounding_box_2d_tight``: ``{"data": (M,) BBOX_2D_DTYPE, "info": {...}}``."""
        self.attach_annotator("bounding_box_2d_tight", **(init_params or {}))

    def remove_bounding_box_2d_tight_from_frame(self) -> None:
        self.detach_annotator("bounding_box_2d_tight")

    def add_motion_vectors_to_frame(self, init_params: dict | None = None) -> None:
        """Frame key ``motion_vectors``: (H, W, 4) float32 pixel motion since the previous render
        (x > 0 leftward, y > 0 upward; see ``camera_frame.motion_vectors``)."""
        self.attach_annotator("motion_vectors", **(init_params or {}))

    def remove_motion_vectors_from_frame(self) -> None:
        self.detach_annotator("motion_vectors")

    @staticmethod
    def _no_colorize(init_params) -> None:
        if init_params and init_params.get("colorize"):
            raise ValueError("colorize=True is not supported; segmentation ids come as uint32, "
                             "map them to colours yourself")

    # -- images ----------------------------------------------------------------------
    def get_rgba(self, device: str | None = None) -> np.ndarray | None:
        """(H, W, 4) uint8 RGBA of the last render; None (with a warning) without the rgb annotator."""
        self._refresh()
        return self._frame.get("rgba") if self._has("rgba", "add_rgb_to_frame") else None

    def get_rgb(self, device: str | None = None) -> np.ndarray | None:
        """(H, W, 3) uint8 RGB of the last render."""
        rgba = self.get_rgba(device)
        return None if rgba is None else rgba[:, :, :3]

    def get_depth(self, device: str | None = None) -> np.ndarray | None:
        """(H, W) float32 distance to the image plane (m), inf where nothing is hit; needs
        ``add_distance_to_image_plane_to_frame()``, else None with a warning, as in Isaac."""
        self._refresh()
        key = "distance_to_image_plane"
        return self._frame.get(key) if self._has(key, "add_distance_to_image_plane_to_frame") else None

    def get_pointcloud(self, device: str | None = None, world_frame: bool = True) -> np.ndarray:
        """(P, 3) float32 points (m) of the pixels that see geometry, world frame (or the ROS
        camera frame with ``world_frame=False``): from the pointcloud annotator when attached,
        else from depth (``add_distance_to_image_plane_to_frame``); empty without either."""
        self._refresh()
        if "pointcloud" in self._annotators and self._frame.get("pointcloud") is not None:
            points = self._frame["pointcloud"]["data"]
            if world_frame:
                return points
            extr = self._capture["camera"]["extrinsics_cw"]
            return (points @ extr[:3, :3].T + extr[:3, 3]).astype(np.float32)
        depth = self.get_depth()
        if depth is None:
            return np.zeros((0, 3), np.float32)
        cam = self._capture["camera"]
        points = frame_fmt.camera_points(depth, cam["intrinsics"])[np.isfinite(depth)]
        if world_frame:
            points = frame_fmt.to_world(points, cam["extrinsics_cw"])
        return points.astype(np.float32)

    def _has(self, key: str, fix: str) -> bool:
        if self._frame.get(key) is None:
            log.warning("camera %s has no %r data; call camera.%s() (and world.reset(), initialize())",
                        self.prim_path, key, fix)
            return False
        return True

    # -- optics ----------------------------------------------------------------------
    def get_resolution(self) -> tuple[int, int]:
        return self.cfg.width, self.cfg.height

    def set_resolution(self, value: tuple[int, int], maintain_square_pixels: bool = True) -> None:
        """(width, height) px; square pixels: the vertical aperture follows the aspect ratio."""
        width, height = _check_resolution(value)
        self.cfg.width, self.cfg.height = width, height
        self.sensor.close()  # the renderer is sized at creation: a new one at the next render
        self._apply_optics()

    def get_aspect_ratio(self) -> float:
        return self.cfg.width / self.cfg.height

    def get_focal_length(self) -> float:
        """Focal length in Isaac's stage units (tenths of the USD attribute; default 5.0)."""
        return self._focal_length

    def set_focal_length(self, value: float) -> None:
        if not value > 0:
            raise ValueError(f"focal length {value!r} must be > 0, e.g. 2.4")
        self._focal_length = float(value)
        self._apply_optics()

    def get_horizontal_aperture(self) -> float:
        """Sensor width in Isaac's stage units (default 2.0955)."""
        return self._horizontal_aperture

    def set_horizontal_aperture(self, value: float, maintain_square_pixels: bool = True) -> None:
        if not value > 0:
            raise ValueError(f"horizontal aperture {value!r} must be > 0, e.g. 2.0955")
        self._horizontal_aperture = float(value)
        self._apply_optics()

    def get_vertical_aperture(self) -> float:
        """Sensor height: the horizontal aperture times H / W (square pixels)."""
        return self._horizontal_aperture * self.cfg.height / self.cfg.width

    def set_vertical_aperture(self, value: float, maintain_square_pixels: bool = True) -> None:
        self.set_horizontal_aperture(value * self.cfg.width / self.cfg.height)

    def get_horizontal_fov(self) -> float:
        """rad."""
        return 2 * math.atan(self._horizontal_aperture / (2 * self._focal_length))

    def get_vertical_fov(self) -> float:
        """rad (exact, from the vertical aperture; Isaac scales the horizontal fov by H / W)."""
        return 2 * math.atan(self.get_vertical_aperture() / (2 * self._focal_length))

    def get_clipping_range(self) -> tuple[float, float]:
        """(near, far) m; a new USD camera's (1, 1e6) by default: nearer surfaces are clipped."""
        return tuple(float(v) for v in self.cfg.clipping_range_m)

    def set_clipping_range(self, near_distance: float | None = None, far_distance: float | None = None) -> None:
        near, far = self.cfg.clipping_range_m
        near = near if near_distance is None else float(near_distance)
        far = far if far_distance is None else float(far_distance)
        if not 0 < near < far:
            raise ValueError(f"clipping range ({near}, {far}) needs 0 < near < far (m), e.g. (0.01, 1000)")
        self.cfg.clipping_range_m = (near, far)
        self._stale = True

    def get_intrinsics_matrix(self) -> np.ndarray:
        """(3, 3) K: fx = W f / h_aperture, fy = H f / v_aperture, principal point (W/2, H/2)."""
        w, h = self.get_resolution()
        fx = w * self._focal_length / self._horizontal_aperture
        fy = h * self._focal_length / self.get_vertical_aperture()
        return np.array([[fx, 0.0, w * 0.5], [0.0, fy, h * 0.5], [0.0, 0.0, 1.0]], np.float32)

    def get_image_coords_from_world_points(self, points_3d) -> np.ndarray:
        """(n, 2) pixel coordinates (u, v) of (n, 3) world points (pinhole projection)."""
        pos, rot_usd = self._world_pose_usd()
        rot_ros = rot_from_usd(rot_usd, "ros")
        p_c = (np.asarray(points_3d, float) - pos) @ rot_ros
        uv = p_c @ self.get_intrinsics_matrix().astype(float).T
        return uv[:, :2] / uv[:, 2:3]

    def _apply_optics(self) -> None:
        fovy = _fovy_deg(self._focal_length, self._horizontal_aperture, self.cfg.width, self.cfg.height)
        self.cfg.fovy_deg, self.cfg.focal_length_px = fovy, None
        if self.initialized:
            self.sensor.engine.model_field("cam_fovy")[:, self.sensor.cam_id] = fovy
        self._stale = True

    # -- poses -----------------------------------------------------------------------
    def get_world_pose(self, camera_axes: str = "world") -> tuple[np.ndarray, np.ndarray]:
        """Position (3,) m and orientation (4,) wxyz in the world, in ``camera_axes``."""
        pos, rot_usd = self._world_pose_usd()
        return pos, mat_to_quat(rot_from_usd(rot_usd, camera_axes))

    def set_world_pose(self, position=None, orientation=None, camera_axes: str = "world") -> None:
        rot_usd = None if orientation is None else quat_to_mat(_usd_quat(orientation, camera_axes))
        if not self.initialized:
            pending = self._pending_world_pose
            if pending is None:  # keep the other half where it is authored now
                pending = (None, None)
            pos = pending[0] if position is None else np.asarray(position, float)
            if pos is None:
                raise RuntimeError("set_world_pose(orientation=...) before world.reset() needs a position= too")
            self._pending_world_pose = (pos, rot_usd if rot_usd is not None else pending[1])
            return
        cur_pos, cur_rot = self._world_pose_usd()
        pos = cur_pos if position is None else np.asarray(position, float)
        rot_usd = cur_rot if rot_usd is None else rot_usd
        mount_pos, mount_rot = self._mount_pose()
        self._set_offset(mount_rot.T @ (pos - mount_pos), mount_rot.T @ rot_usd)

    def get_local_pose(self, camera_axes: str = "world") -> tuple[np.ndarray, np.ndarray]:
        """Translation (3,) m and orientation (4,) wxyz relative to the parent prim."""
        if self.initialized:
            pos, rot_usd = self._world_pose_usd()
            mount_pos, mount_rot = self._mount_pose()
            local_pos, local_rot = mount_rot.T @ (pos - mount_pos), mount_rot.T @ rot_usd
        else:
            local_pos = np.asarray(self.cfg.offset_pos, float)
            local_rot = quat_to_mat(np.asarray(self.cfg.offset_quat, float))
        return local_pos, mat_to_quat(rot_from_usd(local_rot, camera_axes))

    def set_local_pose(self, translation=None, orientation=None, camera_axes: str = "world") -> None:
        cur_pos, cur_quat = self.get_local_pose("usd")
        pos = cur_pos if translation is None else np.asarray(translation, float)
        quat = cur_quat if orientation is None else _usd_quat(orientation, camera_axes)
        self._set_offset(pos, quat_to_mat(quat))

    def _set_offset(self, pos: np.ndarray, rot_usd: np.ndarray) -> None:
        self._store_offset(pos, rot_usd)
        if self.initialized:
            self.sensor.set_local_pose(pos, mat_to_quat(rot_usd), convention="opengl")
        self._stale = True

    def _store_offset(self, pos: np.ndarray, rot_usd: np.ndarray) -> None:
        # the config is what a recompiled stage initializes from: keep the pose there too
        self.cfg.offset_pos = tuple(float(v) for v in pos)
        self.cfg.offset_quat = tuple(float(v) for v in mat_to_quat(rot_usd))

    def _world_pose_usd(self) -> tuple[np.ndarray, np.ndarray]:
        self._require_engine()
        pos, quat = self.sensor.get_world_pose("opengl")
        return pos[0].numpy().astype(float), quat_to_mat(quat[0].numpy())

    def _mount_pose(self) -> tuple[np.ndarray, np.ndarray]:
        engine, mount = self._require_engine(), self.sensor.mount
        model = engine.model
        if mount.site is not None:
            i, pos, mat = model.site(mount.site).id, "site_xpos", "site_xmat"
        else:
            i, pos, mat = (0 if mount.body == "world" else model.body(mount.body).id), "xpos", "xmat"
        return (engine.field(pos)[0, i].cpu().numpy().astype(float),
                engine.field(mat)[0, i].reshape(3, 3).cpu().numpy().astype(float))

    # -- rates -----------------------------------------------------------------------
    def get_frequency(self) -> float:
        """Hz; -1 when the camera renders at every read (no frequency given)."""
        period = self.sensor.update_period_s
        return 1.0 / period if period > 0 else -1

    def set_frequency(self, value: float) -> None:
        self.sensor.update_period_s = period_from(value, None, "Camera")

    def get_dt(self) -> float:
        return self.sensor.update_period_s

    def set_dt(self, value: float) -> None:
        self.sensor.update_period_s = period_from(None, value, "Camera")

    def get_render_product_path(self) -> None:
        """ambulo cameras have no render product (each renders itself)."""
        return None

    def destroy(self) -> None:
        """Free the renderer (its GL context)."""
        self.sensor.close()


def _fovy_deg(focal_length: float, horizontal_aperture: float, width: int, height: int) -> float:
    vertical_aperture = horizontal_aperture * height / width  # square pixels
    return math.degrees(2 * math.atan(vertical_aperture / (2 * focal_length)))


def _usd_quat(orientation, camera_axes: str) -> np.ndarray:
    quat = np.asarray(check_quat("orientation", orientation))
    return mat_to_quat(rot_to_usd(quat_to_mat(quat), camera_axes))


def _mount_pose_at_rest(model: mujoco.MjModel, mount) -> tuple[np.ndarray, np.ndarray]:
    """World pose of a mount in the model's initial configuration (qpos0)."""
    data = mujoco.MjData(model)
    mujoco.mj_kinematics(model, data)
    if mount.site is not None:
        i = model.site(mount.site).id
        return data.site_xpos[i].copy(), data.site_xmat[i].reshape(3, 3).copy()
    i = 0 if mount.body == "world" else model.body(mount.body).id
    return data.xpos[i].copy(), data.xmat[i].reshape(3, 3).copy()


__all__ = ["Camera", "SUPPORTED_ANNOTATORS"]
