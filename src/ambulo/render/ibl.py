"""Image-based lighting for the pbr and path tiers: an HDR environment (Isaac's ``DomeLight``
``inputs:texture:file``) as the KTX cubemap MuJoCo's Filament renderer lights with, stored in the
model; the path tier reads the same texels back (``image_light_radiance``), so one model lights both.

``add_image_light(spec, "sky.hdr")`` adds ``<texture file="...ktx">`` and ``<light type="image">``
to a scene. Filament reads an image light as a KTX1 cubemap whose key ``sh`` holds the
environment's irradiance as 9 spherical-harmonic coefficients per colour, pre-scaled for its
shader (``L_lm K_lm A_l / pi``, Ramamoorthi & Hanrahan 2001): the layout of the ``ibl.ktx`` that
mujoco-studio ships (Filament's ``cmgen`` output), whose own coefficients this module reproduces
from its faces to 0.3 % before cmgen's ringing window (``tests/render/test_ibl.py``).

The latitude-longitude image is read z up as the path tier reads it (Mitsuba's ``envmap`` turned
z up): column u looks along azimuth atan2(x, y) = 2 pi u, row v at polar angle pi v from +z.
Diffuse light is exact to the SH's 3 bands; glossy reflections sample box-filtered mip levels
(not GGX-prefiltered as cmgen's are): an approximation for rough metals.
"""

from __future__ import annotations

import hashlib
import os
import struct
from pathlib import Path

import mujoco
import numpy as np

FACE_PX = 64
"""Cubemap face size (texels): 64 keeps a 4k x 2k environment's lighting at ~0.2 MB of KTX."""

_CUBE_FACES = ("+x", "-x", "+y", "-y", "+z", "-z")
"""KTX1 cubemap face order (OpenGL's)."""

CUBE_TO_WORLD = np.array([[1.0, 0.0, 0.0], [0.0, 0.0, -1.0], [0.0, 1.0, 0.0]])
"""Cube-map coordinates (Filament's world: y up) -> MuJoCo's world (z up): Filament's +y is
MuJoCo's +z. Columns: where the cube's x, y, z axes point in the MuJoCo world."""

_SH_K = np.array([0.282095, 0.488603, 0.488603, 0.488603, 1.092548, 1.092548, 0.315392, 1.092548, 0.546274])
"""Real spherical-harmonic normalizations K_lm in Filament's order (l=0; l=1: y, z, x; l=2: xy, yz,
3z^2-1, xz, x^2-y^2)."""
_SH_A_OVER_PI = np.array([1.0, 2 / 3, 2 / 3, 2 / 3, 0.25, 0.25, 0.25, 0.25, 0.25])
"""The clamped-cosine (Lambertian) convolution A_l = (pi, 2 pi / 3, pi / 4) over pi, per coefficient."""

# KTX1 header words of the texel format, as Filament's cmgen writes them in the shipped ibl.ktx:
# glType, glTypeSize, glFormat, glInternalFormat, glBaseInternalFormat (GL_R11F_G11F_B10F = 0x8C3A)
_KTX_FORMAT = (0x8C3A, 1, 0x1907, 0x8C3A, 0x8C3A)
_KTX1_ID = b"\xabKTX 11\xbb\r\n\x1a\n"

FILAMENT_EXPOSURE = 1.0 / 38400.0
"""Linear image value per unit of luminance of Filament's default camera (f/16, 1/125 s, ISO 100:
1 / (1.2 * 2^EV100), EV100 = log2(16^2 * 125)). The path tier reads an image light's radiance as
texel x intensity x this, so both tiers show the same linear value (before the pbr tier's tone mapping)."""

IMAGE_LIGHT_PER_NIT = 30.0
"""Image-light intensity per nit of an Isaac DomeLight (``inputs:intensity``): Isaac's default
1000-nit dome becomes Filament's default 30,000 (a radiance-1 environment shown at 0.78 linear)."""


def read_hdr(path: str | os.PathLike) -> np.ndarray:
    """(H, W, 3) float32 linear RGB of a Radiance ``.hdr`` (or ``.exr`` where OpenCV reads it)."""
    import cv2

    image = cv2.imread(str(path), cv2.IMREAD_ANYDEPTH | cv2.IMREAD_COLOR)
    if image is None:
        raise FileNotFoundError(f"cannot read HDR environment {path!r}: give a Radiance .hdr (or .exr) file")
    return np.ascontiguousarray(image[..., ::-1], np.float32)


