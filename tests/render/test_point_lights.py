"""Point lights light the rasterizer's frames (MuJoCo 4.0's GL renderer left them dark), with the
fall-off of a point light: ``diffuse * cos(incidence) / (a0 + a1 d + a2 d^2)``; scenes without point
lights render byte for byte as before."""

from __future__ import annotations

import math

import mujoco
import numpy as np
import pytest

from ambulo.render import offscreen
from ambulo.render.offscreen import OffscreenRenderer
from ambulo.render.point_lights import light_point_lights

SIZE_PX = 64
CAM_HEIGHT_M = 3.0
LAMP_HEIGHT_M = 1.0
DIFFUSE = 0.6

# A white plane seen straight down (fovy 90 deg) by a camera over the lamp; no headlight, no ambient.
XML = """<mujoco>
  <visual><headlight active="0" ambient="0 0 0" diffuse="0 0 0" specular="0 0 0"/></visual>
  <worldbody>
    <geom type="plane" size="10 10 0.1" rgba="1 1 1 1"/>
    {lights}
    <camera name="top" pos="0 0 {cam}" xyaxes="1 0 0 0 1 0" fovy="90"/>
  </worldbody>
</mujoco>"""
LAMP = (f'<light type="point" pos="0 0 {LAMP_HEIGHT_M}" dir="{{dir}}" diffuse="{DIFFUSE} {DIFFUSE} {DIFFUSE}" '
        'specular="0 0 0" castshadow="false" attenuation="{att}"/>')
SUN = '<light type="directional" dir="0.3 0.2 -1" diffuse="0.5 0.5 0.5" specular="0.1 0.1 0.1" ambient="0.2 0.2 0.2"/>'


def _model(lights: str) -> tuple[mujoco.MjModel, mujoco.MjData]:
    model = mujoco.MjModel.from_xml_string(XML.format(lights=lights, cam=CAM_HEIGHT_M))
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    return model, data


def _render(model, data, view: bool = False) -> np.ndarray:
    """(H, W) float red channel of the top camera's rgb, 0..255."""
    with OffscreenRenderer(model, SIZE_PX, SIZE_PX) as renderer:
        if view:  # the viewer's path
            camera = mujoco.MjvCamera()
            camera.type, camera.fixedcamid = mujoco.mjtCamera.mjCAMERA_FIXED, 0
            renderer.update_view(model, data, camera)
        else:
            renderer.update(model, data, 0, np.array([0.0, 0.0, CAM_HEIGHT_M]), np.eye(3))
        return renderer.render_rgb()[..., 0].astype(np.float64)


def _expected(attenuation: tuple[float, float, float]) -> np.ndarray:
    """(H, W) the point light's diffuse term on the plane at each pixel centre, 0..255."""
    half = math.tan(math.radians(45.0)) * CAM_HEIGHT_M  # half the ground width seen, m
    coords = ((np.arange(SIZE_PX) + 0.5) / SIZE_PX * 2.0 - 1.0) * half
    x_m, y_m = np.meshgrid(coords, coords[::-1])  # image rows top first: +y at the top
    dist_m = np.sqrt(x_m**2 + y_m**2 + LAMP_HEIGHT_M**2)
    cos_incidence = LAMP_HEIGHT_M / dist_m
    a0, a1, a2 = attenuation
    return 255.0 * DIFFUSE * cos_incidence / (a0 + a1 * dist_m + a2 * dist_m**2)


@pytest.mark.parametrize("attenuation", [(1.0, 0.0, 0.0), (1.0, 1.0, 0.0), (0.0, 0.0, 1.0)])
def test_point_light_lights_a_plane_with_its_attenuation(attenuation):
    model, data = _model(LAMP.format(dir="0 0 -1", att=" ".join(map(str, attenuation))))
    image = _render(model, data)
    assert image.mean() > 15.0  # before the fix: 0 or one flat shade
    centre = image[SIZE_PX // 2 - 1: SIZE_PX // 2 + 1, SIZE_PX // 2 - 1: SIZE_PX // 2 + 1]
    assert centre.min() >= image.max() - 1.0  # brightest under the lamp
    # fall-off symmetric about the lamp: the plane is the same seen mirrored (up to a level or
    # three where 1/d^2 is steep: pixel centres sit half a pixel off the axis)
    assert np.abs(image - image[:, ::-1]).max() <= 5.0
    assert np.abs(image - image[::-1, :]).max() <= 5.0
    assert np.abs(image - image.T).max() <= 5.0
    # and it is a point light's: cos(incidence) over the attenuation polynomial (8-bit, per-vertex error)
    expected = _expected(attenuation)
    assert np.abs(image - expected).max() <= 5.0
    assert image[SIZE_PX // 2, 2] < 0.5 * image[SIZE_PX // 2, SIZE_PX // 2]  # it does fall off


def test_point_light_shines_every_way_on_the_viewer_path_too():
    # a point light has no direction: pointed up, away from the plane, it lights it the same
    model, data = _model(LAMP.format(dir="0 0 1", att="1 0 0"))
    image = _render(model, data, view=True)
    assert np.abs(image - _expected((1.0, 0.0, 0.0))).max() <= 5.0


def test_scene_without_point_lights_renders_byte_identically(monkeypatch):
    spot = ('<light type="spot" pos="0.5 0 1" dir="0 0 -1" cutoff="40" exponent="5" '
            'diffuse="0.4 0.4 0.4" attenuation="1 0.5 0"/>')
    for lights in (SUN, SUN + spot):
        model, data = _model(lights)
        fixed = _render(model, data)
        monkeypatch.setattr(offscreen, "light_point_lights", lambda model, scene: 0)
        before = _render(model, data)
        monkeypatch.undo()
        assert fixed.mean() > 20.0
        np.testing.assert_array_equal(fixed, before)


def test_only_point_lights_are_changed_and_spots_keep_theirs():
    model, data = _model(SUN + LAMP.format(dir="0 0 -1", att="1 0.2 0.1"))
    scene = mujoco.MjvScene(model, maxgeom=100)
    camera = mujoco.MjvCamera()
    mujoco.mjv_updateScene(model, data, mujoco.MjvOption(), None, camera, mujoco.mjtCatBit.mjCAT_ALL, scene)
    sun_before = scene.lights[0].type, scene.lights[0].dir.copy()
    assert light_point_lights(model, scene) == 1
    sun, lamp = scene.lights[0], scene.lights[1]
    assert (sun.type, *sun.dir) == (sun_before[0], *sun_before[1])
    assert lamp.type == mujoco.mjtLightType.mjLIGHT_SPOT
    assert (lamp.cutoff, lamp.exponent) == (180.0, 0.0)
    np.testing.assert_allclose(lamp.attenuation, [1.0, 0.2, 0.1], rtol=1e-6)
