"""Image-based lighting for the pbr tier: the irradiance SH convention against the KTX that
mujoco-studio ships (Filament's cmgen), a uniform environment, the texel packing, and the
environment's orientation in a render (z up, azimuth as the path tier reads it)."""

import struct
from pathlib import Path

import cv2
import mujoco
import numpy as np
import pytest

from ambulo.render import ibl, pbr
from ambulo.render.pbr import PbrRenderer, PbrSettings, gl_camera
from ambulo.sensors.frames import look_at_gl

SHIPPED = Path(mujoco.__file__).parent / "studio" / "assets" / "ibl.ktx"


@pytest.mark.skipif(not SHIPPED.is_file(), reason="mujoco-studio's ibl.ktx is not installed")
def test_irradiance_sh_reproduces_cmgen_coefficients_of_the_shipped_environment():
    """cmgen multiplies bands 1 and 2 by a ringing window; band 0 is the plain irradiance, and within
    each band every coefficient and colour has the same ratio: same basis, order, axes and scale."""
    faces, stored = ibl.read_ktx(SHIPPED.read_bytes())
    ours = ibl.irradiance_sh(faces)
    ratio = stored / ours
    assert np.allclose(ratio[0], 1.0, rtol=5e-3)
    for band in (slice(1, 4), slice(4, 9)):
        assert np.ptp(ratio[band]) < 0.015 * ratio[band].mean(), ratio[band]
        assert 0.8 < ratio[band].mean() <= 1.0  # a window only attenuates


def test_a_uniform_environment_has_only_the_constant_coefficient():
    radiance = np.array([0.5, 1.0, 2.0])
    faces = ibl.cube_faces(np.broadcast_to(radiance, (16, 32, 3)).astype(np.float32), 16)
    sh = ibl.irradiance_sh(faces)
    assert np.allclose(sh[0], radiance, rtol=1e-3)  # irradiance / pi of a uniform sky is its radiance
    assert np.abs(sh[1:]).max() < 1e-3


def test_texel_packing_round_trips_within_the_format_precision():
    values = np.array([[0.0, 0.0, 0.0], [1.0, 0.5, 0.25], [123.4, 0.01, 7.7], [60000.0, 3e-3, 1e-4]])
    back = ibl._unpack_r11g11b10(ibl._pack_r11g11b10(values))
    assert np.all(np.abs(back - values) <= values * 2.0**-5 + 1e-4)  # 6/5-bit mantissas, truncated


def test_ktx_header_and_levels_match_the_shipped_layout(tmp_path):
    faces = ibl.cube_faces(np.ones((8, 16, 3), np.float32), 8)
    blob = ibl.ktx_bytes(faces)
    header = struct.unpack("<13I", blob[12:64])
    assert blob[:12] == ibl._KTX1_ID and header[6:12] == (8, 8, 0, 0, 6, 4)  # 8, 4, 2, 1 px levels
    if SHIPPED.is_file():
        assert header[1:6] == struct.unpack("<13I", SHIPPED.read_bytes()[12:64])[1:6]
    read_faces, sh = ibl.read_ktx(blob)
    assert np.allclose(read_faces[0], 1.0, rtol=2**-5) and np.allclose(sh[0], 1.0, rtol=1e-3)


@pytest.mark.skipif(pbr._vulkan_problem() is not None, reason=f"no Vulkan here: {pbr._vulkan_problem()}")
@pytest.mark.parametrize(("bright", "lit_side"), [("zenith", "top"), ("east", "right")])
def test_the_environment_lights_the_side_it_shines_from(tmp_path, bright, lit_side):
    """A white sphere under a dark sky with one bright region, seen from -y: the bright zenith
    lights its top, a bright band at azimuth +x (u = 0.25) its right side."""
    h, w = 64, 128
    env = np.full((h, w, 3), 0.05, np.float32)
    v, u = (np.arange(h) + 0.5) / h, (np.arange(w) + 0.5) / w
    if bright == "zenith":
        env[v < 0.25] = 1.0
    else:
        env[:, np.abs(u - 0.25) < 0.08] = 1.0
    path = tmp_path / "sky.hdr"
    assert cv2.imwrite(str(path), env[..., ::-1].copy())
    spec = mujoco.MjSpec()
    spec.visual.headlight.active = 0
    spec.worldbody.add_geom(type=mujoco.mjtGeom.mjGEOM_SPHERE, size=[0.5, 0, 0], rgba=[1, 1, 1, 1])
    ibl.add_image_light(spec, path, cache_dir=tmp_path / "cache")
    model = spec.compile()
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    eye = np.array([0.0, -3.0, 0.0])
    cam = gl_camera(eye, look_at_gl(eye, np.zeros(3)), 40.0, 64, 64, (0.05, 20.0))
    image = PbrRenderer(model, 64, 64, PbrSettings(post_processing=False, skybox=False)).render(data, cam)
    sides = {"top": image[20, 32, 0], "bottom": image[44, 32, 0], "left": image[32, 20, 0], "right": image[32, 44, 0]}
    opposite = {"top": "bottom", "right": "left"}[lit_side]
    assert int(sides[lit_side]) > 2 * int(sides[opposite]) + 5, sides


def test_cube_faces_back_to_latlong_is_the_same_environment():
    """What the path tier reads from an image light's KTX: a smooth sky varying with azimuth and
    elevation (each axis direction a different colour) survives lat-long -> cube -> lat-long."""
    h = 32
    theta = np.pi * (np.arange(h) + 0.5) / h
    phi = 2 * np.pi * (np.arange(2 * h) + 0.5) / (2 * h)
    t, p = np.meshgrid(theta, phi, indexing="ij")
    x, y, z = np.sin(t) * np.sin(p), np.sin(t) * np.cos(p), np.cos(t)
    env = np.stack([1.5 + x, 1.5 + y, 1.5 + z], -1).astype(np.float32)
    back = ibl.latlong_of_faces(ibl.cube_faces(env, 32), h)  # float faces: the mapping, not the 6-bit packing
    assert np.abs(back - env).max() < 0.03 and np.abs(back - env).mean() < 0.003