def face_directions(face: int, size: int) -> tuple[np.ndarray, np.ndarray]:
    """Unit directions (size, size, 3) in cube coordinates of face ``face``'s texel centres (row 0
    first, OpenGL's cube-map orientation) and each texel's exact solid angle (size, size) sr
    (the corner formula: a texel's area projected on the unit sphere)."""
    c = (np.arange(size) + 0.5) / size * 2 - 1
    s, t = np.meshgrid(c, c)
    one = np.ones_like(s)
    d = np.stack([(one, -t, -s), (-one, -t, s), (s, one, t), (s, -one, -t), (s, -t, one), (-s, -t, -one)][face], -1)
    edges = np.linspace(-1.0, 1.0, size + 1)
    x, y = np.meshgrid(edges, edges)
    corner = np.arctan2(x * y, np.sqrt(x * x + y * y + 1))
    solid_angle = corner[1:, 1:] - corner[:-1, 1:] - corner[1:, :-1] + corner[:-1, :-1]
    return d / np.linalg.norm(d, axis=-1, keepdims=True), np.abs(solid_angle)


def sample_latlong(env: np.ndarray, dirs_w: np.ndarray) -> np.ndarray:
    """Bilinear radiance (..., 3) of lat-long ``env`` along world directions ``dirs_w`` (..., 3), z up."""
    h, w = env.shape[:2]
    u = (np.arctan2(dirs_w[..., 0], dirs_w[..., 1]) / (2 * np.pi)) % 1.0
    v = np.arccos(np.clip(dirs_w[..., 2], -1.0, 1.0)) / np.pi
    x, y = u * w - 0.5, np.clip(v * h - 0.5, 0, h - 1)
    x0, y0 = np.floor(x).astype(int), np.floor(y).astype(int)
    fx, fy = (x - x0)[..., None], (y - y0)[..., None]
    x0, x1 = x0 % w, (x0 + 1) % w
    y1 = np.minimum(y0 + 1, h - 1)
    top = env[y0, x0] * (1 - fx) + env[y0, x1] * fx
    bottom = env[y1, x0] * (1 - fx) + env[y1, x1] * fx
    return top * (1 - fy) + bottom * fy


def cube_faces(env: np.ndarray, size: int = FACE_PX) -> list[np.ndarray]:
    """The six (size, size, 3) float32 faces of lat-long ``env`` in KTX order."""
    return [sample_latlong(env, face_directions(f, size)[0] @ CUBE_TO_WORLD.T).astype(np.float32)
            for f in range(len(_CUBE_FACES))]


def irradiance_sh(faces: list[np.ndarray]) -> np.ndarray:
    """(9, 3) irradiance SH of a cubemap, pre-scaled as Filament's shader reads them: the radiance's
    projection L_lm on each basis function times K_lm A_l / pi (no ringing window)."""
    size = faces[0].shape[0]
    projection = np.zeros((9, 3))
    for f, face in enumerate(faces):
        d, solid_angle = face_directions(f, size)
        x, y, z = d[..., 0], d[..., 1], d[..., 2]
        basis = np.stack([np.ones_like(x), y, z, x, x * y, y * z, 3 * z * z - 1, x * z, x * x - y * y], -1) * _SH_K
        projection += np.einsum("hwk,hwc,hw->kc", basis, face.astype(np.float64), solid_angle)
    return projection * (_SH_K * _SH_A_OVER_PI)[:, None]


def _pack_r11g11b10(rgb: np.ndarray) -> np.ndarray:
    """uint32 texels of (..., 3) non-negative floats: half floats share the 5-bit exponent and bias
    of the 11- and 10-bit floats, so each is a half with its sign dropped and mantissa cut."""
    half = np.clip(rgb, 0.0, 65000.0).astype(np.float16).view(np.uint16).astype(np.uint32)
    return ((half[..., 0] >> 4) & 0x7FF) | (((half[..., 1] >> 4) & 0x7FF) << 11) | (((half[..., 2] >> 5) & 0x3FF) << 22)


def _mips(face: np.ndarray) -> list[np.ndarray]:
    levels = [face]
    while levels[-1].shape[0] > 1:
        f = levels[-1]
        levels.append(0.25 * (f[0::2, 0::2] + f[1::2, 0::2] + f[0::2, 1::2] + f[1::2, 1::2]))
    return levels


def ktx_bytes(faces: list[np.ndarray]) -> bytes:
    """A KTX1 cubemap (R11F_G11F_B10F, full mip chain) with the irradiance SH under key ``sh``."""
    size = faces[0].shape[0]
    if size & (size - 1) or any(f.shape != (size, size, 3) for f in faces):
        raise ValueError("cube faces must be six square (N, N, 3) arrays with N a power of two")
    sh = irradiance_sh(faces)
    value = "".join(f"{r:g} {g:g} {b:g}\n" for r, g, b in sh).encode() + b"\0"
    key_value = b"sh\0" + value
    key_value = struct.pack("<I", len(key_value)) + key_value
    key_value += b"\0" * (-len(key_value) % 4)
    mips = [_mips(f) for f in faces]
    header = _KTX1_ID + struct.pack("<13I", 0x04030201, *_KTX_FORMAT, size, size, 0, 0, 6, len(mips[0]),
                                    len(key_value))
    body = []
    for level in range(len(mips[0])):
        texels = [_pack_r11g11b10(m[level]).astype("<u4").tobytes() for m in mips]
        body.append(struct.pack("<I", len(texels[0])) + b"".join(texels))
    return header + key_value + b"".join(body)


