"""The ``pbr`` camera tier: MuJoCo 4's Filament renderer (physically based materials, image-based
lighting, shadows) behind one small class.

``PbrRenderer(model, width, height).render(data, camera)`` returns an (H, W, 3) uint8 image seen
from ``camera``, a ``mujoco.MjvGLCamera`` (position, forward/up axes and the frustum on the near
plane): the type MuJoCo's own rasterizer reads, so the ``raster`` and ``pbr`` tiers take the same
intrinsics from the same object (``gl_camera`` builds one from a pose and a field of view).

What Filament reads from the MJCF: each geom's colour and material (``rgba``, ``roughness``,
``metallic``, ``specular``, ``reflectance``, textures), the model's lights (directional, spot,
point; ``castshadow``) and image lights (``<light type="image" texture=...>`` on a KTX cubemap,
which ``ambulo.render.ibl`` writes from an HDR environment). It reads them on every ``render``,
so colour, material and light randomizers written into the model show. Labels never come from
here: depth, ids and boxes come from the raster id pass whatever tier draws the colours.

Filament draws through Vulkan. On a machine without a GPU driver Mesa's lavapipe renders on the
CPU (``apt-get install libvulkan1 mesa-vulkan-drivers``); without a loader or a driver the first
``PbrRenderer`` raises ``NoVulkanError``, one line naming those packages, instead of the abort
inside Filament. Each renderer has its own Filament engine (~1 s to create; the first frame
compiles shaders, ~9 s on lavapipe until Mesa's shader cache holds them): in mujoco-studio 4.0.0
a second model scene with textures in one engine fails its first frame ("unknown exception").
"""

from __future__ import annotations

import contextlib
import ctypes
import glob
import math
import os
import sys
from dataclasses import dataclass

import mujoco
import numpy as np

from ..utils.validate import Checked

INSTALL = "install Vulkan: apt-get install libvulkan1 mesa-vulkan-drivers (Mesa's lavapipe renders on the CPU)"

_VULKAN_LOADER = "libvulkan.so.1"
"""The Vulkan loader Filament opens (tests rename it to simulate a machine without one)."""

_ICD_DIRS = ("/usr/share/vulkan/icd.d", "/etc/vulkan/icd.d", "/usr/local/share/vulkan/icd.d")
"""Where the loader looks for drivers (ICD manifests) unless ``VK_ICD_FILENAMES``/``VK_DRIVER_FILES``
name them: the Vulkan loader's documented search path on Linux."""


class NoVulkanError(RuntimeError):
    """The pbr tier cannot start here; ``str(err)`` is one line ``"<problem>; <fix>"``."""

    def __init__(self, problem: str, fix: str = INSTALL):
        self.problem, self.fix = problem, fix
        super().__init__(f"{problem}; {fix}")

    def __reduce__(self):
        # raised in a dataset worker process, it crosses back to the parent by pickling
        return type(self), (self.problem, self.fix)


@dataclass(kw_only=True)
class PbrSettings(Checked):
    """What Filament draws beyond the lit surfaces.

    ``post_processing`` is Filament's colour pipeline: tone mapping (PBR Neutral), sRGB encoding,
    ambient occlusion and FXAA; off, the image holds linear radiance scaled by the camera's
    exposure, clipped at 1 and quantized to 8 bits (what the Lambertian check compares to the
    analytic irradiance). On lavapipe at 320x240 post-processing costs ~half the frame. It also
    keeps history between frames (temporal filtering): an image depends on what the renderer drew
    before it (up to 40 levels at edges, 0.4 on average, in mujoco-studio 4.0.0, where these
    options are not exposed), so frames are reproducible only with ``post_processing=False``.
    """

    shadows: bool = True
    """Shadow maps: every directional light casts one, whatever its MJCF ``castshadow`` (usually
    off for the rasterizer's sake, 10-20x its frame time on llvmpipe, not because the scene has
    none); point and spot lights cast where the MJCF says so (a point light's shadow is six
    maps: on lavapipe the warehouse's lamp alone took the frame from ~75 to ~210 ms of CPU)."""
    reflections: bool = False
    post_processing: bool = True
    skybox: bool = True
    """Draw the background: the model's first image light (a USD DomeLight) if it has one, else its MJCF skybox."""
    haze: bool = False


def _vulkan_problem() -> str | None:
    """Why Filament's Vulkan backend cannot start here, or None: checked before Filament, which
    aborts the process when it finds no loader or no device."""
    try:
        ctypes.CDLL(_VULKAN_LOADER)
    except OSError:
        return f"no Vulkan loader ({_VULKAN_LOADER} cannot be loaded)"
    named = os.environ.get("VK_DRIVER_FILES") or os.environ.get("VK_ICD_FILENAMES")
    if named:
        if not any(os.path.isfile(p) for p in named.split(os.pathsep)):
            return f"no Vulkan driver: none of the files VK_DRIVER_FILES/VK_ICD_FILENAMES names exists ({named})"
        return None
    if not any(glob.glob(os.path.join(d, "*.json")) for d in _ICD_DIRS):
        return f"no Vulkan driver (no ICD manifest in {', '.join(_ICD_DIRS)})"
    return None


