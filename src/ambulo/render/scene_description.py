"""One description of what a MuJoCo camera sees, for renderers other than MuJoCo's rasterizer.

Everything is read from the ``MjvScene`` that ``mjv_updateScene`` fills for the rasterizer, so the
geoms drawn, their resolved colours (geom rgba over material rgba), the lights (headlight
included) and the camera frustum are the rasterizer's own, not a second reading of the model:

- surfaces: each visible geom as triangles in its frame (``tessellate``) and its pose in the world;
  geoms welded to the world are ``static`` (a renderer may bake them once).
- materials: MJCF rgba / 2-D texture -> base colour; ``roughness`` and ``metallic`` when the
  material sets them (MuJoCo >= 3.3), else roughness from the Phong ``shininess`` and metallic from
  ``reflectance``; MJCF ``specular`` is kept (0.5, MuJoCo's default, is Disney's 4 % dielectric).
- lights: MuJoCo's lights carry a colour that the rasterizer adds as ``diffuse * rgba * cos``
  without falloff; physical intensities are chosen so a Lambertian surface reads the same there
  (directional: irradiance ``pi * diffuse``; point/spot: radiance matched where the light points,
  see ``light_intensity``). ``ambient`` light becomes a constant environment.
- camera: vertical field of view, clip distances and pose of the rasterizer's camera.

Colours are linear RGB (MJCF colours are authored as display sRGB and converted); radiance is in
the units where a white Lambertian surface under ``diffuse = 1`` at normal incidence reads 1.
"""

from __future__ import annotations

from dataclasses import dataclass

import mujoco
import numpy as np

from .tessellate import TriangleMesh, geom_mesh

_CATMASK = int(mujoco.mjtCatBit.mjCAT_STATIC) | int(mujoco.mjtCatBit.mjCAT_DYNAMIC)
_GEOM = int(mujoco.mjtObj.mjOBJ_GEOM)
_LIGHT = mujoco.mjtLightType


def srgb_to_linear(c: np.ndarray) -> np.ndarray:
    """IEC 61966-2-1 sRGB decoding of values in [0, 1]."""
    c = np.asarray(c, np.float32)
    return np.where(c <= 0.04045, c / 12.92, ((c + 0.055) / 1.055) ** 2.4).astype(np.float32)


def linear_to_srgb(c: np.ndarray) -> np.ndarray:
    """IEC 61966-2-1 sRGB encoding; input clipped to [0, 1]."""
    c = np.clip(np.asarray(c, np.float32), 0.0, 1.0)
    return np.where(c <= 0.0031308, 12.92 * c, 1.055 * np.power(c, 1 / 2.4) - 0.055).astype(np.float32)


@dataclass
class MaterialDesc:
    """Physically based parameters of one geom's surface."""

    base_color: np.ndarray
    """(3,) float32 linear RGB albedo (multiplies ``texture`` when there is one)."""
    opacity: float
    """rgba alpha in (0, 1]."""
    roughness: float
    """Disney roughness in [0, 1] (GGX alpha = roughness^2)."""
    metallic: float
    specular: float
    """Disney specular: 0.5 is a 4 % dielectric reflectance at normal incidence."""
    emission: np.ndarray
    """(3,) float32 linear emitted radiance (MJCF ``emission * rgba``)."""
    texture: np.ndarray | None = None
    """(H, W, C) uint8 2-D texture, top row first, or None."""
    texture_is_srgb: bool = True
    tint: np.ndarray | None = None
    """(3,) float32 factor of ``base_color`` beyond the rgba (a cube map's mean colour), or None."""


@dataclass
class SurfaceDesc:
    """A visible geom: its triangles (geom frame) and what it is made of."""

    geom_id: int
    mesh: TriangleMesh
    """Triangles in the geom frame, with ``texcoords`` (planar unless the mesh has its own)."""
    material: MaterialDesc
    static: bool
    """Welded to the world: its pose never changes."""
    planar_uv: bool = True
    """``mesh.texcoords`` are ``primitive_texcoords`` (they follow the material's texrepeat), not the mesh's own."""


