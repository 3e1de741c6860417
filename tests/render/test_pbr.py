"""The pbr tier (Filament): projection against the rasterizer and the pinhole model, Lambertian
shading against the analytic cosine law, labels identical to raster, and the one-line error
without Vulkan. The first Filament frame of a process compiles its shaders (~9 s on lavapipe)."""

import math

import mujoco
import numpy as np
import pytest

from ambulo.render import OffscreenRenderer, pbr
from ambulo.render.pbr import NoVulkanError, PbrRenderer, PbrSettings, gl_camera
from ambulo.sensors.frames import look_at_gl

needs_vulkan = pytest.mark.skipif(pbr._vulkan_problem() is not None,
                                  reason=f"no Vulkan here: {pbr._vulkan_problem()}")

W, H = 160, 120


def _srgb_to_linear(c: float) -> float:
    """IEC 61966-2-1: Filament reads MJCF colours as sRGB-encoded base colours."""
    return c / 12.92 if c <= 0.04045 else ((c + 0.055) / 1.055) ** 2.4


@needs_vulkan
def test_known_points_project_to_the_pinhole_pixels_within_1px():
    """Small spheres at known points: the centroid of each drawn sphere is the pinhole projection of
    its centre (a 3 cm sphere at ~1.8 m: the perspective shift of the centroid is < 0.05 px)."""
    points = [(0.3, 0.2, 0.05), (-0.4, 0.1, 0.05), (0.1, -0.35, 0.05), (0.45, -0.3, 0.05)]
    spec = mujoco.MjSpec()
    spec.visual.headlight.active = 0
    spec.worldbody.add_light(pos=[0, 0, 3], dir=[0, 0, -1], type=mujoco.mjtLightType.mjLIGHT_DIRECTIONAL,
                             castshadow=False)
    spec.worldbody.add_geom(type=mujoco.mjtGeom.mjGEOM_PLANE, size=[5, 5, 0.1], rgba=[0.2, 0.2, 0.2, 1])
    for p in points:
        spec.worldbody.add_geom(type=mujoco.mjtGeom.mjGEOM_SPHERE, pos=p, size=[0.03, 0, 0], rgba=[1, 0, 0, 1])
    model = spec.compile()
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    width, height, fovy = 320, 240, 60.0
    eye = np.array([0.1, -0.9, 1.6])
    rot = look_at_gl(eye, np.zeros(3))
    cam = gl_camera(eye, rot, fovy, width, height, (0.05, 20.0))
    rgb = PbrRenderer(model, width, height, PbrSettings(shadows=False)).render(data, cam).copy()
    f = height / 2 / math.tan(math.radians(fovy) / 2)
    red = rgb[..., 0] > 3 * rgb[..., 1].astype(int) + 30
    for i, p in enumerate(points):
        p_c = rot.T @ (np.asarray(p) - eye)  # OpenGL camera axes: x right, y up, looking along -z
        u, v = width / 2 - 0.5 + f * p_c[0] / -p_c[2], height / 2 - 0.5 - f * p_c[1] / -p_c[2]
        near = (np.abs(np.arange(width)[None] - u) < 10) & (np.abs(np.arange(height)[:, None] - v) < 10)
        ys, xs = np.nonzero(red & near)
        assert len(xs) > 10, f"sphere {i} not drawn near ({u:.1f}, {v:.1f})"
        assert abs(xs.mean() - u) <= 1.0 and abs(ys.mean() - v) <= 1.0, (i, xs.mean(), ys.mean(), u, v)