def environment_ktx(env: str | os.PathLike | np.ndarray, cache_dir: str | os.PathLike | None = None,
                    face_px: int = FACE_PX, name: str = "environment") -> Path:
    """The KTX of lat-long environment ``env`` (an HDR file, or an (H, W, 3) float linear image
    called ``name``) in ``cache_dir`` (default ``~/.cache/ambulo/ibl``), written once per content
    and face size (the file name is their hash)."""
    if isinstance(env, np.ndarray):
        image = np.ascontiguousarray(env, np.float32)
        if image.ndim != 3 or image.shape[-1] != 3:
            raise ValueError(f"an environment image is (H, W, 3) linear RGB, not {image.shape}")
        data, stem = image.tobytes() + str(image.shape).encode(), name
    else:
        image, data, stem = None, Path(env).read_bytes(), Path(env).stem
    digest = hashlib.sha256(data + str(face_px).encode()).hexdigest()[:16]
    folder = Path(cache_dir or Path.home() / ".cache" / "ambulo" / "ibl")
    out = folder / f"{stem.replace('/', '_')}-{digest}.ktx"
    if not out.is_file():
        folder.mkdir(parents=True, exist_ok=True)
        tmp = out.with_suffix(f".{os.getpid()}.tmp")
        tmp.write_bytes(ktx_bytes(cube_faces(read_hdr(env) if image is None else image, face_px)))
        os.replace(tmp, out)
    return out


def add_image_light(spec: mujoco.MjSpec, env: str | os.PathLike | np.ndarray, *, name: str = "environment",
                    intensity: float = 30000.0, cache_dir: str | os.PathLike | None = None) -> mujoco.MjsLight:
    """Light ``spec``'s scene with the lat-long environment ``env`` (an HDR file or an (H, W, 3)
    linear image), for the pbr and path tiers (the rasterizer ignores image lights). ``intensity``
    scales the values: a white Lambertian surface under a uniform environment of value T shows
    ``T * intensity * FILAMENT_EXPOSURE`` (linear), so Filament's default 30,000 shows T = 1 at 0.78."""
    ktx = environment_ktx(env, cache_dir, name=name)
    spec.add_texture(name=f"{name}_ktx", file=str(ktx), type=mujoco.mjtTexture.mjTEXTURE_2D)
    light = spec.worldbody.add_light(name=name, type=mujoco.mjtLightType.mjLIGHT_IMAGE, texture=f"{name}_ktx")
    light.intensity = float(intensity)
    light.castshadow = False
    return light


def _unpack_r11g11b10(words: np.ndarray) -> np.ndarray:
    """R11F_G11F_B10F texels -> (..., 3) float32 (unsigned floats: 5-bit exponent, bias 15)."""
    def channel(shift, mantissa_bits):
        v = (words >> shift) & ((1 << (5 + mantissa_bits)) - 1)
        e, m = (v >> mantissa_bits) & 31, v & ((1 << mantissa_bits) - 1)
        frac = m / 2.0**mantissa_bits
        return np.where(e == 0, frac * 2.0**-14, 2.0 ** (e.astype(float) - 15) * (1 + frac))
    return np.stack([channel(0, 6), channel(11, 6), channel(22, 5)], -1).astype(np.float32)


def read_ktx(blob: bytes) -> tuple[list[np.ndarray], np.ndarray | None]:
    """Level-0 faces (six (N, N, 3) float32, KTX order) and the ``sh`` coefficients (9, 3) (None
    without that key) of an R11F_G11F_B10F KTX1 cubemap: what ``ktx_bytes`` and Filament's cmgen write."""
    if blob[:12] != _KTX1_ID:
        raise ValueError("not a KTX1 file: image lights are KTX1 cubemaps (ambulo.render.ibl writes them)")
    header = struct.unpack("<13I", blob[12:64])
    if header[1:6] != _KTX_FORMAT or header[10] != 6:
        raise ValueError("only R11F_G11F_B10F KTX1 cubemaps are read (as ambulo.render.ibl and cmgen write them)")
    size, kv_bytes = header[6], header[12]
    sh, offset = None, 64
    while offset < 64 + kv_bytes:
        length = struct.unpack("<I", blob[offset:offset + 4])[0]
        key, _, value = blob[offset + 4:offset + 4 + length].partition(b"\0")
        if key == b"sh":
            sh = np.array(value.rstrip(b"\0").decode().split(), float).reshape(9, 3)
        offset += 4 + length + (-length % 4)
    offset = 64 + kv_bytes
    face_bytes = struct.unpack("<I", blob[offset:offset + 4])[0]
    offset += 4
    faces = []
    for _ in range(6):
        faces.append(_unpack_r11g11b10(np.frombuffer(blob[offset:offset + face_bytes], "<u4").reshape(size, size)))
        offset += face_bytes
    return faces, sh