@dataclass
class LightDesc:
    kind: str
    """"point", "spot" or "directional"."""
    pos_w: np.ndarray
    """(3,) m, world."""
    dir_w: np.ndarray
    """(3,) unit direction the light shines along, world."""
    intensity: np.ndarray
    """(3,) linear RGB: radiant intensity (W/sr) for point/spot, irradiance (W/m^2) for directional."""
    cutoff_deg: float = 180.0
    """Spot: half-angle of the cone."""
    beam_deg: float = 180.0
    """Spot: half-angle of full intensity (where MuJoCo's cos^exponent falls to a half)."""
    headlight: bool = False


@dataclass
class CameraDesc:
    """A pinhole camera identical to the rasterizer's for an image of ``width`` x ``height``."""

    pos_w: np.ndarray
    """(3,) m, world."""
    rot_w_gl: np.ndarray
    """(3, 3): columns are the OpenGL camera axes (x right, y up, looking along -z) in the world."""
    fovy_deg: float
    """Vertical field of view of the image."""
    near_m: float
    far_m: float
    width: int
    height: int


def roughness_from_shininess(shininess: float) -> float:
    """Disney roughness of MuJoCo's Phong ``shininess`` (exponent ``128 * shininess``).

    Walter et al. 2007 (Microfacet models for refraction, sec. 5.2): a Phong exponent n matches a
    Beckmann/GGX width alpha = sqrt(2 / (n + 2)); Disney roughness is sqrt(alpha).
    """
    alpha = np.sqrt(2.0 / (128.0 * float(shininess) + 2.0))
    return float(np.sqrt(alpha))


def _texture(model: mujoco.MjModel, tex_id: int) -> tuple[np.ndarray, bool]:
    """(H, W, C) uint8 texels of colour texture ``tex_id`` and whether to decode them as sRGB: always.

    MuJoCo's rasterizer shows ``auto`` and ``linear`` texels as they are, display values like MJCF
    rgba (a PNG file without an sRGB chunk compiles to ``linear``: read as linear albedo it came
    out far paler than the rasterizer shows it, blue (30, 60, 230) lit to (63, 96, 154) beside its
    (18, 42, 118)). ``sRGB`` texels it decodes and does not encode again, so they look darker there
    than in the pbr and path tiers, which decode them once (the physical reading)."""
    h, w, c = int(model.tex_height[tex_id]), int(model.tex_width[tex_id]), int(model.tex_nchannel[tex_id])
    adr = int(model.tex_adr[tex_id])
    pixels = model.tex_data[adr:adr + h * w * c].reshape(h, w, c)
    return pixels, True


def base_color_of(geom: mujoco.MjvGeom, tint: np.ndarray | None = None) -> np.ndarray:
    """(3,) float32 linear albedo of a scene geom's resolved rgba (times ``tint``)."""
    base = srgb_to_linear(np.asarray(geom.rgba[:3]))
    return base if tint is None else (base * tint).astype(np.float32)


def material_of(model: mujoco.MjModel, geom: mujoco.MjvGeom) -> MaterialDesc:
    """The PBR material of a scene geom (its rgba/emission/specular are already resolved)."""
    rgba = np.asarray(geom.rgba, np.float32)
    mat = int(geom.matid)
    roughness = roughness_from_shininess(geom.shininess)
    metallic = float(geom.reflectance)
    if mat >= 0 and model.mat_roughness[mat] >= 0:
        roughness = float(model.mat_roughness[mat])
    if mat >= 0 and model.mat_metallic[mat] >= 0:
        metallic = float(model.mat_metallic[mat])
    texture, srgb, tint = None, True, None
    tex_id = int(geom.texid)
    if tex_id >= 0:
        pixels, srgb = _texture(model, tex_id)
        if int(model.tex_type[tex_id]) == int(mujoco.mjtTexture.mjTEXTURE_2D):
            texture = pixels
        else:
            # cube maps on objects: their mean colour (each face's mapping is not reproduced)
            mean = pixels[..., :3].reshape(-1, pixels.shape[-1] if pixels.shape[-1] < 3 else 3).mean(0) / 255.0
            tint = srgb_to_linear(mean) if srgb else mean.astype(np.float32)
    return MaterialDesc(base_color=base_color_of(geom, tint), opacity=float(rgba[3]), roughness=float(np.clip(roughness, 0, 1)),
                        metallic=float(np.clip(metallic, 0, 1)), specular=float(np.clip(geom.specular, 0, 1)),
                        emission=(float(geom.emission) * srgb_to_linear(rgba[:3])).astype(np.float32),
                        texture=texture, texture_is_srgb=srgb, tint=tint)


