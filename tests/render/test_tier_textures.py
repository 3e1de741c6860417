"""Textured surfaces look the same in the raster, pbr and path tiers (issue 26).

- texture mapping: a texture whose texels encode their own (column, row), drawn unlit (ambient 1),
  shows the same texel on every pixel of a plane (finite and infinite), on each face of a box and
  on spheres, ellipsoids, cylinders (caps too) and capsules seen from above, the sides and below,
  in both ``texuniform`` modes, in the path tier as in the rasterizer (median within 2 texels of 4 levels;
  a flipped or shifted mapping misses by tens);
- colour: a checker box beside an untextured box of its mean colour under one directional light:
  the path tier's mean colours are the rasterizer's within 3 levels; the pbr tier (linear output,
  its own exposure) has the rasterizer's linear textured/plain ratio within 5 % per channel
  (textures were read as linear by Filament: 60 % too bright in green);
- a texture, colour or material given after the path tracer was built shows in the next frame;
- a PNG texture (colorspace ``linear``) on a sphere and a cylinder, unlit: the path tier's mean
  colour per shape is the rasterizer's within 4 levels.
"""

from __future__ import annotations

import mujoco
import numpy as np
import pytest

from ambulo.render import OffscreenRenderer, pbr
from ambulo.render.path import PathTracer, PathTracerCfg
from ambulo.render.scene_description import srgb_to_linear
from ambulo.sensors.frames import look_at_gl

pytestmark = pytest.mark.usefixtures("needs_mitsuba")  # tests/render/conftest.py


W = 64
CENTRE = np.array([0.3, -0.2, 0.1])


def _coded_texture_model(geom_type: str, size, repeat, uniform: bool) -> mujoco.MjModel:
    """One geom with a 64 x 64 texture whose red is its column and green its row (x 4), unlit."""
    spec = mujoco.MjSpec()
    head = spec.visual.headlight
    head.ambient, head.diffuse, head.specular = [1, 1, 1], [0, 0, 0], [0, 0, 0]
    spec.visual.global_.offwidth = spec.visual.global_.offheight = W
    u, v = np.meshgrid(np.arange(64), np.arange(64))
    tex = spec.add_texture(name="t", type=mujoco.mjtTexture.mjTEXTURE_2D, width=64, height=64, nchannel=3)
    tex.data = np.stack([4 * u + 2, 4 * v + 2, np.full_like(u, 128)], -1).astype(np.uint8).tobytes()
    mat = spec.add_material(name="m", texrepeat=list(repeat), texuniform=uniform, specular=0, shininess=0)
    mat.textures[mujoco.mjtTextureRole.mjTEXROLE_RGB] = "t"
    spec.worldbody.add_geom(type=getattr(mujoco.mjtGeom, f"mjGEOM_{geom_type.upper()}"), size=list(size),
                            material="m", rgba=[1, 1, 1, 1], pos=CENTRE.tolist(), euler=[0, 0, 20])
    spec.worldbody.add_camera(name="c", fovy=45)
    return spec.compile()


_CURVED_EYES = [(0.4, -0.1, 4.0), (4.0, 0.5, 0.3), (-1.0, 4.0, -0.5), (0.3, -0.2, -4.0)]
"""Top (the +z cap or pole), two sides (the azimuth seam at +x among them) and the bottom."""


@pytest.mark.parametrize(("geom_type", "size", "repeat", "uniform", "eyes"), [
    ("plane", (0.4, 0.3, 0.1), (1.5, 2.5), False, [(0.4, -0.1, 4.0)]),
    ("plane", (0.4, 0.3, 0.1), (1.5, 2.5), True, [(0.4, -0.1, 4.0)]),
    ("plane", (0.0, 0.0, 0.1), (1.5, 2.5), False, [(0.4, -0.1, 4.0)]),
    ("box", (0.4, 0.3, 0.5), (1.5, 2.5), False, [(0.4, -0.1, 4.0), (4.0, 0.5, 0.3), (0.5, 4.0, 0.2)]),
    ("box", (0.4, 0.3, 0.5), (1.5, 2.5), True, [(0.4, -0.1, 4.0), (-4.0, -1.0, 0.5), (1.0, -4.0, -0.3)]),
    ("sphere", (0.5, 0.0, 0.0), (1.5, 2.5), False, _CURVED_EYES),
    ("sphere", (0.5, 0.0, 0.0), (1.5, 2.5), True, _CURVED_EYES),
    ("ellipsoid", (0.5, 0.3, 0.4), (1.5, 2.5), True, _CURVED_EYES),
    ("cylinder", (0.3, 0.5, 0.0), (1.5, 2.5), False, _CURVED_EYES),
    ("cylinder", (0.3, 0.5, 0.0), (1.5, 2.5), True, _CURVED_EYES),
    ("capsule", (0.3, 0.5, 0.0), (1.5, 2.5), False, _CURVED_EYES),
], ids=["plane", "plane-uniform", "plane-infinite", "box", "box-uniform", "sphere", "sphere-uniform",
        "ellipsoid-uniform", "cylinder", "cylinder-uniform", "capsule"])