def _filament_context():
    """A new Filament context (``mjrf.Context``) on Vulkan, or ``NoVulkanError``."""
    problem = _vulkan_problem()
    if problem is not None:
        raise NoVulkanError(problem)
    try:
        # registers the 'filament:' resource provider that serves the shipped materials (pbr.filamat)
        import mujoco.studio._studio  # noqa: F401
        from mujoco import mjrf
    except ImportError as err:
        raise NoVulkanError(f"MuJoCo's Filament renderer is not installed ({err})",
                            "pip install mujoco-studio (it ships mujoco.mjrf)") from err
    config = mjrf.ContextConfig()
    config.graphics_api = mjrf.GraphicsApi.GRAPHICS_API_VULKAN
    return mjrf.Context(config)


@contextlib.contextmanager
def _quiet_stdout():
    """Filament logs its engine start-up (backend, device, buffers: seven lines) on file descriptor
    1 from C++, where a program's own output goes (``ambulo generate``'s summary, JSON on stdout);
    they are dropped while the engine starts and draws its first frame. Errors go to stderr."""
    sys.stdout.flush()
    saved = os.dup(1)
    try:
        with open(os.devnull, "wb") as devnull:
            os.dup2(devnull.fileno(), 1)
        yield
    finally:
        os.dup2(saved, 1)
        os.close(saved)


def gl_camera(pos_w, rot_w_gl, fovy_deg: float, width: int, height: int,
              clip_m: tuple[float, float]) -> mujoco.MjvGLCamera:
    """A pinhole ``MjvGLCamera`` at ``pos_w`` (3,) m with OpenGL axes ``rot_w_gl`` (3, 3) columns
    in the world, ``fovy_deg`` vertical field of view, square pixels and (near, far) ``clip_m``:
    the frustum MuJoCo's rasterizer builds for the same camera (``mjv_updateScene``)."""
    cam = mujoco.MjvGLCamera()
    rot = np.asarray(rot_w_gl, float)
    cam.pos[:] = pos_w
    cam.forward[:] = -rot[:, 2]
    cam.up[:] = rot[:, 1]
    near, far = clip_m
    half_h = near * math.tan(math.radians(fovy_deg) / 2)
    cam.frustum_near, cam.frustum_far = near, far
    cam.frustum_top, cam.frustum_bottom = half_h, -half_h
    cam.frustum_center = 0.0
    cam.frustum_width = half_h * width / height
    cam.orthographic = 0
    return cam


class PbrRenderer:
    """Renders worlds of ``model`` at ``width`` x ``height`` with Filament.

    ``model`` is read on every ``render`` (colours, materials, lights), so pass the model object
    that randomizers edit in place; ``data`` must belong to a model of the same structure.
    """

    def __init__(self, model: mujoco.MjModel, width: int, height: int, settings: PbrSettings | None = None):
        from mujoco import mjrf  # only after _filament_context has checked Vulkan

        self.width, self.height = int(width), int(height)
        self.settings = settings or PbrSettings()
        with _quiet_stdout():
            self._ctx = _filament_context()
        self._frames = 0
        self._model = model
        with _colour_textures_as_srgb(model):
            self._resources = mjrf.ModelResources(self._ctx, model)
        self._scene = self._ctx.create_scene(mjrf.SceneParams())
        self._scene.configure_from_model(model)
        self._lights = mjrf.ModelLights(self._scene, self._resources)
        self._renderables = mjrf.ModelRenderables(self._scene, self._resources)
        self._renderables.set_options(_scenery_only())
        # after ModelLights and ModelRenderables: set before them, the background stayed black
        self._skybox = _image_light_skybox(self._ctx, model) if self.settings.skybox else None
        if self._skybox is not None:
            self._scene.set_skybox(self._skybox)
        self._target = self._ctx.create_render_target(mjrf.RenderTargetConfig(
            width=self.width, height=self.height, color_format=mjrf.PixelFormat.PIXEL_FORMAT_RGB8))
        self._rgb = np.zeros((self.height, self.width, 3), np.uint8)
        self._read = mjrf.ReadRequest(self._target)
        self._read.set_buffer(self._rgb)
        self._request = mjrf.RenderRequest()
        self._request.scene = self._scene
        self._request.target = self._target
        self._request.viewport.left, self._request.viewport.bottom = 0, 0
        self._request.viewport.width, self._request.viewport.height = self.width, self.height
        s = self.settings
        self._request.shadows, self._request.reflections = s.shadows, s.reflections
        self._request.post_processing, self._request.skybox, self._request.haze = s.post_processing, s.skybox, s.haze
        self._request.headlight = bool(model.vis.headlight.active)
        if self._request.headlight:  # MuJoCo's headlight is a diffuse colour; Filament's is in lux
            self._request.headlight_color = np.asarray(model.vis.headlight.diffuse, np.float32)
            self._request.headlight_intensity = _HEADLIGHT_LUX
        self._camera = mjrf.Camera()
        self.gl_renderer = "filament/vulkan"

    def render(self, data: mujoco.MjData, camera: mujoco.MjvGLCamera) -> np.ndarray:
        """(H, W, 3) uint8 colour image of ``data`` seen from ``camera``, top row first (a view
        reused by the next call: copy it to keep it)."""
        self._lights.update(data)
        if self.settings.shadows:
            for i in range(self._model.nlight):
                light = self._lights.get_light(i)
                if light is not None and self._model.light_type[i] == mujoco.mjtLightType.mjLIGHT_DIRECTIONAL:
                    light.set_cast_shadow(True)
        self._renderables.update(data)
        cam = self._camera
        cam.pos, cam.forward, cam.up = camera.pos, camera.forward, camera.up
        cam.frustum_near, cam.frustum_far = camera.frustum_near, camera.frustum_far
        cam.frustum_top, cam.frustum_bottom = camera.frustum_top, camera.frustum_bottom
        cam.frustum_center, cam.frustum_width = camera.frustum_center, camera.frustum_width
        cam.orthographic = camera.orthographic
        self._request.camera = cam
        with _quiet_stdout() if self._frames == 0 else contextlib.nullcontext():
            frame = self._ctx.render([self._request], [self._read])
            self._ctx.wait_for_frame(frame)
        self._frames += 1
        return self._rgb

    def close(self) -> None:
        """Drop this renderer's Filament objects, its engine last."""
        self._read = self._request = self._renderables = self._lights = self._scene = self._skybox = None
        self._target = self._resources = self._ctx = None

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()