def planar_texcoords(mesh: TriangleMesh, geom: mujoco.MjvGeom) -> np.ndarray:
    """MuJoCo 4's 2-D texture mapping of geoms without UVs, as UVs: planar in two geom axes (a, b).

    u = 0.5 * k_a * (size_a + a), v = 0.5 * k_b * (size_b - b) (texture rows), with k = repeat / size_a:
    the texture starts at the face's (-a, +b) corner and repeats ``repeat`` times across it;
    ``texuniform``: k_a = repeat_u * size_x / size_a, k_b = repeat_v * size_y / size_b (``repeat``
    per metre on a plane or a box's top). (a, b) is (x, y), except on a box's faces, each mapped in
    its own plane: (y, z) on the +-x faces, (x, z) on the +-y faces (the same way on both faces of a
    pair). An infinite plane (size 0): u = 0.5 + 0.5 * repeat * x, v = 0.5 - 0.5 * repeat * y.
    Measured on MuJoCo 4's rasterizer (a texture whose texels encode their own (column, row),
    drawn unlit: ``test_path_look`` checks planes and every face of a box, both texuniform modes);
    render_gl3.c's older object-linear planes differ. Explicit mesh UVs are passed as they are (not
    checked against the rasterizer).
    """
    positions = mesh.positions
    n = len(positions)
    a, b = np.zeros(n, np.intp), np.ones(n, np.intp)
    if geom.type == mujoco.mjtGeom.mjGEOM_BOX:  # flat faces: the normal's axis picks the plane
        axis = np.argmax(np.abs(mesh.normals), 1)
        a, b = np.where(axis == 0, 1, 0), np.where(axis == 2, 1, 2)
    size = np.asarray(geom.size, np.float32)
    repeat = np.asarray(geom.texrepeat, np.float32)
    rows = np.arange(n)
    coords = []
    for j, (axes, sign) in enumerate(((a, 1.0), (b, -1.0))):  # v runs against its axis (texture rows)
        half = size[axes]
        # repeats across a face: ``repeat``, or with texuniform ``repeat`` per metre of the geom's
        # own x (u) or y (v) size, whichever face it is (the rasterizer's rule, measured on boxes)
        span = repeat[j] * size[j] if geom.texuniform and size[j] > 0 else repeat[j]
        k = np.where(half > 0, span / np.maximum(half, 1e-9), repeat[j])
        start = np.where(half > 0, 0.5 * k * half, 0.5)  # an infinite plane: texture centred on the origin
        coords.append(start + 0.5 * k * sign * positions[rows, axes])
    return np.stack(coords, 1).astype(np.float32)


def primitive_texcoords(mesh: TriangleMesh, geom: mujoco.MjvGeom) -> np.ndarray:
    """(V, 2) float32 UVs of a primitive geom where MuJoCo 4's rasterizer puts its 2-D texture:
    ``mesh.surface_uv`` (spheres, ellipsoids, cylinders, capsules; measured, see ``TriangleMesh``)
    times ``texrepeat`` (with ``texuniform``, times the geom's size too: ``repeat_u * size_x``,
    ``repeat_v * size_y``, the rule ``planar_texcoords`` follows), else ``planar_texcoords``."""
    if mesh.surface_uv is None:
        return planar_texcoords(mesh, geom)
    span = np.asarray(geom.texrepeat, np.float32)
    if geom.texuniform:
        span = span * np.asarray(geom.size, np.float32)[:2]
    return (mesh.surface_uv * span).astype(np.float32)


