"""One reusable offscreen MuJoCo renderer: rgb, metric depth and geom-id images.

``mujoco.Renderer`` renders once per output (rgb, depth, segmentation). We render
twice per frame instead: a lit pass read back as rgb, and a flat-colour id pass
(``mjRND_SEGMENT``) read back as geom ids *and* depth from the same depth buffer.
The camera pose is written straight into the scene's GL camera, so a camera can
be posed per world without touching the model or recomputing kinematics.
"""

from __future__ import annotations

import contextlib
import copy
import sys
from dataclasses import dataclass

import mujoco
import numpy as np

from ..utils.validate import Checked
from .gl import create_gl_context, gl_renderer_string
from .point_lights import light_point_lights

# Geom categories we draw: no decorations (contact points, frames, labels).
_CATMASK = int(mujoco.mjtCatBit.mjCAT_STATIC) | int(mujoco.mjtCatBit.mjCAT_DYNAMIC)
_GEOM = int(mujoco.mjtObj.mjOBJ_GEOM)


_KTX_SKIPPED = "classic renderer can't upload"
"""MuJoCo's warning when a context meets a KTX texture (an image light's: a USD DomeLight)."""
_ktx_warned = False


@contextlib.contextmanager
def _image_light_warning_once():
    """MuJoCo's rasterizer warns, on every context it makes, that it skips a model's KTX textures
    (image lights, which it stands in for with an ambient light); a camera, a viewer, a recorder
    or a dataset worker each make one, so a model with a dome printed it again and again. Said
    once per process here; MuJoCo's other warnings pass through as before."""
    previous = mujoco.get_mju_user_warning()

    def warn(message: str) -> None:
        global _ktx_warned
        if _KTX_SKIPPED in message:
            if _ktx_warned:
                return
            _ktx_warned = True
        if previous is not None:
            previous(message)
        else:
            print(f"WARNING: {message}", file=sys.stderr, flush=True)  # MuJoCo's own handler: stdout

    mujoco.set_mju_user_warning(warn)
    try:
        yield
    finally:
        mujoco.set_mju_user_warning(previous)


@dataclass(kw_only=True)
class RenderSettings(Checked):
    """How the rasterizer draws; defaults are the fast headless ones.

    On a software rasterizer (llvmpipe) shadow maps cost 10-20x the rgb time and
    4x multisampling another ~2x (research/anchors-synthetic-data.md, 3c), so both
    are off unless asked for.
    """

    shadows: bool = False
    multisample: bool = False
    reflections: bool = False
    max_geom: int = 4000


def fast_render_settings() -> RenderSettings:
    return RenderSettings()


def quality_render_settings() -> RenderSettings:
    return RenderSettings(shadows=True, multisample=True, reflections=True)