@needs_vulkan
def test_pbr_and_raster_draw_each_box_on_the_same_pixels_within_1px():
    spec = mujoco.MjSpec()
    spec.visual.headlight.active = 0
    spec.worldbody.add_light(pos=[0, 0, 3], dir=[0, 0, -1], type=mujoco.mjtLightType.mjLIGHT_DIRECTIONAL,
                             castshadow=False)
    spec.worldbody.add_geom(type=mujoco.mjtGeom.mjGEOM_PLANE, size=[5, 5, 0.1], rgba=[0.2, 0.2, 0.2, 1])
    centres = [(0.3, 0.2, 0.05), (-0.4, 0.1, 0.05), (0.1, -0.35, 0.05)]
    for c in centres:
        spec.worldbody.add_geom(type=mujoco.mjtGeom.mjGEOM_BOX, pos=c, size=[0.04, 0.04, 0.04], rgba=[1, 0, 0, 1])
    spec.worldbody.add_camera(name="cam", pos=[0.1, -0.9, 1.6])
    model = spec.compile()
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    eye = np.array([0.1, -0.9, 1.6])
    rot = look_at_gl(eye, np.zeros(3))
    raster = OffscreenRenderer(model, W, H)
    raster.update(model, data, 0, eye, rot, (0.05, 20.0))
    ids, _ = raster.render_ids(want_depth=False)
    rgb = PbrRenderer(model, W, H, PbrSettings(shadows=False)).render(data, raster.scene.camera[0]).copy()
    red = rgb[..., 0] > 3 * rgb[..., 1].astype(int) + 30
    for geom in range(1, len(centres) + 1):
        ys, xs = np.nonzero(ids == geom)
        box = (np.abs(np.arange(W)[None] - xs.mean()) < 15) & (np.abs(np.arange(H)[:, None] - ys.mean()) < 15)
        py, px = np.nonzero(red & box)
        assert len(xs) > 20 and len(px) > 20
        assert abs(px.mean() - xs.mean()) <= 1.0 and abs(py.mean() - ys.mean()) <= 1.0
        assert abs(len(px) - len(xs)) <= 0.15 * len(xs)  # same silhouette, up to antialiased edges
    raster.close()


@needs_vulkan
def test_lambertian_plane_follows_the_cosine_law_and_linear_albedo():
    """Post-processing off: the image is exposure x radiance, and a rough dielectric's diffuse
    radiance is albedo E cos(theta) / pi under a directional light of E lux. Filament keeps a
    small specular lobe even at roughness 1 (~1.3 % of white here), the same for every albedo: it
    is measured on a black plane and subtracted. The exposure is one constant k, fitted from the
    white plane at normal incidence; every other angle and albedo must then match
    k albedo cos(theta) within 8-bit quantization."""
    xml = """<mujoco><visual><headlight active="0"/></visual>
      <asset><material name="m" rgba="{a} {a} {a} 1" roughness="1" metallic="0" specular="0"/></asset>
      <worldbody><light directional="true" pos="0 0 3" dir="{d}" castshadow="false" intensity="100000"/>
      <geom type="plane" size="50 50 .1" material="m"/></worldbody></mujoco>"""
    eye = np.array([0.0, -2.0, 2.0])
    cam = gl_camera(eye, look_at_gl(eye, np.zeros(3)), 60.0, 32, 24, (0.05, 20.0))
    model = mujoco.MjModel.from_xml_string(xml.format(a=1, d="0 0 -1"))
    data = mujoco.MjData(model)
    # one renderer: it reads the model's materials and lights on every frame, as randomizers need
    r = PbrRenderer(model, 32, 24, PbrSettings(post_processing=False, shadows=False, skybox=False))
    measured = {}
    for albedo in (1.0, 0.5, 0.0):
        for theta_deg in (0, 30, 60, 75):
            t = math.radians(theta_deg)
            model.mat_rgba[0, :3] = albedo
            model.light_dir[0] = [math.sin(t), 0, -math.cos(t)]
            mujoco.mj_forward(model, data)
            measured[albedo, theta_deg] = r.render(data, cam)[12, 16].astype(float) / 255
    diffuse = {key: rgb - measured[0.0, key[1]] for key, rgb in measured.items() if key[0] > 0}
    k = diffuse[1.0, 0][0]
    assert 0.3 < k < 0.95  # 100,000 lux of white sunlight is a bright, unclipped image
    assert measured[0.0, 0][0] < 0.03 * k  # the specular residue is small
    for (albedo, theta_deg), rgb in diffuse.items():
        expected = k * _srgb_to_linear(albedo) * math.cos(math.radians(theta_deg))
        assert np.all(np.abs(rgb - expected) <= 1.5 / 255 + 0.02 * expected), (albedo, theta_deg, rgb, expected)
        assert np.ptp(rgb) == 0  # grey stays grey


def test_no_vulkan_loader_is_one_line_naming_the_apt_packages(monkeypatch):
    monkeypatch.setattr(pbr, "_VULKAN_LOADER", "libvulkan-not-installed.so.1")
    model = mujoco.MjModel.from_xml_string("<mujoco><worldbody><geom size='1'/></worldbody></mujoco>")
    with pytest.raises(NoVulkanError) as err:
        PbrRenderer(model, 32, 24)
    message = str(err.value)
    assert "\n" not in message
    assert "no Vulkan loader" in message and "apt-get install libvulkan1 mesa-vulkan-drivers" in message