def surface_of(model: mujoco.MjModel, geom: mujoco.MjvGeom, infinite_half_m: float,
               slices: int = 32, stacks: int = 16) -> SurfaceDesc | None:
    """The surface of a scene geom, or None when it is not a model geom drawn as triangles."""
    if geom.objtype != _GEOM or geom.rgba[3] <= 0:
        return None
    gid = int(geom.objid)
    # model.geom_size, not MjvGeom.size (which reads (r, r, half-length) for capsules and cylinders)
    mesh = geom_mesh(model, int(geom.type), model.geom_size[gid], int(model.geom_dataid[gid]),
                     infinite_half_m=infinite_half_m, slices=slices, stacks=stacks)
    if mesh is None:
        return None
    material = material_of(model, geom)
    # every surface gets UVs, textured or not: a material randomizer may give it a texture later
    planar = mesh.texcoords is None or not geom.texcoord
    if planar:
        mesh.texcoords = primitive_texcoords(mesh, geom)
    body = int(model.geom_bodyid[gid])
    static = int(model.body_weldid[body]) == 0 and int(model.body_mocapid[body]) < 0
    return SurfaceDesc(geom_id=gid, mesh=mesh, material=material, static=static, planar_uv=planar)


def geom_pose(geom: mujoco.MjvGeom) -> tuple[np.ndarray, np.ndarray]:
    """(3,) position (m) and (3, 3) rotation of a scene geom's frame in the world."""
    return np.asarray(geom.pos, np.float64), np.asarray(geom.mat, np.float64).reshape(3, 3)


def light_intensity(light: mujoco.MjvLight, reference_m: float, attenuation=(1.0, 0.0, 0.0)) -> np.ndarray:
    """Physical intensity (see ``LightDesc.intensity``) of a MuJoCo light, linear RGB.

    MJCF ``intensity`` > 0 is taken as the physical value itself (W/sr, or W/m^2 for a
    directional light) tinted by the diffuse colour. Otherwise the rasterizer's look: it adds
    ``diffuse / (c + l r + q r^2)`` (MJCF ``attenuation`` = c, l, q) times ``rgba * cos``, and a
    Lambertian surface under intensity I at distance r reads ``albedo I cos / (pi r^2)``, so
    ``I = pi diffuse r^2 / (c + l r + q r^2)`` matches it at ``r = reference_m`` (where the light
    points). A directional light matches everywhere with irradiance ``pi diffuse``.
    """
    diffuse = srgb_to_linear(np.clip(light.diffuse, 0, 1))
    if light.intensity > 0:
        return (float(light.intensity) * diffuse / max(float(diffuse.max()), 1e-9)).astype(np.float32)
    if light.type == _LIGHT.mjLIGHT_DIRECTIONAL:
        return (np.pi * diffuse).astype(np.float32)
    c, lin, q = (float(a) for a in attenuation)
    r = float(reference_m)
    return (np.pi * diffuse * r * r / max(c + lin * r + q * r * r, 1e-9)).astype(np.float32)


def lights_of(model: mujoco.MjModel, data: mujoco.MjData, scene: mujoco.MjvScene) -> list[LightDesc]:
    """The scene's lights (headlight included) with physical intensities; image lights are not
    among them (they are the environment: ``ibl.image_light_radiance``)."""
    out = []
    for light in scene.lights[: scene.nlight]:
        if light.type == _LIGHT.mjLIGHT_IMAGE:
            continue
        pos, direction = np.asarray(light.pos, float), np.asarray(light.dir, float)
        direction = direction / max(np.linalg.norm(direction), 1e-12)
        if light.type == _LIGHT.mjLIGHT_DIRECTIONAL or light.headlight:
            kind, reference = "directional", 1.0
        else:
            kind = "spot" if light.type == _LIGHT.mjLIGHT_SPOT else "point"
            hit = mujoco.mj_ray(model, data, pos, direction, None, 1, -1, np.zeros(1, np.int32))
            reference = hit if hit > 0 else float(model.stat.extent)
        # the model's attenuation: MjvLight.attenuation reads zeros in MuJoCo 4.0
        attenuation = model.light_attenuation[light.id] if light.id >= 0 and not light.headlight else (1.0, 0.0, 0.0)
        desc = LightDesc(kind=kind, pos_w=pos, dir_w=direction, headlight=bool(light.headlight),
                         intensity=light_intensity(light, reference, attenuation))
        if kind == "spot":
            desc.cutoff_deg = float(light.cutoff)
            exponent = max(float(light.exponent), 1e-3)
            desc.beam_deg = min(desc.cutoff_deg, float(np.degrees(np.arccos(0.5 ** (1.0 / exponent)))))
        out.append(desc)
    return out


