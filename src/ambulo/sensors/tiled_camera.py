"""TiledCamera: one pinhole camera rendered in every world at once by MuJoCo Warp's ray caster.

Isaac Lab's ``TiledCamera`` renders the cameras of all envs in one call and hands back
(N, H, W, C) tensors; this is the same on MuJoCo Warp (``mujoco_warp.create_render_context``,
``refit_bvh``, ``render``). It needs the warp engine (``GpuEngine``: a CUDA device, or Warp's
CPU device with ``engine="warp"``); with MuJoCo's CPU engine use ``ambulo.sensors.Camera``,
which rasterizes one world at a time with MuJoCo's OpenGL renderer.

Outputs (``camera.data.output[name]``, on the engine's device, row 0 the top of the image):

- ``"rgb"``: (N, H, W, 3) uint8, lit by the model's lights and headlight (no shadows);
- ``"depth"``: (N, H, W, 1) float32 m, distance to the image plane (as ``Camera``'s
  ``"depth"``; MuJoCo Warp projects the hit distance onto the optical axis), +inf where the
  ray hits nothing within the far clip;
- ``"instance_segmentation"``: (N, H, W, 1) int32 geom id, -1 for none (flex hits too); this is
  ``Camera``'s ``"geom_ids"``, not its ``"instance_segmentation"`` (ids of labelled bodies);
- ``"semantic_segmentation"``: (N, H, W, 1) int32 semantic id of the geom's labelled body
  (``ambulo.core.semantics``; ids as ``Camera``'s: 0 background or unlabelled, k for
  ``table.categories[k - 1]``).

Intrinsics are ``Camera``'s for the same config (square pixels, centres at integer OpenCV
coordinates). Two differences from ``Camera``: rays start at the camera centre, so the near
clip distance only matters to ``Camera`` (nothing is cut in front of it here), and the image
is one ray per pixel (no multisampling).

The camera pose is the mount's pose (``xpos``/``site_xpos`` of the engine) times a per-world
offset (``set_local_pose``, ``set_camera_view``), written into the engine's ``cam_xpos`` and
``cam_xmat`` before each render; geometry and mount come from the same kinematics pass.
Rendering is lazy, as Isaac Lab's sensors: ``update`` and ``reset`` mark the images out of
date and the next read of ``data`` renders every world (``refit_bvh``, ``render`` and one kernel
that unpacks the buffers into the outputs: one CUDA graph on a GPU, recaptured when
``engine.model_version`` changes), so an env that resets worlds after physics observes their new
state. On an H100, 1024 worlds at 128 x 128 with all four outputs render at 0.93x raw
``refit_bvh`` + ``render`` (benchmarks/render_gpu.py).
"""

from __future__ import annotations

import functools
from dataclasses import dataclass

import mujoco
import numpy as np
import torch

from ambulo.utils.checks import InvalidValueError
from ambulo.utils.rotations import mat_to_quat, quat_to_mat

from . import annotators as ann
from .base import MountPose, Sensor, spec_body
from .camera import PinholeCfg
from .frames import check_convention, look_at_gl

DATA_TYPES = ("rgb", "depth", "instance_segmentation", "semantic_segmentation")
# Isaac Replicator names for the same outputs
_ALIASES = {"distance_to_image_plane": "depth", "rgba": "rgb"}
_SEGMENTATION = ("instance_segmentation", "semantic_segmentation")
_OBJ_GEOM = int(mujoco.mjtObj.mjOBJ_GEOM)


