"""The path tracer's scene description: the rasterizer's look, environment maps, per-frame colours.

- a Lambertian plane under a MuJoCo light (no physical ``intensity`` given) reads what the
  rasterizer draws there: within 2 grey levels everywhere under a directional light, within 5
  where a spot light points (``scene_description.light_intensity``);
- an HDR environment map is z up (Isaac's DomeLight convention after the y-up -> z-up turn), and
  the model's skybox is the one the rasterizer draws (its random marks in the same places);
- a colour written into the model after the tracer was built shows in the next frame (the
  replicator's colour randomizer), without a rebuild.
"""

from __future__ import annotations

import mujoco
import numpy as np
import pytest

from ambulo.render.path import PathTracer, PathTracerCfg, _mitsuba
from ambulo.render.scene_description import roughness_from_shininess

pytestmark = pytest.mark.usefixtures("needs_mitsuba")  # tests/render/conftest.py


def _cfg(**kw) -> PathTracerCfg:
    return PathTracerCfg(variant="llvm_ad_rgb", denoise=False, **kw)


_MATTE = '<asset><material name="matte" specular="0" shininess="0"/></asset>'
_DARK = '<visual><headlight active="0" ambient="0 0 0" diffuse="0 0 0"/><global offwidth="64" offheight="48"/></visual>'


def _raster(model, data, cam_id, width, height):
    from ambulo.render import OffscreenRenderer

    with OffscreenRenderer(model, width, height) as renderer:
        renderer.update(model, data, cam_id, data.cam_xpos[cam_id], data.cam_xmat[cam_id].reshape(3, 3))
        return renderer.render_rgb().copy()


# The spot's tolerance is wider: the rasterizer lights per vertex of its plane grid (Gouraud), which
# dims the peak of a cos^10 spot between vertices (118 where 0.6 * 0.8 would read 122).
@pytest.mark.parametrize("light, where, levels", [
    ('<light type="directional" dir="0 0 -1" diffuse="0.8 0.8 0.8" specular="0 0 0"/>', np.s_[:, :], 2.0),
    ('<light type="spot" pos="0 0 1.5" dir="0 0 -1" diffuse="0.8 0.8 0.8" specular="0 0 0"/>', np.s_[23:25, 31:33], 5.0),
], ids=["directional", "spot-centre"])
def test_a_lambertian_plane_reads_what_the_rasterizer_draws(light, where, levels):
    model = mujoco.MjModel.from_xml_string(
        f'<mujoco>{_DARK}{_MATTE}<worldbody><geom type="plane" size="4 4 0.1" rgba="0.6 0.6 0.6 1" material="matte"/>'
        f'{light}<camera name="c" pos="0 0 2" xyaxes="1 0 0 0 1 0" fovy="50"/></worldbody></mujoco>')
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    raster = _raster(model, data, 0, 64, 48).astype(float)
    path = PathTracer(model, _cfg(width=64, height=48, spp=8)).render(data, "c").astype(float)
    assert raster[where].mean() > 60  # lit, not a black-equals-black pass
    assert abs(path[where].mean() - raster[where].mean()) < levels, (path[where].mean(), raster[where].mean())


def test_an_environment_map_is_z_up(tmp_path):
    mi, _ = _mitsuba("llvm_ad_rgb")
    sky = np.zeros((16, 32, 3), np.float32)
    sky[:8] = 1.0  # the upper half of a latitude-longitude image is the sky
    path = str(tmp_path / "sky.exr")
    mi.Bitmap(sky).write(path)
    model = mujoco.MjModel.from_xml_string(
        f'<mujoco>{_DARK}<worldbody><camera name="up" pos="0 0 0" xyaxes="1 0 0 0 -1 0" fovy="40"/>'
        '<camera name="down" pos="0 0 0" xyaxes="1 0 0 0 1 0" fovy="40"/></worldbody></mujoco>')
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    tracer = PathTracer(model, _cfg(width=16, height=12, spp=4, envmap_path=path))
    assert tracer.render_linear(data, "up").mean() > 0.95
    assert tracer.render_linear(data, "down").mean() < 0.05


