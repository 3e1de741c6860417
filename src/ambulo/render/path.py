"""The path-traced camera tier: Mitsuba 3 renders what MuJoCo's rasterizer would draw.

The scene (``scene_description``: the rasterizer's own geoms, colours, lights and camera) is
built into a Mitsuba scene once; each frame only what moved or changed is written through
``mi.traverse`` parameters (vertex positions of moving geoms, light and camera poses, a geom's
colour, texture and material when a randomizer changed them), so Mitsuba reuses its compiled
kernels; only a surface changing kind (matte <-> glossy, opaque <-> not, emitting) rebuilds the
scene. Images are rendered with Mitsuba's ``path`` integrator at ``spp`` samples per pixel,
denoised with Open Image Denoise guided by first-hit albedo and normals (``denoise``), and encoded
to sRGB.

Variants: ``cuda_ad_rgb`` on an NVIDIA GPU, else ``llvm_ad_rgb`` (CPU; needs libLLVM >= 16:
Debian's ``libllvm19``, which ``scripts/setup.sh`` installs). Labels (depth, ids) are not made
here: they come from the rasterizer's id pass, so they are identical in every tier.

The environment: ``envmap_path`` if given, else the model's image lights (``<light type="image">``,
what a USD DomeLight becomes; read once, when the tracer is built), else the model's skybox (which,
unlike in the rasterizer, also lights the scene), else a constant one of the lights' ambient.

2-D textures lie where the rasterizer puts them on every primitive (planes, boxes, spheres,
ellipsoids, cylinders, capsules: ``scene_description.primitive_texcoords``) and at a mesh's own UVs.

What it does not model: MuJoCo cube-map textures on objects (mean colour), flexes and skins,
orthographic or off-axis cameras, light textures, the rasterizer's fog and haze.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Literal

import mujoco
import numpy as np

from ..utils.validate import Checked, rule
from .denoise import denoise_numpy, denoise_torch, has_pyoidn
from .ibl import image_light_ids, image_light_radiance
from .scene_description import (
    CameraDesc,
    LightDesc,
    MaterialDesc,
    SceneReader,
    SurfaceDesc,
    ambient_radiance,
    camera_of,
    geom_pose,
    infinite_plane_half_m,
    lights_of,
    linear_to_srgb,
    material_of,
    primitive_texcoords,
    skybox_latlong,
    srgb_to_linear,
    surface_of,
)


class NoPathTracerError(RuntimeError):
    """Mitsuba cannot run here; the one-line message names what to install."""


@dataclass(kw_only=True)
class PathTracerCfg(Checked):
    """How the path tracer renders; the defaults are the CPU tier of issue 26 (320x240, 16 spp)."""

    width: int = field(default=320, metadata=rule(minimum=1))
    height: int = field(default=240, metadata=rule(minimum=1))
    spp: int = field(default=16, metadata=rule(minimum=1))
    """Samples per pixel."""
    max_depth: int = field(default=4, metadata=rule(signed=True, minimum=-1))
    """Longest path in vertices (Mitsuba's ``max_depth``): 4 is three bounces; -1 is unbounded."""
    rr_depth: int = field(default=2, metadata=rule(minimum=1))
    """Path depth from which Russian roulette may end a path (Mitsuba's ``rr_depth``; 1: after the
    first bounce). Unbiased (a surviving path is weighted up by 1 / its survival probability):
    only noise, which the denoiser takes. On the warehouse at 320x240, 16 spp (2026-11-28): 2
    instead of Mitsuba's 5 (never, with ``max_depth`` 4) cut the path tracing's CPU time by a
    quarter (~1.75 -> ~1.3 s); the mean image was unchanged (0.264 / 0.287 / 0.187 both) and the
    denoised image's mean error against a 512-spp reference went from 1.05 to 1.08 sRGB levels."""
    denoise: bool = True
    denoise_quality: Literal["fast", "balanced", "high"] = "fast"
    """Open Image Denoise's speed/quality trade: "fast" costs half of "balanced" (0.17 vs 0.32 CPU-s at 320x240)."""
    guide_spp: int = field(default=4, metadata=rule(minimum=1))
    """Samples per pixel of the denoiser's albedo and normal guides (antialiased like the colour)."""
    variant: Literal["auto", "cuda_ad_rgb", "llvm_ad_rgb"] = "auto"
    """"auto": CUDA when an NVIDIA driver is there, else the LLVM CPU backend."""
    envmap_path: str | None = None
    """Latitude-longitude HDR image (.exr, .hdr) lighting the scene, z up, in place of the model's own
    environment; None: the model's image lights, else its skybox, else the lights' ambient (module doc)."""
    envmap_scale: float = field(default=1.0, metadata=rule(minimum=0))
    """Multiplies ``envmap_path``'s values or the model's image lights."""
    exposure: float = field(default=1.0, metadata=rule(minimum=0, strict=True))
    """Multiplies linear radiance before the sRGB encoding."""
    seed: int = 0
    """Noise seed of the first frame; each frame adds one, so frames are independent samples."""
    slices: int = field(default=32, metadata=rule(minimum=3))
    """Tessellation of curved geoms: segments around, and ``slices // 2`` from pole to pole."""


def _mitsuba(variant: str):
    """Import Mitsuba and set ``variant`` ("auto": CUDA if it works, else LLVM)."""
    try:
        import drjit as dr
        import mitsuba as mi
    except ImportError as e:
        raise NoPathTracerError(f"the path tracer needs Mitsuba 3: pip install 'ambulo[render]' ({e})") from None
    if variant == "auto":
        variant = "cuda_ad_rgb" if dr.has_backend(dr.JitBackend.CUDA) else "llvm_ad_rgb"
    backend = dr.JitBackend.CUDA if variant.startswith("cuda") else dr.JitBackend.LLVM
    if not dr.has_backend(backend):
        need = ("an NVIDIA driver (libcuda)" if backend == dr.JitBackend.CUDA
                else "libLLVM >= 16: apt-get install libllvm19 (scripts/setup.sh does it)")
        raise NoPathTracerError(f"Mitsuba variant {variant} cannot run here: it needs {need}")
    mi.set_variant(variant)
    return mi, dr


class PathTracer:
    """Path-traced colour images of ``model``'s scene from its cameras.

    >>> tracer = PathTracer(model, PathTracerCfg(width=320, height=240, spp=16))
    >>> rgb = tracer.render(data, "head_cam")   # (240, 320, 3) uint8 sRGB
    """

    def __init__(self, model: mujoco.MjModel, cfg: PathTracerCfg | None = None):
        self.cfg = cfg or PathTracerCfg()
        self.mi, self._dr = _mitsuba(self.cfg.variant)
        self.variant = self.mi.variant()
        if self.cfg.denoise and not has_pyoidn():
            raise NoPathTracerError("denoise=True needs Open Image Denoise: pip install pyoidn, or pass denoise=False")
        self.model = model
        self._reader = SceneReader(model)
        self._frame = 0
        data = mujoco.MjData(model)
        mujoco.mj_forward(model, data)
        scene = self._reader.read(model, data, 0 if model.ncam else -1)
        self._surfaces: dict[int, SurfaceDesc] = {}
        self._poses: dict[int, tuple[np.ndarray, np.ndarray]] = {}
        self._looks: dict[int, tuple] = {}
        half = infinite_plane_half_m(model)
        for geom in scene.geoms[: scene.ngeom]:
            surface = surface_of(model, geom, half, self.cfg.slices, self.cfg.slices // 2)
            if surface is not None:
                self._surfaces[surface.geom_id] = surface
                self._poses[surface.geom_id] = geom_pose(geom)
                self._looks[surface.geom_id] = _look_of(geom)
        self._lights = lights_of(model, data, scene)
        self._scene = self.mi.load_dict(self._scene_dict(scene, camera_of(scene, self.cfg.width, self.cfg.height)))
        self._params = self.mi.traverse(self._scene)
        self._guide_integrator = self.mi.load_dict({"type": "aov", "aovs": "albedo:albedo,nn:sh_normal"})

    # -- building -------------------------------------------------------------------------------
    def _bsdf(self, material: MaterialDesc) -> dict:
        # a bitmap even without a texture (2 x 2): a material randomizer may texture it later, and
        # a bitmap's texels can be replaced by one of another size without rebuilding the scene
        color = {"type": "bitmap", "bitmap": self.mi.Bitmap(_texels(material)), "raw": True,
                 "filter_type": "bilinear", "wrap_mode": "repeat"}
        if _is_principled(material):
            bsdf = {"type": "principled", "base_color": color, "roughness": material.roughness,
                    "metallic": material.metallic, "specular": material.specular}
        else:
            bsdf = {"type": "diffuse", "reflectance": color}
        if material.opacity < 1:
            bsdf = {"type": "mask", "opacity": material.opacity, "material": bsdf}
        return bsdf

    def _mesh(self, surface: SurfaceDesc, pose: tuple[np.ndarray, np.ndarray]):
        mi, mesh = self.mi, surface.mesh
        props = mi.Properties()
        props["bsdf"] = mi.load_dict(self._bsdf(surface.material))
        if np.any(surface.material.emission > 0):
            props["emitter"] = mi.load_dict({"type": "area", "radiance": {
                "type": "rgb", "value": surface.material.emission.tolist()}})
        out = mi.Mesh(f"geom_{surface.geom_id}", len(mesh.positions), len(mesh.faces), props=props,
                      has_vertex_normals=True, has_vertex_texcoords=True)
        params = mi.traverse(out)
        positions, normals = _to_world(mesh.positions, mesh.normals, pose)
        params["vertex_positions"] = mi.Float(positions.ravel())
        params["vertex_normals"] = mi.Float(normals.ravel())
        params["faces"] = mi.UInt(mesh.faces.ravel())
        params["vertex_texcoords"] = mi.Float(mesh.texcoords.ravel())
        params.update()
        return out

    def _scene_dict(self, scene: mujoco.MjvScene, camera: CameraDesc) -> dict:
        cfg = self.cfg
        integrator = {"type": "path", "max_depth": cfg.max_depth, "rr_depth": cfg.rr_depth}
        out = {"type": "scene", "integrator": integrator, "sensor": {
            "type": "perspective", "fov_axis": "y", "fov": camera.fovy_deg, "near_clip": camera.near_m,
            "far_clip": camera.far_m, "to_world": self._look_at(camera.pos_w, camera.rot_w_gl, scalar=True),
            "sampler": {"type": "multijitter", "sample_count": cfg.spp},
            "film": {"type": "hdrfilm", "width": cfg.width, "height": cfg.height, "rfilter": {"type": "box"},
                     "pixel_format": "rgb"}}}
        for gid, surface in self._surfaces.items():
            out[f"geom_{gid}"] = self._mesh(surface, self._poses[gid])
        for i, light in enumerate(self._lights):
            out[f"light_{i}"] = self._light_dict(light)
        turn = self.mi.ScalarTransform4f().rotate([1, 0, 0], 90)  # Mitsuba's envmaps are y up; ours z up
        ambient = ambient_radiance(scene)
        sky = skybox_latlong(self.model) if scene.flags[mujoco.mjtRndFlag.mjRND_SKYBOX] else None
        images = image_light_ids(self.model)
        if cfg.envmap_path is not None:
            out["environment"] = {"type": "envmap", "filename": cfg.envmap_path, "scale": cfg.envmap_scale,
                                  "to_world": turn}
        elif images:
            # the model's image lights (a USD DomeLight) are the environment, as in the pbr tier: they
            # replace the skybox and the lights' ambient (the rasterizer's stand-in for them)
            env = sum(image_light_radiance(self.model, i) for i in images)
            out["environment"] = {"type": "envmap", "bitmap": self.mi.Bitmap(np.ascontiguousarray(env, np.float32)),
                                  "scale": cfg.envmap_scale, "to_world": turn}
        elif sky is not None:
            # the one environment emitter: the skybox the rasterizer shows, plus the lights' ambient
            sky = np.ascontiguousarray(sky + ambient, np.float32)
            out["environment"] = {"type": "envmap", "bitmap": self.mi.Bitmap(sky), "to_world": turn}
        elif np.any(ambient > 0):
            out["environment"] = {"type": "constant", "radiance": {"type": "rgb", "value": ambient.tolist()}}
        return out

    def _light_dict(self, light: LightDesc) -> dict:
        value = {"type": "rgb", "value": light.intensity.tolist()}
        if light.kind == "directional":
            return {"type": "directional", "irradiance": value, "to_world": self._shine(light, scalar=True)}
        if light.kind == "point":
            return {"type": "point", "intensity": value, "position": light.pos_w.tolist()}
        return {"type": "spot", "intensity": value, "cutoff_angle": light.cutoff_deg, "beam_width": light.beam_deg,
                "to_world": self._shine(light, scalar=True)}

    def _look_at(self, pos_w, rot_w_gl, scalar: bool = False):
        """Mitsuba's camera frame (looks along +z, y up) at the OpenGL pose ``rot_w_gl``."""
        transform = self.mi.ScalarTransform4f() if scalar else self.mi.Transform4f()
        pos = [float(v) for v in pos_w]
        target = [float(v) for v in np.asarray(pos_w) - rot_w_gl[:, 2]]
        return transform.look_at(origin=pos, target=target, up=[float(v) for v in rot_w_gl[:, 1]])

    def _shine(self, light: LightDesc, scalar: bool = False):
        """A frame whose +z is the light's direction (directional and spot emitters shine along +z)."""
        d = light.dir_w
        up = np.array([0.0, 0.0, 1.0]) if abs(d[2]) < 0.9 else np.array([1.0, 0.0, 0.0])
        transform = self.mi.ScalarTransform4f() if scalar else self.mi.Transform4f()
        return transform.look_at(origin=light.pos_w.tolist(), target=(light.pos_w + d).tolist(), up=up.tolist())

    # -- per frame ------------------------------------------------------------------------------
    def update(self, data: mujoco.MjData, camera: int | str = 0,
               pose: tuple[np.ndarray, np.ndarray] | None = None) -> CameraDesc:
        """Write the poses of ``data`` (geoms, lights, camera ``camera`` or ``pose``) into the scene.

        ``pose``: (pos_w (3,), rot_w_gl (3, 3)) replacing the model camera's (as ``OffscreenRenderer``
        takes it). Geoms whose pose and colour are unchanged are not written, so a static scene
        costs no acceleration-structure rebuild. Returns the camera rendered from.
        """
        model, params, mi = self.model, self._params, self.mi
        cam_id = camera if isinstance(camera, (int, np.integer)) else model.camera(camera).id
        scene = self._reader.read(model, data, int(cam_id), pose)
        rebuild = False
        for geom in scene.geoms[: scene.ngeom]:
            gid = int(geom.objid)
            surface = self._surfaces.get(gid) if geom.objtype == mujoco.mjtObj.mjOBJ_GEOM else None
            if surface is None:
                continue
            if not surface.static:
                new_pose = geom_pose(geom)
                old = self._poses[gid]
                if not (np.array_equal(new_pose[0], old[0]) and np.array_equal(new_pose[1], old[1])):
                    positions, normals = _to_world(surface.mesh.positions, surface.mesh.normals, new_pose)
                    params[f"geom_{gid}.vertex_positions"] = mi.Float(positions.ravel())
                    params[f"geom_{gid}.vertex_normals"] = mi.Float(normals.ravel())
                    self._poses[gid] = new_pose
            look = _look_of(geom)
            if look != self._looks[gid]:  # colour, material or texture changed (randomizers)
                self._looks[gid] = look
                rebuild |= self._restyle(surface, geom)
        if rebuild:  # a surface changed kind (matte <-> glossy, opaque <-> not, emitting): a new scene
            self._scene = self.mi.load_dict(self._scene_dict(scene, camera_of(scene, self.cfg.width, self.cfg.height)))
            self._params = params = self.mi.traverse(self._scene)
        self._update_lights(lights_of(model, data, scene))
        cam = camera_of(scene, self.cfg.width, self.cfg.height)
        params["sensor.to_world"] = self._look_at(cam.pos_w, cam.rot_w_gl)
        params["sensor.x_fov"] = _x_fov_deg(cam)
        params.update()  # rebuilds the acceleration structure only when vertices were written
        return cam

    def _restyle(self, surface: SurfaceDesc, geom: mujoco.MjvGeom) -> bool:
        """Write geom ``geom``'s current material into its BSDF (and its UVs when the
        texture's repeat changed); True when the BSDF's kind changed, which needs a new scene."""
        old, new = surface.material, material_of(self.model, geom)
        surface.material = new
        if _kind(new) != _kind(old):
            return True
        params, mi, gid = self._params, self.mi, surface.geom_id
        prefix = f"geom_{gid}.bsdf." + ("material." if new.opacity < 1 else "")
        if _is_principled(new):
            params[prefix + "base_color.data"] = mi.TensorXf(_texels(new))
            params[prefix + "roughness.value"] = new.roughness
            params[prefix + "metallic.value"] = new.metallic
            params[prefix + "specular"] = new.specular
        else:
            params[prefix + "reflectance.data"] = mi.TensorXf(_texels(new))
        if new.opacity < 1:
            params[f"geom_{gid}.bsdf.opacity.value"] = new.opacity
        if new.texture is not None and surface.planar_uv:
            uv = primitive_texcoords(surface.mesh, geom)
            if not np.array_equal(uv, surface.mesh.texcoords):
                surface.mesh.texcoords = uv
                params[f"geom_{gid}.vertex_texcoords"] = mi.Float(uv.ravel())
        return False

    def _update_lights(self, lights: list[LightDesc]) -> None:
        params, mi = self._params, self.mi
        if len(lights) != len(self._lights):
            raise RuntimeError("the number of lights changed; build a new PathTracer for the new model")
        for i, (new, old) in enumerate(zip(lights, self._lights)):
            if (np.array_equal(new.pos_w, old.pos_w) and np.array_equal(new.dir_w, old.dir_w)
                    and np.array_equal(new.intensity, old.intensity)):
                continue
            key = "irradiance" if new.kind == "directional" else "intensity"
            params[f"light_{i}.{key}.value"] = mi.Color3f(*new.intensity.tolist())
            if new.kind == "point":
                params[f"light_{i}.position"] = mi.Point3f(*new.pos_w.tolist())
            else:
                params[f"light_{i}.to_world"] = self._shine(new)
            self._lights[i] = new

    def render_linear(self, data: mujoco.MjData, camera: int | str = 0,
                      pose: tuple[np.ndarray, np.ndarray] | None = None) -> np.ndarray:
        """(H, W, 3) float32 linear radiance (denoised when ``cfg.denoise``) after ``update``."""
        self.update(data, camera, pose)
        seed = self.cfg.seed + self._frame
        self._frame += 1
        image = self.mi.render(self._scene, spp=self.cfg.spp, seed=seed)
        if not self.cfg.denoise:
            return np.asarray(image, np.float32)
        # the guides: first-hit albedo and normal, nearly noise-free at a few samples (4 cost ~5 % of 16 path samples)
        guides = self.mi.render(self._scene, integrator=self._guide_integrator, spp=self.cfg.guide_spp, seed=seed)
        if self.variant.startswith("cuda") and _torch_has_cuda():
            # denoised on the GPU the image is on (a CPU-only torch build copies to the host instead)
            color, guides = image.torch(), guides.torch()
            return denoise_torch(color, guides[..., :3], guides[..., 3:6], quality=self.cfg.denoise_quality).cpu().numpy()
        guides = np.asarray(guides, np.float32)
        return denoise_numpy(np.asarray(image, np.float32), guides[..., :3], guides[..., 3:6],
                             quality=self.cfg.denoise_quality)

    def render(self, data: mujoco.MjData, camera: int | str = 0,
               pose: tuple[np.ndarray, np.ndarray] | None = None) -> np.ndarray:
        """(H, W, 3) uint8 sRGB image of camera ``camera`` (id or name) for the state ``data``."""
        linear = self.render_linear(data, camera, pose) * np.float32(self.cfg.exposure)
        return (linear_to_srgb(linear) * 255.0 + 0.5).astype(np.uint8)


def _texels(material: MaterialDesc) -> np.ndarray:
    """(H, W, 3) float32 linear base colour: the texture (sRGB decoded unless linear) times the
    rgba colour, or (2, 2, 3) of the colour alone (Mitsuba refuses to update a bitmap to less than 2 x 2)."""
    if material.texture is None:
        return np.full((2, 2, 3), material.base_color, np.float32)
    pixels = material.texture[..., :3].astype(np.float32) / 255.0
    if pixels.shape[-1] == 1:
        pixels = np.repeat(pixels, 3, -1)
    linear = srgb_to_linear(pixels) if material.texture_is_srgb else pixels
    return np.ascontiguousarray(linear * material.base_color, np.float32)


def _is_principled(material: MaterialDesc) -> bool:
    return material.metallic > 0 or material.specular > 0


def _kind(material: MaterialDesc) -> tuple:
    """What fixes a surface's Mitsuba objects: BSDF type, mask, emission (values changed in place otherwise)."""
    return _is_principled(material), material.opacity < 1, tuple(material.emission.tolist())


def _look_of(geom: mujoco.MjvGeom) -> tuple:
    """What a scene geom's material depends on (resolved colour, material, texture and its mapping)."""
    return (int(geom.matid), int(geom.texid), tuple(geom.rgba), tuple(geom.texrepeat), bool(geom.texuniform),
            float(geom.shininess), float(geom.specular), float(geom.reflectance), float(geom.emission))


def _torch_has_cuda() -> bool:
    try:
        import torch
    except ImportError:
        return False
    return torch.cuda.is_available()


def _to_world(positions: np.ndarray, normals: np.ndarray, pose: tuple[np.ndarray, np.ndarray]):
    pos_w, rot_w = pose
    rot = rot_w.astype(np.float32)
    return positions @ rot.T + pos_w.astype(np.float32), normals @ rot.T


def _x_fov_deg(cam: CameraDesc) -> float:
    """Mitsuba stores the horizontal field of view; the rasterizer's is fixed by fovy and aspect."""
    half_y = np.tan(np.radians(cam.fovy_deg) / 2)
    return float(np.degrees(2 * np.arctan(half_y * cam.width / cam.height)))


__all__ = ["NoPathTracerError", "PathTracer", "PathTracerCfg"]
