"""Image-based lighting for the pbr tier: an HDR environment (Isaac's ``DomeLight``
``inputs:texture:file``) as the KTX cubemap MuJoCo's Filament renderer lights with.

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


def environment_ktx(hdr_path: str | os.PathLike, cache_dir: str | os.PathLike | None = None,
                    face_px: int = FACE_PX) -> Path:
    """The KTX of HDR ``hdr_path`` in ``cache_dir`` (default ``~/.cache/ambulo/ibl``), written once
    per file content and face size (the name is their hash)."""
    data = Path(hdr_path).read_bytes()
    digest = hashlib.sha256(data + str(face_px).encode()).hexdigest()[:16]
    folder = Path(cache_dir or Path.home() / ".cache" / "ambulo" / "ibl")
    out = folder / f"{Path(hdr_path).stem}-{digest}.ktx"
    if not out.is_file():
        folder.mkdir(parents=True, exist_ok=True)
        tmp = out.with_suffix(f".{os.getpid()}.tmp")
        tmp.write_bytes(ktx_bytes(cube_faces(read_hdr(hdr_path), face_px)))
        os.replace(tmp, out)
    return out


def add_image_light(spec: mujoco.MjSpec, hdr_path: str | os.PathLike, *, name: str = "environment",
                    intensity: float = 30000.0, cache_dir: str | os.PathLike | None = None) -> mujoco.MjsLight:
    """Light ``spec``'s scene with the HDR environment ``hdr_path`` (pbr tier; the rasterizer ignores
    image lights). ``intensity`` scales the HDR's values: Filament's default 30,000 shows an
    environment of radiance 1 at about half of white with its default exposure."""
    ktx = environment_ktx(hdr_path, cache_dir)
    spec.add_texture(name=f"{name}_ktx", file=str(ktx), type=mujoco.mjtTexture.mjTEXTURE_2D)
    light = spec.worldbody.add_light(name=name, type=mujoco.mjtLightType.mjLIGHT_IMAGE, texture=f"{name}_ktx")
    light.intensity = float(intensity)
    light.castshadow = False
    return light