_HEADLIGHT_LUX = 30000.0
"""Illuminance (lux) of the headlight when the model turns it on: Filament's default exposure
(f/16, 1/125 s, ISO 100) maps ~100,000 lux of sunlight to white, so this is a fill, not a sun."""


@contextlib.contextmanager
def _colour_textures_as_srgb(model: mujoco.MjModel):
    """While Filament uploads the textures: colour textures (materials' RGB role, skyboxes) whose
    MJCF ``colorspace`` is ``auto`` or ``linear`` (a PNG without an sRGB chunk compiles to it)
    marked sRGB, then put back.

    MuJoCo's rasterizer shows those texels as they are (display values, like MJCF rgba), which is what
    sRGB-encoded colours look like; Filament reads them as linear, so a texture lit
    the same as an rgba of its mean colour came out brighter and paler (a checker of mean sRGB
    (0.55, 0.40, 0.45) showed (96, 69, 76) instead of (71, 25, 52) beside that rgba's (46, 24, 29)).
    The model is left as it was: the rasterizer would decode sRGB textures into darker pixels."""
    colour = set(int(t) for t in model.mat_texid[:, int(mujoco.mjtTextureRole.mjTEXROLE_RGB)] if t >= 0)
    colour |= set(np.nonzero(model.tex_type == int(mujoco.mjtTexture.mjTEXTURE_SKYBOX))[0].tolist())
    shown_raw = [t for t in sorted(colour) if model.tex_colorspace[t] != int(mujoco.mjtColorSpace.mjCOLORSPACE_SRGB)]
    authored = model.tex_colorspace[shown_raw].copy()
    model.tex_colorspace[shown_raw] = int(mujoco.mjtColorSpace.mjCOLORSPACE_SRGB)
    try:
        yield
    finally:
        model.tex_colorspace[shown_raw] = authored


def _image_light_skybox(ctx, model: mujoco.MjModel):
    """The model's first image light's cubemap as Filament's skybox, or None without image lights.

    An image light (a USD DomeLight) lights the scene but Filament does not show it: the background
    stayed black (or the MJCF skybox). Shown, it reads the image light's radiance, as the path tier
    shows it (a uniform dome: within 1 level of the expected linear value, ``test_dome_light``); it
    replaces the MJCF skybox there as it does in the path tier."""
    from mujoco import mjrf

    from .ibl import image_light_ids

    ids = image_light_ids(model)
    if not ids:
        return None
    tex = int(model.light_texid[ids[0]])
    if tex < 0:
        return None
    adr = int(model.tex_adr[tex])
    size = int(model.tex_width[tex]) * int(model.tex_height[tex]) * int(model.tex_nchannel[tex])
    texture = ctx.create_texture(mjrf.TextureConfig(width=0, height=0, format=mjrf.PixelFormat.PIXEL_FORMAT_KTX,
                                                    sampler_type=mjrf.SamplerType.TEXTURE_SKYBOX))
    pixels = mjrf.TextureData()
    pixels.set_image(model.tex_data[adr:adr + size].tobytes())
    texture.upload(pixels)
    return texture


def _scenery_only() -> mujoco.MjvOption:
    """What the pbr tier draws: geoms of the default groups, no sites (mounts), no decor; the
    same selection as the rasterizer's camera pass (``OffscreenRenderer``)."""
    option = mujoco.MjvOption()
    option.sitegroup[:] = 0
    return option