@dataclass(kw_only=True)
class TiledCameraCfg(PinholeCfg):
    """A pinhole camera on a body or site, rendered in all worlds at once. The far clip applies;
    the near one does not (rays start at the camera)."""

    width: int = 128
    """Image width (px)."""
    height: int = 128
    """Image height (px)."""
    data_types: tuple[str, ...] = ("rgb",)
    """Outputs of ``data.output``, a subset of ``DATA_TYPES``."""

    def __post_init__(self):
        """The pinhole fields by ``PinholeCfg``'s rules (the CPU camera's one-line errors), then
        the outputs and the axis convention."""
        super().__post_init__()
        if isinstance(self.data_types, str) or not self.data_types:
            raise InvalidValueError("data_types", self.data_types, "expected a non-empty tuple of names",
                                    f"pass a subset of {DATA_TYPES}, e.g. ('rgb', 'depth')")
        for name in self.data_types:
            if _ALIASES.get(name, name) not in DATA_TYPES:
                raise InvalidValueError("data_types", self.data_types, f"unknown output {name!r}",
                                        f"pass a subset of {DATA_TYPES}")
        if self.offset_convention not in ("world", "opengl", "opencv", "ros"):
            raise InvalidValueError("offset_convention", self.offset_convention, "unknown camera convention",
                                    "use 'world', 'opengl', 'opencv' or 'ros'")


@dataclass(kw_only=True)
class TiledCameraData:
    """What a ``TiledCamera`` read last (all tensors on the engine's device)."""

    output: dict[str, torch.Tensor]
    """Images by name, each (N, H, W, C); see the module docstring. The tensors are the sensor's
    buffers, overwritten by the next render: clone what must outlive it."""
    intrinsic_matrices: torch.Tensor
    """(N, 3, 3) float32 K (OpenCV: pixel centres at integer coordinates), the same per world."""
    pos_w: torch.Tensor
    """(N, 3) float32 m: camera centre in the world frame at the last render."""
    rot_w_gl: torch.Tensor
    """(N, 3, 3) float32: the camera's OpenGL axes (x right, y up, looking along -z) as columns,
    in the world frame, at the last render."""
    image_shape: tuple[int, int]
    """(H, W) px."""


