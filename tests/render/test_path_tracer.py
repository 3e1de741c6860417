"""The path-traced tier against physics and against the rasterizer (issue 26).

- white furnace: a white Lambertian sphere in a uniform environment of radiance L reads L
  (a convex object sees only the environment, and albedo 1 reflects all of it);
- a Lambertian plane under a point light of intensity I reads ``albedo I cos(theta) / (pi r^2)``;
- projection: small emissive spheres land on the rasterizer's pixels (centroids within 1 px),
  also after they move (the per-frame pose update, not a rebuild).

Tiny images and few samples keep each test to seconds; skipped when Mitsuba or its LLVM backend
cannot run here (the skip names what to install).
"""

from __future__ import annotations

import mujoco
import numpy as np
import pytest

from ambulo.render.path import PathTracer, PathTracerCfg
from ambulo.render.scene_description import srgb_to_linear

pytestmark = pytest.mark.usefixtures("needs_mitsuba")  # tests/render/conftest.py


def _model(body: str, visual: str = '<headlight active="0" ambient="0 0 0" diffuse="0 0 0"/>') -> mujoco.MjModel:
    """``body`` in the world; materials: "matte" (rgba white, no specular) and "glow" (emissive white)."""
    assets = ('<asset><material name="matte" rgba="1 1 1 1" specular="0"/>'
              '<material name="glow" rgba="1 1 1 1" specular="0" emission="1"/></asset>')
    return mujoco.MjModel.from_xml_string(
        f"<mujoco><visual>{visual}</visual>{assets}<worldbody>{body}</worldbody></mujoco>")


def _cfg(**kw) -> PathTracerCfg:
    return PathTracerCfg(variant="llvm_ad_rgb", denoise=False, **kw)


def test_white_furnace_sphere_reads_the_environment_radiance():
    # the headlight's ambient is the only light: a constant environment of radiance 1 (sRGB 1 = linear 1)
    model = _model('<geom type="sphere" size="0.5" material="matte"/>'
                   '<camera name="c" pos="0 -2 0" xyaxes="1 0 0 0 0 1" fovy="40"/>',
                   '<headlight active="1" ambient="1 1 1" diffuse="0 0 0"/>')
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    tracer = PathTracer(model, _cfg(width=40, height=40, spp=32, max_depth=8))
    radiance = tracer.render_linear(data, "c")
    # pixels wholly on the sphere: inside 80 % of its projected radius (tan(asin(0.5/2)) / tan(20 deg))
    v, u = np.mgrid[:40, :40] + 0.5
    r_px = 20 * np.tan(np.arcsin(0.25)) / np.tan(np.radians(20))
    on_sphere = np.hypot(u - 20, v - 20) < 0.8 * r_px
    assert on_sphere.sum() > 300
    values = radiance[on_sphere]
    assert abs(values.mean() - 1.0) < 0.01, values.mean()
    assert np.abs(values - 1.0).max() < 0.1  # a dark rim or a bright spot would show here
    assert np.allclose(radiance[0, 0], 1.0, atol=1e-4)  # the environment itself


def test_lambertian_plane_under_a_point_light_matches_the_analytic_radiance():
    intensity_w_sr, height_m = 2.0, 1.0
    model = _model(f'<geom type="plane" size="5 5 0.1" rgba="0.6 0.6 0.6 1" material="matte"/>'
                   f'<light type="point" pos="0 0 {height_m}" intensity="{intensity_w_sr}" diffuse="1 1 1"/>'
                   '<camera name="top" pos="0 0 3" xyaxes="1 0 0 0 1 0" fovy="60"/>')
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    width, height = 48, 36
    tracer = PathTracer(model, _cfg(width=width, height=height, spp=16))
    radiance = tracer.render_linear(data, "top")[..., 0]
    # each pixel centre's ray meets the plane at (3 dx, 3 dy, 0); the camera's x is world x, its y world y
    f_px = (height / 2) / np.tan(np.radians(30))
    v, u = np.mgrid[:height, :width] + 0.5
    x_m, y_m = 3.0 * (u - width / 2) / f_px, -3.0 * (v - height / 2) / f_px
    r_m = np.sqrt(x_m ** 2 + y_m ** 2 + height_m ** 2)
    albedo = srgb_to_linear(np.array([0.6]))[0]
    expected = albedo * intensity_w_sr * (height_m / r_m) / (np.pi * r_m ** 2)
    rel = radiance / expected - 1.0
    assert abs(rel.mean()) < 0.01, rel.mean()
    assert np.abs(rel).max() < 0.05, np.abs(rel).max()  # direct light only: per-pixel noise is small


_POINTS_M = np.array([[0.0, 0.0, 0.3], [0.6, 0.3, 0.6], [-0.5, -0.3, 0.0], [0.5, -0.5, -0.1], [-0.4, 0.5, 0.8]])


def _spheres_model() -> mujoco.MjModel:
    geoms = "".join(f'<body name="b{i}" pos="{x} {y} {z}"><freejoint/>'
                    f'<geom type="sphere" size="0.03" material="glow"/></body>'
                    for i, (x, y, z) in enumerate(_POINTS_M))
    return _model(geoms + '<camera name="c" pos="0.1 -2.5 0.3" xyaxes="1 0 0 0 0 1" fovy="45"/>',
                  '<headlight active="0" ambient="0 0 0" diffuse="0 0 0"/><global offwidth="96" offheight="72"/>')