def latlong_of_faces(faces: list[np.ndarray], height_px: int) -> np.ndarray:
    """The (height_px, 2 height_px, 3) lat-long image (z up, as ``sample_latlong`` reads) of cube
    ``faces``: the inverse of ``cube_faces``, bilinear within each face (edges clamped)."""
    size = faces[0].shape[0]
    theta = np.pi * (np.arange(height_px) + 0.5) / height_px
    phi = 2 * np.pi * (np.arange(2 * height_px) + 0.5) / (2 * height_px)
    t, p = np.meshgrid(theta, phi, indexing="ij")
    d_w = np.stack([np.sin(t) * np.sin(p), np.sin(t) * np.cos(p), np.cos(t)], -1)
    x, y, z = np.moveaxis(d_w @ CUBE_TO_WORLD, -1, 0)  # cube coordinates (CUBE_TO_WORLD is a rotation)
    ax, ay, az = np.abs(x), np.abs(y), np.abs(z)
    major = np.argmax(np.stack([ax, ay, az]), 0)
    face = np.where(major == 0, np.where(x > 0, 0, 1), np.where(major == 1, np.where(y > 0, 2, 3),
                                                                np.where(z > 0, 4, 5)))
    # (s, t) of face_directions' texel grid, solved for each face's major axis
    s = np.choose(face, [-z / ax, z / ax, x / ay, x / ay, x / az, -x / az])
    tc = np.choose(face, [-y / ax, -y / ax, z / ay, -z / ay, -y / az, -y / az])
    col = np.clip((s + 1) / 2 * size - 0.5, 0, size - 1)
    row = np.clip((tc + 1) / 2 * size - 0.5, 0, size - 1)
    c0, r0 = np.minimum(col.astype(int), size - 2), np.minimum(row.astype(int), size - 2)
    fc, fr = (col - c0)[..., None], (row - r0)[..., None]
    cube = np.stack(faces)
    top = cube[face, r0, c0] * (1 - fc) + cube[face, r0, c0 + 1] * fc
    bottom = cube[face, r0 + 1, c0] * (1 - fc) + cube[face, r0 + 1, c0 + 1] * fc
    return (top * (1 - fr) + bottom * fr).astype(np.float32)


def rotate_latlong(env: np.ndarray, rot_w_local: np.ndarray) -> np.ndarray:
    """Lat-long ``env`` given in a frame turned by ``rot_w_local`` (3, 3) (a rotated USD DomeLight),
    resampled in the world frame at the same size."""
    h = env.shape[0]
    theta = np.pi * (np.arange(h) + 0.5) / h
    phi = 2 * np.pi * (np.arange(2 * h) + 0.5) / (2 * h)
    t, p = np.meshgrid(theta, phi, indexing="ij")
    d_w = np.stack([np.sin(t) * np.sin(p), np.sin(t) * np.cos(p), np.cos(t)], -1)
    return sample_latlong(env, d_w @ np.asarray(rot_w_local, float)).astype(np.float32)  # d_local = R^T d_w


def image_light_radiance(model: mujoco.MjModel, light_id: int, height_px: int | None = None) -> np.ndarray:
    """(H, 2H, 3) float32 lat-long radiance of image light ``light_id`` in the tiers' units: texel x
    intensity x ``FILAMENT_EXPOSURE``, what the pbr tier shows with its default camera (before tone
    mapping). ``height_px`` defaults to twice the cube face (the texels' own resolution)."""
    tex = int(model.light_texid[light_id])
    if tex < 0:
        raise ValueError(f"image light {light_id} has no texture; give it a KTX cubemap (add_image_light)")
    adr = int(model.tex_adr[tex])
    n = int(model.tex_width[tex]) * int(model.tex_height[tex]) * int(model.tex_nchannel[tex])
    faces, _ = read_ktx(model.tex_data[adr:adr + n].tobytes())
    env = latlong_of_faces(faces, height_px or 2 * faces[0].shape[0])
    return env * np.float32(model.light_intensity[light_id] * FILAMENT_EXPOSURE)


def image_light_ids(model: mujoco.MjModel) -> list[int]:
    """The active image lights of ``model`` (MJCF ``<light type="image">``)."""
    return [i for i in range(model.nlight)
            if model.light_type[i] == mujoco.mjtLightType.mjLIGHT_IMAGE and model.light_active[i]]