def test_the_path_tier_puts_each_texel_where_the_rasterizer_does(geom_type, size, repeat, uniform, eyes):
    from scipy.ndimage import binary_erosion

    model = _coded_texture_model(geom_type, size, repeat, uniform)
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    tracer = PathTracer(model, PathTracerCfg(width=W, height=W, spp=4, denoise=False, variant="llvm_ad_rgb"))
    with OffscreenRenderer(model, W, W) as raster:
        for eye in eyes:
            eye = np.asarray(eye)
            rot = look_at_gl(eye, CENTRE, up=(0, 1, 0) if abs(eye[2]) > 3 else (0, 0, 1))
            raster.update(model, data, 0, eye, rot, (0.1, 20.0))
            expected = raster.render_rgb().astype(float)
            inside = binary_erosion(raster.render_ids(want_depth=False)[0] == 0, iterations=2)  # no edge pixels
            path = tracer.render(data, 0, pose=(eye, rot)).astype(float)
            assert inside.sum() > 50
            for channel, what in ((0, "column"), (1, "row")):
                miss = np.median(np.abs(path[inside, channel] - expected[inside, channel]))
                assert miss <= 8.0, (eye, what, miss)  # 2 texels: the rasterizer's mipmaps blur minified texels


_TWO_BOXES = """<mujoco><visual><headlight active="0" ambient="0 0 0" diffuse="0 0 0"/>
  <global offwidth="96" offheight="72"/></visual>
  <asset><texture name="t" type="2d" builtin="checker" width="64" height="64" rgb1="0.9 0.3 0.1" rgb2="0.2 0.5 0.8"/>
    <material name="checker" texture="t" texrepeat="2 2" texuniform="true" specular="0" shininess="0"/>
    <material name="plain" rgba="0.55 0.4 0.45 1" specular="0" shininess="0"/></asset>
  <worldbody><light type="directional" dir="0 0 -1" diffuse="0.8 0.8 0.8" specular="0 0 0"/>
    <geom type="box" size="0.5 0.5 0.5" pos="-0.6 0 0" material="checker"/>
    <geom type="box" size="0.5 0.5 0.5" pos="0.6 0 0" material="plain"/>
    <camera name="c" pos="0 0 4" xyaxes="1 0 0 0 1 0" fovy="40"/></worldbody></mujoco>"""


def _two_boxes():
    model = mujoco.MjModel.from_xml_string(_TWO_BOXES)
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    return model, data


def _raster_and_path(model, data):
    """Camera "c" at 96x72: the rasterizer's colours and geom ids, and the path tier's colours
    (16 spp, not denoised), as float images."""
    with OffscreenRenderer(model, 96, 72) as raster:
        raster.update(model, data, 0, data.cam_xpos[0], data.cam_xmat[0].reshape(3, 3))
        expected = raster.render_rgb().astype(float)
        ids, _ = raster.render_ids(want_depth=False)
    path = PathTracer(model, PathTracerCfg(width=96, height=72, spp=16, denoise=False, variant="llvm_ad_rgb")
                      ).render(data, "c").astype(float)
    return expected, ids, path


def test_a_checker_box_has_the_rasterizers_colour_in_the_path_tier():
    model, data = _two_boxes()
    expected, ids, path = _raster_and_path(model, data)
    for geom in (0, 1):
        mean_path, mean_raster = path[ids == geom].mean(0), expected[ids == geom].mean(0)
        assert np.all(np.abs(mean_path - mean_raster) <= 3.0), (geom, mean_path, mean_raster)


@pytest.mark.skipif(pbr._vulkan_problem() is not None, reason=f"no Vulkan here: {pbr._vulkan_problem()}")
def test_a_checker_box_has_the_rasterizers_colour_in_the_pbr_tier():
    from ambulo.render.pbr import PbrRenderer, PbrSettings

    model, data = _two_boxes()
    with OffscreenRenderer(model, 96, 72) as raster:
        raster.update(model, data, 0, data.cam_xpos[0], data.cam_xmat[0].reshape(3, 3))
        linear_raster = srgb_to_linear(raster.render_rgb() / 255.0)
        ids, _ = raster.render_ids(want_depth=False)
        with PbrRenderer(model, 96, 72, PbrSettings(post_processing=False, shadows=False)) as renderer:
            linear_pbr = renderer.render(data, raster.scene.camera[0]).astype(float) / 255.0  # linear x exposure
    assert model.tex_colorspace[0] == mujoco.mjtColorSpace.mjCOLORSPACE_AUTO  # the model is left as it was
    ratio_pbr = linear_pbr[ids == 0].mean(0) / linear_pbr[ids == 1].mean(0)
    ratio_raster = linear_raster[ids == 0].mean(0) / linear_raster[ids == 1].mean(0)
    assert np.allclose(ratio_pbr, ratio_raster, rtol=0.05), (ratio_pbr, ratio_raster)