def _centroids(image: np.ndarray, near_px: np.ndarray, radius_px: int = 6) -> np.ndarray:
    """Brightness-weighted centroid (u, v) px of the blob near each of ``near_px``."""
    gray = image.astype(np.float64).mean(-1)
    out = []
    for u0, v0 in near_px:
        u_lo, v_lo = max(int(u0) - radius_px, 0), max(int(v0) - radius_px, 0)
        win = gray[v_lo:int(v0) + radius_px + 1, u_lo:int(u0) + radius_px + 1]
        vv, uu = np.mgrid[:win.shape[0], :win.shape[1]] + 0.5
        out.append([(uu * win).sum() / win.sum() + u_lo, (vv * win).sum() / win.sum() + v_lo])
    return np.array(out)


def _raster_centroids(model, data, cam_id, width, height):
    from ambulo.render import OffscreenRenderer

    with OffscreenRenderer(model, width, height) as renderer:
        renderer.update(model, data, cam_id, data.cam_xpos[cam_id], data.cam_xmat[cam_id].reshape(3, 3))
        ids, _ = renderer.render_ids(want_depth=False)
    out = []
    for geom in range(model.ngeom):
        v, u = np.nonzero(ids == geom)
        out.append([u.mean() + 0.5, v.mean() + 0.5])
    return np.array(out)


def test_known_points_land_on_the_rasterizers_pixels_and_follow_a_pose_update():
    model = _spheres_model()
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    width, height = 96, 72
    cam = model.camera("c").id
    tracer = PathTracer(model, _cfg(width=width, height=height, spp=16))
    for step in range(2):
        raster = _raster_centroids(model, data, cam, width, height)
        path = _centroids(tracer.render(data, "c"), raster)
        assert np.abs(path - raster).max() < 1.0, (step, path - raster)
        # the next frame: every sphere moves (free joints), the camera stays
        data.qpos[np.arange(model.nbody - 1)[:, None] * 7 + np.arange(3)] += [0.12, -0.05, 0.08]
        mujoco.mj_forward(model, data)


def test_every_geom_type_covers_the_rasterizers_pixels():
    # emissive white shapes on black, turned off their axes: the path tracer's silhouettes are the
    # rasterizer's id pass (intersection over union per geom)
    shapes = ('<geom type="box" size="0.15 0.1 0.2" pos="-0.6 0 0.25" euler="20 30 10" material="glow"/>'
              '<geom type="capsule" size="0.08 0.2" pos="-0.15 0 0.25" euler="60 0 20" material="glow"/>'
              '<geom type="cylinder" size="0.12 0.15" pos="0.3 0 0.25" euler="0 45 0" material="glow"/>'
              '<geom type="ellipsoid" size="0.2 0.1 0.15" pos="0.65 0 0.25" euler="0 0 30" material="glow"/>'
              '<geom type="mesh" mesh="wedge" pos="-0.3 0 -0.25" euler="10 20 30" material="glow"/>'
              '<geom type="sphere" size="0.15" pos="0.3 0 -0.25" material="glow"/>')
    model = mujoco.MjModel.from_xml_string(
        '<mujoco><visual><headlight active="0" ambient="0 0 0" diffuse="0 0 0"/>'
        '<global offwidth="128" offheight="96"/><quality numslices="64" numstacks="32"/></visual>'
        '<asset><material name="glow" rgba="1 1 1 1" specular="0" emission="1"/>'
        '<mesh name="wedge" vertex="0 0 0  0.4 0 0  0 0.3 0  0 0 0.25  0.4 0 0.25  0 0.3 0.25"/></asset>'
        f'<worldbody>{shapes}<camera name="c" pos="0 -2.5 0" xyaxes="1 0 0 0 0 1" fovy="45"/></worldbody></mujoco>')
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    from ambulo.render import OffscreenRenderer

    with OffscreenRenderer(model, 128, 96) as renderer:
        renderer.update(model, data, 0, data.cam_xpos[0], data.cam_xmat[0].reshape(3, 3))
        ids, _ = renderer.render_ids(want_depth=False)
    lit = PathTracer(model, _cfg(width=128, height=96, spp=16)).render_linear(data, "c").mean(-1) > 0.5  # half covered
    for geom in range(model.ngeom):
        raster = ids == geom
        # the path-traced pixels of this geom: lit pixels nearer its raster pixels than any other's
        near = np.zeros_like(raster)
        v, u = np.nonzero(raster)
        near[max(v.min() - 3, 0):v.max() + 4, max(u.min() - 3, 0):u.max() + 4] = True
        path = lit & near & ((ids == geom) | (ids < 0))
        iou = (raster & path).sum() / (raster | path).sum()
        v_path, u_path = np.nonzero(path)
        # 0.95-0.997 here (the capsule lowest): the edge pixels of 20-40 px shapes decide it
        assert iou > 0.93, (geom, iou)
        assert np.hypot(u_path.mean() - u.mean(), v_path.mean() - v.mean()) < 0.5, geom