def test_a_colour_changed_in_the_model_shows_in_the_next_frame():
    model = mujoco.MjModel.from_xml_string(
        f'<mujoco><visual><headlight active="1" ambient="1 1 1" diffuse="0 0 0"/></visual>{_MATTE}<worldbody>'
        '<geom type="sphere" size="0.5" rgba="1 1 1 1" material="matte"/>'
        '<camera name="c" pos="0 -2 0" xyaxes="1 0 0 0 0 1" fovy="20"/></worldbody></mujoco>')
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    tracer = PathTracer(model, _cfg(width=8, height=8, spp=4))
    before = tracer.render_linear(data, "c")[3:5, 3:5].mean((0, 1))
    model.geom_rgba[0] = [1.0, 0.0, 0.0, 1.0]
    after = tracer.render_linear(data, "c")[3:5, 3:5].mean((0, 1))
    assert np.allclose(before, 1.0, atol=0.05) and after[0] > 0.95 and after[1:].max() < 0.02, (before, after)


def test_phong_shininess_maps_to_disney_roughness():
    # Walter et al. 2007: alpha = sqrt(2 / (n + 2)) for a Phong exponent n = 128 shininess; roughness = sqrt(alpha)
    assert roughness_from_shininess(0.0) == pytest.approx(1.0)
    assert roughness_from_shininess(0.5) == pytest.approx((2 / 66) ** 0.25)
    assert roughness_from_shininess(1.0) == pytest.approx((2 / 130) ** 0.25)


def test_the_skybox_is_the_rasterizers_star_for_star():
    # a gradient sky strewn with random white marks: the marks' high-pass pattern must correlate
    # with the rasterizer's (mirrored it does not), looking at the horizon and straight up
    from scipy.ndimage import uniform_filter

    model = mujoco.MjModel.from_xml_string(
        f'<mujoco>{_DARK}<asset><texture type="skybox" builtin="gradient" rgb1="0.55 0.7 0.9" rgb2="0.1 0.12 0.18" '
        'width="64" height="64" mark="random" random="0.02" markrgb="1 1 1"/></asset><worldbody>'
        '<camera name="horizon" xyaxes="1 0 0 0 0 1" fovy="90"/><camera name="up" xyaxes="1 0 0 0 1 0" fovy="90"/>'
        '</worldbody></mujoco>')
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    tracer = PathTracer(model, _cfg(width=64, height=48, spp=4))

    def high_pass(image):
        gray = image.astype(float).mean(-1)
        return gray - uniform_filter(gray, 5)

    for cam in ("horizon", "up"):
        raster, path = _raster(model, data, model.camera(cam).id, 64, 48), tracer.render(data, cam)
        assert np.abs(raster.astype(float) - path).mean() < 8.0, cam
        same = np.corrcoef(high_pass(raster).ravel(), high_pass(path).ravel())[0, 1]
        mirrored = np.corrcoef(high_pass(raster).ravel(), high_pass(path)[:, ::-1].ravel())[0, 1]
        assert same > 0.5 and mirrored < 0.2, (cam, same, mirrored)


@pytest.mark.parametrize("uniform", ["false", "true"])
def test_a_2d_texture_lies_where_the_rasterizer_puts_it(uniform):
    # an asymmetric pattern (a 3 x 2 checker, repeated 1.5 x 2.5 times) on a plane seen from above
    model = mujoco.MjModel.from_xml_string(
        f'<mujoco>{_DARK}<asset><texture name="t" type="2d" builtin="checker" rgb1="1 1 1" rgb2="0 0 0" '
        f'width="96" height="64"/><material name="m" texture="t" texrepeat="1.5 2.5" texuniform="{uniform}" '
        'specular="0" shininess="0"/></asset><worldbody><geom type="plane" size="1.5 1 0.1" material="m"/>'
        '<light type="directional" dir="0 0 -1" diffuse="0.8 0.8 0.8" specular="0 0 0"/>'
        '<camera name="c" pos="0.2 0.1 2" xyaxes="1 0 0 0 1 0" fovy="50"/></worldbody></mujoco>')
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    raster = _raster(model, data, 0, 64, 48).astype(float).mean(-1)
    path = PathTracer(model, _cfg(width=64, height=48, spp=8)).render(data, "c").astype(float).mean(-1)
    same = np.corrcoef(raster.ravel(), path.ravel())[0, 1]
    flipped = np.corrcoef(raster.ravel(), path[::-1].ravel())[0, 1]
    assert same > 0.9 and flipped < 0.5, (same, flipped)