def ambient_radiance(scene: mujoco.MjvScene) -> np.ndarray:
    """(3,) linear radiance of a constant environment standing in for the lights' ``ambient``.

    The rasterizer adds ``ambient * rgba`` everywhere; a constant environment of radiance L lights
    an unoccluded Lambertian surface to ``albedo L`` (and occluded corners less).
    """
    total = np.zeros(3, np.float32)
    for light in scene.lights[: scene.nlight]:
        total += np.asarray(light.ambient, np.float32)
    return srgb_to_linear(np.clip(total, 0, 1))


def skybox_latlong(model: mujoco.MjModel, height_px: int = 128) -> np.ndarray | None:
    """The model's skybox as a (height_px, 2 height_px, 3) float32 linear latitude-longitude image.

    Row 0 is the zenith (world +z), column u at azimuth phi = 2 pi (u + 0.5) / width from +y
    towards +x: pixel (u, v) looks along (sin t sin phi, sin t cos phi, cos t), t = pi (v + 0.5) /
    height. The rasterizer draws the skybox as a cube map looked up along (x, z, -y) for a world
    direction (x, y, z) (render_gl3.c, "rotate 90 deg around X"), faces stored +x, -x, +y, -y, +z, -z
    with OpenGL's per-face (s, t) axes. None when the model has no skybox.
    """
    ids = np.nonzero(model.tex_type == int(mujoco.mjtTexture.mjTEXTURE_SKYBOX))[0]
    if len(ids) == 0:
        return None
    pixels, srgb = _texture(model, int(ids[0]))
    face_px = pixels.shape[1]
    faces = pixels.reshape(-1, face_px, face_px, pixels.shape[-1])
    if len(faces) != 6:  # a single-image skybox repeated on every face (MuJoCo's default layout)
        faces = np.repeat(faces[:1], 6, 0)
    theta = np.pi * (np.arange(height_px) + 0.5) / height_px
    phi = 2 * np.pi * (np.arange(2 * height_px) + 0.5) / (2 * height_px)
    t, p = np.meshgrid(theta, phi, indexing="ij")
    x, y, z = np.sin(t) * np.sin(p), np.sin(t) * np.cos(p), np.cos(t)
    gx, gy, gz = x, z, -y  # the GL lookup direction
    ax, ay, az = np.abs(gx), np.abs(gy), np.abs(gz)
    major = np.argmax(np.stack([ax, ay, az]), 0)
    # OpenGL 4.6 table 8.19: face, sc, tc and the major axis magnitude per selected axis and sign
    face = np.where(major == 0, np.where(gx > 0, 0, 1), np.where(major == 1, np.where(gy > 0, 2, 3),
                                                                  np.where(gz > 0, 4, 5)))
    sc = np.choose(face, [-gz, gz, gx, gx, gx, -gx])
    tc = np.choose(face, [-gy, -gy, gz, -gz, -gy, -gy])
    ma = np.choose(major, [ax, ay, az])
    s_px = np.clip(((sc / ma + 1) / 2 * face_px).astype(int), 0, face_px - 1)
    t_px = np.clip(((tc / ma + 1) / 2 * face_px).astype(int), 0, face_px - 1)
    rgb = faces[face, t_px, s_px][..., :3].astype(np.float32) / 255.0
    if rgb.shape[-1] == 1:
        rgb = np.repeat(rgb, 3, -1)
    return srgb_to_linear(rgb) if srgb else rgb