def test_no_vulkan_driver_is_one_line_naming_the_apt_packages(monkeypatch, tmp_path):
    monkeypatch.setattr(pbr, "_VULKAN_LOADER", pbr._VULKAN_LOADER)
    monkeypatch.setenv("VK_DRIVER_FILES", str(tmp_path / "missing_icd.json"))
    problem = pbr._vulkan_problem()
    if problem is not None and "loader" in problem:
        pytest.skip("no Vulkan loader here: the driver check comes after it")
    with pytest.raises(NoVulkanError, match="no Vulkan driver.*mesa-vulkan-drivers"):
        pbr._filament_context()


@needs_vulkan
def test_two_renderers_of_a_textured_model_render_side_by_side():
    """Each renderer has its own Filament engine: two model scenes with textures in one engine
    fail the second's first frame in mujoco-studio 4.0.0."""
    model = mujoco.MjModel.from_xml_string("""<mujoco><asset>
      <texture name="c" type="2d" builtin="checker" width="64" height="64" rgb1="1 1 1" rgb2="0 0 0"/>
      <material name="m" texture="c"/></asset><worldbody><light directional="true" dir="0 0 -1"/>
      <geom type="plane" size="3 3 .1" material="m"/></worldbody></mujoco>""")
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    eye = np.array([-2.0, -1.5, 1.8])
    cam = gl_camera(eye, look_at_gl(eye, np.zeros(3)), 60.0, 64, 48, (0.05, 20.0))
    first, second = PbrRenderer(model, 64, 48), PbrRenderer(model, 64, 48)
    a = first.render(data, cam).copy()
    b = second.render(data, cam).copy()
    # both engines drew the same first frame (Filament's temporal dithering depends on the frame count)
    assert np.ptp(a) > 100 and np.abs(a.astype(int) - b).max() <= 1


@needs_vulkan
def test_shadows_fall_behind_a_box_even_when_the_mjcf_light_casts_none():
    """PbrSettings.shadows makes every light cast shadows (MJCF castshadow is a rasterizer cost
    knob): the floor where the box blocks the sun is darker than its mirror image; without
    shadows the two are equally lit."""
    model = mujoco.MjModel.from_xml_string("""<mujoco><visual><headlight active="0"/></visual><worldbody>
      <light directional="true" pos="0 0 3" dir="0.5 0.3 -1" castshadow="false" intensity="100000"/>
      <geom type="plane" size="5 5 .1" rgba=".8 .8 .8 1"/>
      <geom type="box" pos="0 0 .3" size=".3 .3 .3" rgba="1 0 0 1"/></worldbody></mujoco>""")
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    eye = np.array([0.0, -3.0, 2.5])
    rot = look_at_gl(eye, np.zeros(3))
    cam = gl_camera(eye, rot, 60.0, 160, 120, (0.05, 20.0))
    f = 60 / math.tan(math.radians(30))

    def pixel(p):
        p_c = rot.T @ (np.asarray(p) - eye)
        return int(round(60 - 0.5 - f * p_c[1] / -p_c[2])), int(round(80 - 0.5 + f * p_c[0] / -p_c[2]))

    shaded, mirror = pixel([0.45, 0.1, 0.0]), pixel([-0.45, 0.1, 0.0])  # (0.45, 0.1) is on the sun's line behind the box
    for shadows in (False, True):
        image = PbrRenderer(model, 160, 120, PbrSettings(shadows=shadows)).render(data, cam).astype(int)
        dark, lit = image[shaded].mean(), image[mirror].mean()
        if shadows:
            assert dark < 0.8 * lit, (dark, lit)
        else:
            assert abs(dark - lit) <= 3, (dark, lit)


def test_the_no_vulkan_error_survives_a_worker_process_boundary():
    import pickle

    err = pickle.loads(pickle.dumps(NoVulkanError("no Vulkan loader (libvulkan.so.1 cannot be loaded)")))
    assert str(err) == "no Vulkan loader (libvulkan.so.1 cannot be loaded); " + pbr.INSTALL
    assert err.fix == pbr.INSTALL