class TiledCamera(Sensor):
    """TiledCamera(TiledCameraCfg(...)) or TiledCamera(prim_path=..., width=..., ...)."""

    def __init__(self, cfg: TiledCameraCfg | None = None, **kwargs):
        if cfg is None:
            cfg = TiledCameraCfg(**kwargs)
        elif kwargs:
            raise TypeError("pass either a TiledCameraCfg or keyword arguments, not both")
        if cfg.renderer != "raster":
            # MuJoCo Warp casts one ray per pixel for all worlds in one launch; Filament reads back one
            # view per render call and the path tracer one world per scene, so neither batches here
            raise ValueError(
                f"TiledCamera renders every world in one MuJoCo Warp launch and cannot batch renderer="
                f"{cfg.renderer!r}; use Camera(CameraCfg(renderer={cfg.renderer!r}, ...)), which renders "
                "world by world, or renderer='raster' here")
        self.cfg = cfg
        self.data_types = tuple(dict.fromkeys(_ALIASES.get(n, n) for n in cfg.data_types))
        super().__init__(cfg.prim_path)
        self._context = None
        self._graph = None
        self._graph_version = -1
        self._outdated = True

    # -- lifecycle ------------------------------------------------------------
    def build(self, spec: mujoco.MjSpec) -> None:
        super().build(spec)
        if spec.camera(self.name) is not None:
            raise ValueError(f"a camera named {self.name!r} already exists; give each camera its own prim path")
        pos, rot = self._offset_in_mount()
        if self.mount.site is not None:
            site = spec.site(self.mount.site)
            site_rot = quat_to_mat(np.asarray(site.quat, float))
            pos, rot = np.asarray(site.pos, float) + site_rot @ pos, site_rot @ rot
        # the model's camera holds the default pose and the field of view the rays are built from
        spec_body(spec, self.mount).add_camera(name=self.name, pos=pos, quat=mat_to_quat(rot),
                                               fovy=self.fovy_deg)

    def initialize(self, engine) -> None:
        super().initialize(engine)
        if not hasattr(engine, "wp_model"):
            raise RuntimeError(
                f"TiledCamera {self.prim_path!r} renders with MuJoCo Warp and needs the warp engine "
                f"(engine='warp', or a CUDA device), not {type(engine).__name__}; on MuJoCo's CPU "
                "engine use ambulo.sensors.Camera")
        n, dev = engine.num_worlds, engine.device
        h, w = self.cfg.height, self.cfg.width
        self.cam_id = engine.model.camera(self.name).id
        self._mount_pose = MountPose(engine, self.mount)
        pos, rot = self._offset_in_mount()
        self._default_offset = (torch.as_tensor(pos, dtype=torch.float32, device=dev),
                                torch.as_tensor(rot, dtype=torch.float32, device=dev))
        self._offset_pos = self._default_offset[0].repeat(n, 1)
        """(N, 3) float32 m: camera position in the mount frame, per world."""
        self._offset_rot_gl = self._default_offset[1].repeat(n, 1, 1)
        """(N, 3, 3) float32: camera OpenGL axes in the mount frame, per world."""
        self._cam_xpos, self._cam_xmat = engine.field("cam_xpos"), engine.field("cam_xmat")
        # bound so that a forward of some worlds keeps the others' geometry in step with their
        # mount pose (GpuEngine restores bound derived fields of the worlds it did not reset)
        engine.field("geom_xpos"), engine.field("geom_xmat")
        self.table = ann.instance_table(engine.model)
        semantic_of_geom = self.table.semantic_ids[self.table.geom_instance]  # index g + 1, 0: none
        self._semantic_of_geom = torch.as_tensor(semantic_of_geom, dtype=torch.int32, device=dev)
        k = torch.as_tensor(self.get_intrinsics_matrix(), dtype=torch.float32, device=dev)
        self.data = TiledCameraData(
            output={}, intrinsic_matrices=k.expand(n, 3, 3).contiguous(),
            pos_w=torch.zeros(n, 3, device=dev), rot_w_gl=torch.zeros(n, 3, 3, device=dev),
            image_shape=(h, w))
        self._buffers = {}
        for name in self.data_types:
            dtype, channels = {"rgb": (torch.uint8, 3), "depth": (torch.float32, 1)}.get(name, (torch.int32, 1))
            self._buffers[name] = torch.zeros(n, h, w, channels, dtype=dtype, device=dev)
        self._context = self._create_context()
        self._wp_outputs = self._warp_outputs()
        self._outdated = True

    def update(self, dt_s: float) -> None:
        """Physics advanced: the next read of ``data`` renders (no work here)."""
        self._outdated = True

    def reset(self, world_ids: torch.Tensor | None = None) -> None:
        """Worlds were reset: the next read of ``data`` renders them anew (all worlds are
        rendered together, so ``world_ids`` only matters to the base class)."""
        super().reset(world_ids)
        self._outdated = True

    # -- outputs --------------------------------------------------------------
    @property
    def data(self) -> TiledCameraData:
        """The images of the current state of every world, rendered if out of date."""
        if self._outdated:
            self.render()
        return self._data

    @data.setter
    def data(self, value: TiledCameraData) -> None:
        self._data = value

    def render(self) -> None:
        """Render every world now and fill ``data`` (no host sync)."""
        self._require_initialized()
        engine = self.engine
        pos, rot = self._pose_gl()
        self._cam_xpos[:, self.cam_id] = pos
        self._cam_xmat[:, self.cam_id] = rot.reshape(-1, 9)
        self._data.pos_w.copy_(pos)
        self._data.rot_w_gl.copy_(rot)
        if engine.use_graphs:
            if self._graph is None or self._graph_version != engine.model_version:
                self._capture()
            import warp as wp  # the warp engine's dependency

            with engine.warp_scope():
                wp.capture_launch(self._graph)
        else:
            with engine.warp_scope():
                self._launch()
        self._data.output = dict(self._buffers)
        self._outdated = False

    def _launch(self) -> None:
        """``refit_bvh``, ``render``, then one pass that unpacks the render context's buffers
        into the (N, H, W, C) outputs (rgb bytes, +inf for misses, geom and semantic ids)."""
        import mujoco_warp as mjw
        import warp as wp

        m, d, rc = self.engine.wp_model, self.engine.wp_data, self._context
        mjw.refit_bvh(m, d, rc)
        mjw.render(m, d, rc)
        n, (h, w) = self.engine.num_worlds, self._data.image_shape
        wp.launch(_unpack_kernel(), dim=(n, h * w),
                  inputs=[rc.rgb_data, rc.depth_data, rc.seg_data, self._wp_semantic_of_geom],
                  outputs=self._wp_outputs)

    def _capture(self) -> None:
        """Capture ``_launch`` as a CUDA graph. The graph holds the engine's model arrays, so it
        is captured again when ``engine.model_version`` changes; the render context itself holds
        none (MuJoCo Warp passes them at each launch) and is kept."""
        import warp as wp

        from ambulo.engine.gpu import capture_graph  # needs the warp engine's packages

        engine = self.engine
        with engine.warp_scope():
            self._launch()  # compiles the kernels, which a capture cannot
        torch.cuda.synchronize(engine.device)
        self._capture_stream = wp.Stream(engine.wp_device)
        self._graph = capture_graph(engine.wp_device, self._capture_stream, self._launch)
        self._graph_version = engine.model_version

    def _warp_outputs(self) -> list:
        """Warp views of the output tensors as the unpack kernel takes them, (N, H*W[, 3]);
        empty arrays for outputs not asked for."""
        import warp as wp

        n, (h, w) = self.engine.num_worlds, self._data.image_shape
        views = []
        for name, dtype, shape in (("rgb", wp.uint8, (n, h * w, 3)), ("depth", wp.float32, (n, h * w)),
                                   ("instance_segmentation", wp.int32, (n, h * w)),
                                   ("semantic_segmentation", wp.int32, (n, h * w))):
            buffer = self._buffers.get(name)
            empty = wp.empty((0,) * len(shape), dtype=dtype, device=self.engine.wp_device)
            views.append(empty if buffer is None else wp.from_torch(buffer.view(shape), dtype=dtype))
        self._wp_semantic_of_geom = wp.from_torch(self._semantic_of_geom)
        return views

    def _create_context(self):
        import mujoco_warp as mjw

        model = self.engine.model.__copy__()
        # MuJoCo Warp reads the far clip from the model's visual settings (scaled by extent)
        near, far = self.cfg.clipping_range_m
        model.vis.map.znear, model.vis.map.zfar = near / model.stat.extent, far / model.stat.extent
        wants = set(self.data_types)
        with self.engine.warp_scope():
            return mjw.create_render_context(
                model, self.engine.num_worlds, cam_res=(self.cfg.width, self.cfg.height),
                render_rgb="rgb" in wants, render_depth="depth" in wants,
                render_seg=bool(wants & set(_SEGMENTATION)), cam_active=[self.cam_id],
                use_shadows=False)

    # -- intrinsics and pose -----------------------------------------------------
    @property
    def resolution(self) -> tuple[int, int]:
        return self.cfg.width, self.cfg.height

    @property
    def fovy_deg(self) -> float:
        return self.cfg.image_fovy_deg()

    def get_intrinsics_matrix(self) -> np.ndarray:
        """(3, 3) float64 K (OpenCV: pixel centres at integer coordinates, square pixels)."""
        return self.cfg.intrinsics_matrix()

    def set_local_pose(self, pos=None, quat=None, convention: str = "world", world_ids=None) -> None:
        """Set the offset from the mount (m, wxyz in ``convention`` axes) for ``world_ids``
        (default all); takes effect at the next render."""
        ids = self._ids(world_ids)
        if pos is not None:
            self._offset_pos[ids] = torch.as_tensor(pos, dtype=torch.float32, device=self.engine.device)
        if quat is not None:
            rot = quat_to_mat(np.asarray(quat, float)) @ check_convention(convention)
            self._offset_rot_gl[ids] = torch.as_tensor(rot, dtype=torch.float32, device=self.engine.device)
        self._outdated = True

    def set_world_pose(self, pos, rot_w_gl, world_ids=None) -> None:
        """Place the camera at world position (.., 3) m with OpenGL axes ``rot_w_gl`` (.., 3, 3),
        relative to where its mount is now."""
        ids = self._ids(world_ids)
        dev = self.engine.device
        mount_pos, mount_rot = self._mount_pose.pos_w()[ids].float(), self._mount_pose.rot_w()[ids].float()
        pos = torch.as_tensor(pos, dtype=torch.float32, device=dev).expand(len(ids), 3)
        rot = torch.as_tensor(rot_w_gl, dtype=torch.float32, device=dev).expand(len(ids), 3, 3)
        r_t = mount_rot.transpose(-1, -2)
        self._offset_pos[ids] = (r_t @ (pos - mount_pos)[..., None])[..., 0]
        self._offset_rot_gl[ids] = r_t @ rot
        self._outdated = True

    def set_camera_view(self, eye, target, up=(0.0, 0.0, 1.0), world_ids=None) -> None:
        """Put the camera at ``eye`` (m, world) looking at ``target``, as in Isaac's set_camera_view."""
        self.set_world_pose(np.asarray(eye, float), look_at_gl(eye, target, up), world_ids)

    def reset_pose(self, world_ids=None) -> None:
        """Back to the configured offset."""
        ids = self._ids(world_ids)
        self._offset_pos[ids], self._offset_rot_gl[ids] = self._default_offset
        self._outdated = True

    # -- helpers ----------------------------------------------------------------
    def _ids(self, world_ids) -> torch.Tensor:
        """World indices (a long tensor on the device) of ids, an (N,) mask or None (all)."""
        self._require_initialized()
        if world_ids is None:
            return torch.arange(self.engine.num_worlds, device=self.engine.device)
        ids = torch.as_tensor(world_ids, device=self.engine.device).reshape(-1)
        # posing is set-up work, not the step path: finding a mask's rows may wait for the device
        return ids.nonzero().squeeze(-1) if ids.dtype == torch.bool else ids.long()

    def _offset_in_mount(self) -> tuple[np.ndarray, np.ndarray]:
        rot = quat_to_mat(np.asarray(self.cfg.offset_quat, float)) @ check_convention(self.cfg.offset_convention)
        return np.asarray(self.cfg.offset_pos, float), rot

    def _pose_gl(self) -> tuple[torch.Tensor, torch.Tensor]:
        """World position (N, 3) and OpenGL axes (N, 3, 3) of the camera, float32."""
        mount_pos, mount_rot = self._mount_pose.pos_w().float(), self._mount_pose.rot_w().float()
        pos = mount_pos + (mount_rot @ self._offset_pos[..., None])[..., 0]
        return pos, mount_rot @ self._offset_rot_gl