def camera_of(scene: mujoco.MjvScene, width: int, height: int) -> CameraDesc:
    """The camera ``mjr_render`` draws a mono image with: the average of the scene's two eyes."""
    cam = mujoco.mjv_averageCamera(scene.camera[0], scene.camera[1])
    if cam.orthographic:
        raise NotImplementedError("orthographic cameras are rasterizer-only; use a perspective camera (fovy)")
    top, bottom, near = float(cam.frustum_top), float(cam.frustum_bottom), float(cam.frustum_near)
    half_w = float(cam.frustum_width) or 0.5 * (top - bottom) * width / height
    off_axis = abs(top + bottom) > 1e-6 * (top - bottom) or abs(float(cam.frustum_center)) > 1e-6 * half_w
    non_square = abs(2 * half_w / width - (top - bottom) / height) > 1e-4 * (top - bottom) / height
    if off_axis or non_square:
        raise NotImplementedError("cameras with an off-centre principal point or non-square pixels "
                                  "(MJCF focal/principal/sensorsize) are rasterizer-only; use fovy")
    forward, up = np.asarray(cam.forward, float), np.asarray(cam.up, float)
    right = np.cross(forward, up)
    rot = np.stack([right, up, -forward], 1)
    return CameraDesc(pos_w=np.asarray(cam.pos, float), rot_w_gl=rot,
                      fovy_deg=float(np.degrees(2 * np.arctan(0.5 * (top - bottom) / near))),
                      near_m=near, far_m=float(cam.frustum_far), width=int(width), height=int(height))


class SceneReader:
    """Fills an ``MjvScene`` the way ``OffscreenRenderer`` does (same geoms, lights and camera).

    ``read`` runs ``mjv_updateScene`` from fixed camera ``cam_id`` (-1: the free camera); a pose ``(pos_w, rot_w_gl)``
    replaces the model camera's, and the headlight follows it as in the rasterizer.
    """

    def __init__(self, model: mujoco.MjModel, max_geom: int = 4000):
        self.scene = mujoco.MjvScene(model, maxgeom=max_geom)
        self._option = mujoco.MjvOption()
        self._option.sitegroup[:] = 0  # as OffscreenRenderer: sites are mounts, not scenery
        self._camera = mujoco.MjvCamera()
        self._camera.type = mujoco.mjtCamera.mjCAMERA_FIXED

    def read(self, model: mujoco.MjModel, data: mujoco.MjData, cam_id: int,
             pose: tuple[np.ndarray, np.ndarray] | None = None) -> mujoco.MjvScene:
        self._camera.type = mujoco.mjtCamera.mjCAMERA_FIXED if cam_id >= 0 else mujoco.mjtCamera.mjCAMERA_FREE
        self._camera.fixedcamid = int(cam_id)
        mujoco.mjv_updateScene(model, data, self._option, None, self._camera, _CATMASK, self.scene)
        if pose is not None:
            pos_w, rot_w_gl = (np.asarray(a, float) for a in pose)
            forward = -rot_w_gl[:, 2]
            for glcam in self.scene.camera:
                glcam.pos[:] = pos_w
                glcam.forward[:] = forward
                glcam.up[:] = rot_w_gl[:, 1]
            for light in self.scene.lights[: self.scene.nlight]:
                if light.headlight:
                    light.pos[:] = pos_w
                    light.dir[:] = forward
        return self.scene


def infinite_plane_half_m(model: mujoco.MjModel) -> float:
    """Half extent of a size-0 plane: out to MuJoCo's far clip distance (``zfar * extent``)."""
    return float(model.vis.map.zfar * model.stat.extent)


__all__ = ["CameraDesc", "LightDesc", "MaterialDesc", "SceneReader", "SurfaceDesc", "ambient_radiance", "base_color_of",
           "camera_of", "geom_pose", "infinite_plane_half_m", "light_intensity", "lights_of", "linear_to_srgb",
           "material_of", "planar_texcoords", "primitive_texcoords", "roughness_from_shininess", "skybox_latlong", "srgb_to_linear", "surface_of"]