class OffscreenRenderer:
    """Renders ``model``'s worlds at ``width`` x ``height`` from arbitrary camera poses.

    One GL context, ``MjrContext`` and ``MjvScene`` are created once and reused
    for every frame and world (creating them costs ~100 ms). Any model with the
    same structure as ``model`` (e.g. a world's model with randomized colours or
    material ids) can be rendered; textures and meshes are uploaded once.
    """

    def __init__(self, model: mujoco.MjModel, width: int, height: int,
                 settings: RenderSettings | None = None):
        self.width, self.height = int(width), int(height)
        self.settings = settings or fast_render_settings()
        ctx_model = copy.copy(model)  # the framebuffer size and MSAA live in the model
        ctx_model.vis.global_.offwidth = max(self.width, model.vis.global_.offwidth)
        ctx_model.vis.global_.offheight = max(self.height, model.vis.global_.offheight)
        ctx_model.vis.quality.offsamples = 4 if self.settings.multisample else 0
        self._gl = create_gl_context(self.width, self.height)
        with _image_light_warning_once():
            self._con = mujoco.MjrContext(ctx_model, mujoco.mjtFontScale.mjFONTSCALE_100)
        mujoco.mjr_setBuffer(mujoco.mjtFramebuffer.mjFB_OFFSCREEN, self._con)
        self._con.readDepthMap = mujoco.mjtDepthMap.mjDEPTH_ZEROFAR
        self.gl_renderer = gl_renderer_string()
        self._scene = mujoco.MjvScene(model, maxgeom=self.settings.max_geom)
        self._option = mujoco.MjvOption()
        self._option.sitegroup[:] = 0  # sites are mounts, not scenery
        self._camera = mujoco.MjvCamera()
        self._camera.type = mujoco.mjtCamera.mjCAMERA_FIXED
        self._rect = mujoco.MjrRect(0, 0, self.width, self.height)
        self._rgb = np.empty((self.height, self.width, 3), np.uint8)
        self._ids = np.empty((self.height, self.width, 3), np.uint8)
        self._zbuf = np.empty((self.height, self.width), np.float32)

    @property
    def scene(self) -> mujoco.MjvScene:
        return self._scene

    def update(self, model: mujoco.MjModel, data: mujoco.MjData, cam_id: int,
               pos_w: np.ndarray, rot_w_gl: np.ndarray,
               clip_m: tuple[float, float] | None = None) -> None:
        """Load a world's geoms and put the camera at ``pos_w`` (3,) with axes ``rot_w_gl``.

        ``rot_w_gl`` (3, 3): columns are the camera's OpenGL axes (x right, y up,
        looking along -z) in the world frame. The frustum (fovy, near, far) comes
        from camera ``cam_id`` of ``model``; ``clip_m`` (near, far) replaces the
        model's clip distances, which scale with the model extent.
        """
        self._camera.fixedcamid = cam_id
        mujoco.mjv_updateScene(model, data, self._option, None, self._camera, _CATMASK, self._scene)
        light_point_lights(model, self._scene)  # MuJoCo 4's rasterizer leaves point lights dark
        flags = self._scene.flags
        flags[mujoco.mjtRndFlag.mjRND_SHADOW] = self.settings.shadows
        flags[mujoco.mjtRndFlag.mjRND_REFLECTION] = self.settings.reflections
        forward, up = -rot_w_gl[:, 2], rot_w_gl[:, 1]
        for glcam in self._scene.camera:
            glcam.pos[:] = pos_w
            glcam.forward[:] = forward
            glcam.up[:] = up
            if clip_m is not None:
                # the frustum is given on the near plane: rescale it with the near distance
                scale = clip_m[0] / glcam.frustum_near
                glcam.frustum_bottom *= scale
                glcam.frustum_top *= scale
                glcam.frustum_width *= scale
                glcam.frustum_center *= scale
                glcam.frustum_near, glcam.frustum_far = clip_m
        if model.vis.headlight.active and self._scene.nlight > 0:
            # mjv_makeLights put the headlight at the model camera; follow our pose
            self._scene.lights[0].pos[:] = pos_w
            self._scene.lights[0].dir[:] = forward

    def update_view(self, model: mujoco.MjModel, data: mujoco.MjData, camera: mujoco.MjvCamera) -> None:
        """Load a world's geoms seen from a viewer camera (free, tracking or fixed ``MjvCamera``)."""
        mujoco.mjv_updateScene(model, data, self._option, None, camera, _CATMASK, self._scene)
        light_point_lights(model, self._scene)
        self._scene.flags[mujoco.mjtRndFlag.mjRND_SHADOW] = self.settings.shadows
        self._scene.flags[mujoco.mjtRndFlag.mjRND_REFLECTION] = self.settings.reflections

    def near_far(self) -> tuple[float, float]:
        """Clip distances (m) of the current frustum."""
        cam = self._scene.camera[0]
        return float(cam.frustum_near), float(cam.frustum_far)

    def render_rgb(self) -> np.ndarray:
        """(H, W, 3) uint8 lit colour image, top row first (a view reused per call)."""
        self._set_segment(False)
        self._gl.make_current()
        mujoco.mjr_render(self._rect, self._scene, self._con)
        mujoco.mjr_readPixels(self._rgb, None, self._rect, self._con)
        return self._rgb[::-1]

    def render_ids(self, want_depth: bool = True) -> tuple[np.ndarray, np.ndarray | None]:
        """Geom id per pixel (H, W) int32, -1 for none; and depth (H, W) float32 m or None.

        Depth is the distance to the image plane (camera -z), from the same
        z-buffer as the ids; far clip (nothing hit) reads as +inf.
        """
        self.queue_ids()
        return self.read_ids(want_depth)

    def queue_ids(self) -> None:
        """Issue the id pass; the rasterizer runs while Python continues until ``read_ids``."""
        self._set_segment(True)
        self._gl.make_current()
        mujoco.mjr_render(self._rect, self._scene, self._con)
        self._lut = self._segid_to_geom()  # the scene may be reused before the read

    def read_ids(self, want_depth: bool = True, per_geom: tuple[np.ndarray, ...] = (), geom_ids: bool = True
                 ) -> tuple[np.ndarray, np.ndarray | None] | tuple[np.ndarray, np.ndarray | None, list[np.ndarray]]:
        """Wait for the id pass of ``queue_ids``; same outputs as ``render_ids``.

        ``per_geom``: tables indexed by geom id + 1 (index 0: no geom), e.g. each geom's instance
        id; when given, also returns each table's value per pixel, (H, W) of its dtype. Below 256
        scene geoms each is one lookup of the id pass's red channel through the table composed
        with this pass's segment ids: ``np.take`` of uint8 indices costs half a lookup of the
        int32 geom ids (which NumPy first widens to intp). The red channel is copied out once first:
        each lookup then reads contiguous bytes, not every third one of the flipped rows.
        ``geom_ids`` False (with ``per_geom``, below 256 geoms): the geom ids are not looked up (None in
        their place), for a caller that reads only the tables' values.
        """
        self._gl.make_current()
        mujoco.mjr_readPixels(self._ids, self._zbuf if want_depth else None, self._rect, self._con)
        lut = self._lut
        if len(lut) <= 256:
            # fewer than 256 scene geoms: the id lives in the red channel alone
            red = np.ascontiguousarray(self._ids[::-1, :, 0]) if per_geom else self._ids[::-1, :, 0]
            geom_ids = np.take(lut, red) if geom_ids or not per_geom else None
            values = [np.take(np.take(table, lut + 1), red) for table in per_geom]
        else:
            ids = self._ids[::-1].astype(np.int32)  # the tables need the geom ids here: always looked up
            geom_ids = lut[ids[..., 0] | (ids[..., 1] << 8) | (ids[..., 2] << 16)]
            values = [np.take(table, geom_ids + 1) for table in per_geom]
        depth = self._linear_depth(self._zbuf[::-1]) if want_depth else None
        if per_geom:
            return geom_ids, depth, values
        return geom_ids, depth

    def render_ids_isolated(self, geoms: np.ndarray) -> np.ndarray:
        """Geom ids (H, W) as if only ``geoms`` were in the scene (no occluders).

        Other geoms are moved beyond the far plane for one pass and put back.
        """
        keep = {int(g) for g in geoms}
        moved = []
        for g in self._scene.geoms[: self._scene.ngeom]:
            if not (g.objtype == _GEOM and g.objid in keep):
                moved.append((g, g.pos.copy()))
                g.pos[:] = 1e9
        try:
            ids, _ = self.render_ids(want_depth=False)
        finally:
            for g, pos in moved:
                g.pos[:] = pos
        return ids

    def _segid_to_geom(self) -> np.ndarray:
        # The id pass paints geom k of the scene with colour segid+1 (0 = nothing).
        lut = np.full(self._scene.ngeom + 1, -1, np.int32)
        for g in self._scene.geoms[: self._scene.ngeom]:
            if g.segid >= 0 and g.objtype == _GEOM:
                lut[g.segid + 1] = g.objid
        return lut

    def _linear_depth(self, zbuf: np.ndarray) -> np.ndarray:
        # Invert the perspective depth mapping of a [0, 1] z-buffer (ZEROFAR: 0 = far).
        near, far = self.near_far()
        if self._scene.camera[0].orthographic:
            depth = np.float32(far) - zbuf * np.float32(far - near)
        else:
            # the projection stores z = n (f - d) / (d (f - n)) for depth d; invert it
            depth = zbuf * np.float32(far - near)
            depth += np.float32(near)
            np.divide(np.float32(far * near), depth, out=depth)
        depth[zbuf <= 0.0] = np.inf
        return depth

    def _set_segment(self, on: bool) -> None:
        self._scene.flags[mujoco.mjtRndFlag.mjRND_SEGMENT] = on
        self._scene.flags[mujoco.mjtRndFlag.mjRND_IDCOLOR] = on

    def close(self) -> None:
        if self._con is not None:
            self._gl.make_current()
            self._con.free()
            self._con = None
        if self._gl is not None:
            self._gl.free()
            self._gl = None

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()

    def __del__(self):
        # at interpreter shutdown GL may already be gone; nothing useful to report then
        with contextlib.suppress(Exception):
            self.close()