def test_a_texture_colour_or_material_given_after_the_build_shows_in_the_next_frame():
    """What the replicator's material randomizer does: geom_matid changes per frame."""
    model, data = _two_boxes()
    tracer = PathTracer(model, PathTracerCfg(width=96, height=72, spp=16, denoise=False, variant="llvm_ad_rgb"))
    tracer.render(data, "c")
    model.geom_matid[:] = [1, 0]  # the boxes swap materials
    model.geom_rgba[1] = [0.5, 1.0, 1.0, 1.0]  # and the now-checkered one is tinted
    with OffscreenRenderer(model, 96, 72) as raster:
        raster.update(model, data, 0, data.cam_xpos[0], data.cam_xmat[0].reshape(3, 3))
        expected = raster.render_rgb().astype(float)
        ids, _ = raster.render_ids(want_depth=False)
    path = tracer.render(data, "c").astype(float)
    for geom in (0, 1):
        inside = ids == geom
        assert np.all(np.abs(path[inside].mean(0) - expected[inside].mean(0)) <= 3.0), geom
    assert np.corrcoef(path[ids == 1, 0], expected[ids == 1, 0])[0, 1] > 0.9  # the checker, cell for cell
    model.mat_specular[:] = 0.5  # matte -> glossy: another kind of BSDF (a new Mitsuba scene)
    glossy = tracer.render(data, "c").astype(float)
    assert np.abs(glossy[ids == 1].mean(0) - path[ids == 1].mean(0)).max() > 1.0
    model.geom_matid[:] = [0, 1]  # glossy checker -> glossy plain: the texture replaced by a colour in place
    tracer.render(data, "c")
    model.geom_rgba[1] = [0.2, 0.3, 0.9, 1.0]  # and that colour changed (Mitsuba refuses 1 x 1 bitmap updates)
    plain = tracer.render(data, "c").astype(float)
    def one_colour(pixels):  # the share of pixels within 10 levels of the median colour
        return (np.abs(pixels - np.median(pixels, 0)).max(1) <= 10).mean()
    assert one_colour(plain[ids == 1]) > 0.8 > one_colour(glossy[ids == 1]), (one_colour(plain[ids == 1]),
                                                                               one_colour(glossy[ids == 1]))


def test_a_png_textured_sphere_and_cylinder_have_the_rasterizers_colours_in_the_path_tier(tmp_path):
    """Unlit (ambient 1): each tier shows the texels themselves, so the mean colour of each shape
    agrees. The PNG (no sRGB chunk) compiles to colorspace ``linear``, which the rasterizer shows as
    display values; its halves (red at u < 0.5, blue beyond, a green top band) make a texture read
    as linear (paler) or mapped in x, y (the front shows red and blue, not blue) miss by tens of levels."""
    from PIL import Image

    texels = np.zeros((64, 64, 3), np.uint8)
    texels[:, :32], texels[:, 32:], texels[:16] = (230, 40, 30), (30, 60, 230), (40, 200, 40)
    Image.fromarray(texels).save(tmp_path / "halves.png")
    model = mujoco.MjModel.from_xml_string(f"""<mujoco>
      <visual><headlight active="1" ambient="1 1 1" diffuse="0 0 0" specular="0 0 0"/>
        <global offwidth="96" offheight="72"/></visual>
      <asset><texture name="halves" type="2d" file="{tmp_path / 'halves.png'}"/>
        <material name="m" texture="halves" specular="0" shininess="0"/></asset>
      <worldbody><geom type="sphere" size="0.45" pos="-0.6 0 0" material="m"/>
        <geom type="cylinder" size="0.35 0.45" pos="0.6 0 0" material="m"/>
        <camera name="c" pos="0 -4 0.8" xyaxes="1 0 0 0 0.2 1" fovy="40"/></worldbody></mujoco>""")
    assert model.tex_colorspace[0] == mujoco.mjtColorSpace.mjCOLORSPACE_LINEAR
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    expected, ids, path = _raster_and_path(model, data)
    from scipy.ndimage import binary_erosion

    for geom in (0, 1):
        inside = binary_erosion(ids == geom, iterations=2)  # the path tier's edges are antialiased
        assert inside.sum() > 150
        mean_path, mean_raster = path[inside].mean(0), expected[inside].mean(0)
        assert np.all(np.abs(mean_path - mean_raster) <= 4.0), (geom, mean_path, mean_raster)