@functools.cache
def _unpack_kernel():
    """The Warp kernel that turns render-context buffers into the outputs (built on first use,
    so that importing this module needs no Warp)."""
    import warp as wp

    @wp.kernel(module="unique", enable_backward=False)
    def unpack(rgb_in: wp.array2d(dtype=wp.uint32), depth_in: wp.array2d(dtype=wp.float32),
               seg_in: wp.array2d(dtype=wp.vec2i), semantic_of_geom: wp.array(dtype=wp.int32),
               rgb_out: wp.array3d(dtype=wp.uint8), depth_out: wp.array2d(dtype=wp.float32),
               instance_out: wp.array2d(dtype=wp.int32), semantic_out: wp.array2d(dtype=wp.int32)):
        world, pixel = wp.tid()
        if rgb_out.shape[0] > 0:
            packed = rgb_in[world, pixel]  # 0xAARRGGBB
            rgb_out[world, pixel, 0] = wp.uint8((packed >> wp.uint32(16)) & wp.uint32(255))
            rgb_out[world, pixel, 1] = wp.uint8((packed >> wp.uint32(8)) & wp.uint32(255))
            rgb_out[world, pixel, 2] = wp.uint8(packed & wp.uint32(255))
        if depth_out.shape[0] > 0:
            depth = depth_in[world, pixel]
            if depth <= 0.0:  # nothing hit within the far clip
                depth = wp.inf
            depth_out[world, pixel] = depth
        if instance_out.shape[0] > 0 or semantic_out.shape[0] > 0:
            hit = seg_in[world, pixel]  # (object id, object type); (-1, -1): nothing
            geom = int(-1)
            if hit[1] == wp.static(_OBJ_GEOM):
                geom = hit[0]
            if instance_out.shape[0] > 0:
                instance_out[world, pixel] = geom
            if semantic_out.shape[0] > 0:
                semantic_out[world, pixel] = semantic_of_geom[geom + 1]

    return unpack


__all__ = ["DATA_TYPES", "TiledCamera", "TiledCameraCfg", "TiledCameraData"]
