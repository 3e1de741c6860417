"""Balance: cart-table ZMP, support polygons and margins, capture point and region, and the
centre of pressure measured from MuJoCo contact forces, against hand-computed values."""

import math

import mujoco
import numpy as np
import pytest
import torch

from ambulo.engine import CpuEngine
from ambulo.locomotion.balance import (
    CenterOfPressure,
    FootShape,
    capture_point,
    capture_region,
    cart_table_zmp,
    foot_polygon,
    polygon_signed_distance,
    support_polygon,
    zmp_in_support,
)

G = 9.81


# --------------------------------------------------------------------------- cart-table
def test_cart_table_zmp_hand_computed():
    # z_c / g = 0.8 / 9.81; c_ddot = (0.981, -1.962) gives a shift of (0.08, -0.16)
    com = np.array([0.1, -0.05])
    acc = np.array([0.981, -1.962])
    np.testing.assert_allclose(cart_table_zmp(com, acc, 0.8), [0.02, 0.11], atol=1e-12)
    # (..., 3): height from z; a vertical acceleration of 0.19 m/s^2 makes g + z_ddot = 10
    p = cart_table_zmp(np.array([0.0, 0.0, 0.8]), np.array([1.0, -0.5, 0.19]))
    np.testing.assert_allclose(p, [-0.08, 0.04], atol=1e-12)


def test_cart_table_zmp_batched_torch_and_lipm_inverse():
    # the LIPM c_ddot = omega^2 (c - p) must give back p, for any batch shape, on tensors
    gen = torch.Generator().manual_seed(0)
    com = torch.rand(4, 5, 2, generator=gen, dtype=torch.float64)
    zmp = torch.rand(4, 5, 2, generator=gen, dtype=torch.float64)
    z_c = 0.7
    acc = (G / z_c) * (com - zmp)
    out = cart_table_zmp(com, acc, z_c)
    assert isinstance(out, torch.Tensor) and out.shape == (4, 5, 2)
    torch.testing.assert_close(out, zmp)
    com3 = torch.cat([com, torch.full((4, 5, 1), z_c, dtype=torch.float64)], -1)
    acc3 = torch.cat([acc, torch.zeros(4, 5, 1, dtype=torch.float64)], -1)
    torch.testing.assert_close(cart_table_zmp(com3, acc3), zmp)
    with pytest.raises(ValueError, match="com_height_m"):
        cart_table_zmp(com, acc)


# --------------------------------------------------------------------------- polygons
def test_foot_polygon_and_double_support_hull():
    foot = FootShape(length_m=0.2, width_m=0.1)
    # yawed by 90 deg: 0.1 along x, 0.2 along y, around (1, 2)
    corners = foot_polygon((1.0, 2.0, math.pi / 2), foot)
    np.testing.assert_allclose(corners.min(0), [0.95, 1.9], atol=1e-12)
    np.testing.assert_allclose(corners.max(0), [1.05, 2.1], atol=1e-12)
    # two parallel feet 0.2 apart: the hull is the 0.2 x 0.3 rectangle around them
    hull = support_polygon([(0.0, 0.1, 0.0), (0.0, -0.1, 0.0)], foot)
    assert len(hull) == 4
    np.testing.assert_allclose(np.sort(hull, axis=0), [[-0.1, -0.15], [-0.1, -0.15], [0.1, 0.15], [0.1, 0.15]])
    # against shapely's hull for a staggered, turned stance
    shapely = pytest.importorskip("shapely")
    poses = [(0.0, 0.12, 0.2), (0.3, -0.1, -0.25)]
    hull = support_polygon(poses, foot)
    ref = shapely.MultiPolygon([shapely.Polygon(foot_polygon(p, foot)) for p in poses]).convex_hull
    assert shapely.Polygon(hull).symmetric_difference(ref).area < 1e-12
    assert shapely.Polygon(hull).exterior.is_ccw


def test_signed_distance_on_a_unit_square():
    square = np.array([[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]])
    points = np.array([[0.5, 0.5], [0.2, 0.5], [0.5, 0.9], [1.5, 0.5], [2.0, 2.0], [1.0, 1.0], [-0.3, 0.4]])
    expected = [0.5, 0.2, 0.1, -0.5, -math.sqrt(2.0), 0.0, -0.3]
    np.testing.assert_allclose(polygon_signed_distance(points, square), expected, atol=1e-12)
    assert zmp_in_support(points, square, margin_m=0.15).tolist() == [True, True, False, False, False, False, False]
    assert zmp_in_support(points, square, margin_m=-0.35).tolist() == [True, True, True, False, False, True, True]
    out = polygon_signed_distance(torch.as_tensor(points).reshape(7, 1, 2), square)
    assert out.shape == (7, 1)
    np.testing.assert_allclose(out[:, 0].numpy(), expected, atol=1e-12)
    with pytest.raises(ValueError, match="counter-clockwise"):
        polygon_signed_distance(points, square[::-1])


def test_signed_distance_matches_shapely():
    shapely = pytest.importorskip("shapely")
    foot = FootShape(length_m=0.22, width_m=0.09, center_offset_m=(0.03, 0.0))
    hull = support_polygon([(0.0, 0.1, 0.3), (0.25, -0.1, -0.2)], foot)
    points = np.random.default_rng(0).uniform(-0.4, 0.6, size=(500, 2))
    poly = shapely.Polygon(hull)
    ref = [poly.exterior.distance(shapely.Point(p)) * (1 if poly.contains(shapely.Point(p)) else -1) for p in points]
    np.testing.assert_allclose(polygon_signed_distance(points, hull), ref, atol=1e-12)


# --------------------------------------------------------------------------- capture point
Z_OMEGA4 = G / 16.0  # a LIPM height with omega = 4 1/s exactly


def lipm(t, c0, v0, p, omega):
    """Closed-form LIPM with a constant ZMP p: (c(t), c_dot(t))."""
    t = np.asarray(t)[:, None]
    c = p + (c0 - p) * np.cosh(omega * t) + v0 / omega * np.sinh(omega * t)
    v = (c0 - p) * omega * np.sinh(omega * t) + v0 * np.cosh(omega * t)
    return c, v


def test_capture_point_of_a_known_lipm_state():
    c0, v0 = np.array([0.1, 0.0]), np.array([0.4, -0.2])
    xi = capture_point(c0, v0, Z_OMEGA4)
    np.testing.assert_allclose(xi, [0.2, -0.05], atol=1e-12)
    # holding the ZMP on the capture point brings the CoM to rest over it; 2 cm off, it runs away
    t = np.linspace(0.0, 3.0, 7)
    c, v = lipm(t, c0, v0, xi, 4.0)
    np.testing.assert_allclose(c[-1], xi, atol=1e-5)
    np.testing.assert_allclose(v[-1], 0.0, atol=1e-4)
    c_off, _ = lipm(t, c0, v0, xi + [0.02, 0.0], 4.0)
    assert abs(c_off[-1, 0] - xi[0]) > 1.0
    # the capture point of every state along that path stays put (it is the DCM's fixed point)
    np.testing.assert_allclose(capture_point(c, v, Z_OMEGA4), np.repeat(xi[None], len(t), 0), atol=1e-9)


def test_capture_region_hand_computed_and_simulated():
    # a 0.1 m square sole centred at (0.02, 0) (off the origin, so P and -P differ)
    stance = np.array([[-0.03, -0.05], [0.07, -0.05], [0.07, 0.05], [-0.03, 0.05]])
    step_time = math.log(2.0) / 4.0  # exp(omega T) = 2: reachable capture points 2 xi0 - P
    c0, v0 = np.array([0.1, 0.0]), np.array([0.4, 0.0])  # xi0 = (0.2, 0)
    region = capture_region(c0, v0, stance, com_height_m=Z_OMEGA4, step_time_s=step_time, max_reach_m=0.6)
    np.testing.assert_allclose(np.sort(region.capture_point_xy, 0),
                               [[0.33, -0.05], [0.33, -0.05], [0.43, 0.05], [0.43, 0.05]], atol=1e-12)
    assert region.contains([[0.38, 0.0], [0.42, 0.04], [0.3, 0.0], [0.38, 0.07]]).tolist() == [True, True, False, False]
    short = capture_region(c0, v0, stance, com_height_m=Z_OMEGA4, step_time_s=step_time, max_reach_m=0.3)
    assert not short.contains([0.38, 0.0])  # 0.36 m from the stance sole
    # a 0.1 x 0.1 sole covers the capture point from 5 cm further away
    wide = capture_region(c0, v0, stance, com_height_m=Z_OMEGA4, step_time_s=step_time, max_reach_m=0.6,
                          swing_foot=FootShape(length_m=0.1, width_m=0.1))
    assert wide.contains([[0.29, 0.0], [0.47, 0.09]]).tolist() == [True, True]
    assert not wide.contains([0.27, 0.0])
    # simulate: any constant CoP in the stance square gives a capture point at touchdown inside
    # the region's capture-point set, and the square's corners reach its corners
    cops = np.vstack([np.random.default_rng(1).uniform(-0.05, 0.05, (50, 2)) + [0.02, 0.0], stance])
    for cop in cops:
        c, v = lipm([step_time], c0, v0, cop, 4.0)
        xi_t = capture_point(c[0], v[0], Z_OMEGA4)
        assert polygon_signed_distance(xi_t, region.capture_point_xy) >= -1e-12
    corner_xi = capture_point(*lipm([step_time], c0, v0, stance[0], 4.0), Z_OMEGA4)[0]
    assert abs(polygon_signed_distance(corner_xi, region.capture_point_xy)) < 1e-12


# --------------------------------------------------------------------------- measured CoP
BOX_XML = """
<mujoco>
  <option timestep="0.002"/>
  <worldbody>
    <geom name="floor" type="plane" size="5 5 0.1" friction="1 0.005 0.0001"/>
    <body name="foot" pos="0.3 0.2 0.1" euler="0 0 0.4">
      <freejoint/>
      <geom type="box" size="0.1 0.06 0.1" mass="2"/>
    </body>
    <body name="crate" pos="-0.5 0 0.05">
      <freejoint/>
      <geom type="box" size="0.05 0.05 0.05" mass="6"/>
    </body>
  </worldbody>
</mujoco>
"""
FOOT_MASS, CRATE_MASS, FOOT_HALF_HEIGHT = 2.0, 6.0, 0.1


def settle(model, data, seconds=1.5):
    for _ in range(int(seconds / model.opt.timestep)):
        mujoco.mj_step(model, data)


def test_cop_of_a_resting_box_is_its_centre():
    model = mujoco.MjModel.from_xml_string(BOX_XML)
    data = mujoco.MjData(model)
    settle(model, data)
    foot = model.body("foot").id
    cop = CenterOfPressure(model, ["foot"])(data)
    assert cop.num_contacts == 4
    np.testing.assert_allclose(cop.cop_w[:2], data.xpos[foot, :2], atol=1e-3)
    assert cop.cop_w[2] == 0.0
    np.testing.assert_allclose(cop.force_w, [0.0, 0.0, FOOT_MASS * G], atol=1e-6)
    # both boxes: the mass-weighted mean of the two centres (the crate's contacts now count)
    both = CenterOfPressure(model, ["foot", model.body("crate").id])(data)
    expected = (FOOT_MASS * data.xpos[foot, :2] + CRATE_MASS * data.xpos[model.body("crate").id, :2]) / 8.0
    np.testing.assert_allclose(both.cop_w[:2], expected, atol=1e-3)
    with pytest.raises(ValueError, match="no body named 'hand'"):
        CenterOfPressure(model, ["hand"])


def push_at_height(model, engine_or_data, world, force_x, height):
    """Apply a horizontal force at ``height`` above the ground through the foot's CoM: the
    force plus its moment about the CoM, (height - CoM height) * F about y."""
    wrench = np.array([force_x, 0.0, 0.0, 0.0, (height - FOOT_HALF_HEIGHT) * force_x, 0.0])
    foot = model.body("foot").id
    if isinstance(engine_or_data, mujoco.MjData):
        engine_or_data.xfrc_applied[foot] = wrench
    else:
        engine_or_data.field("xfrc_applied")[world, foot] = torch.as_tensor(wrench)


def test_cop_shifts_by_f_h_over_mg_under_a_push():
    # moments about the CoP of a box at rest: m g (p - x_c) = F h, so p - x_c = F h / (m g)
    model = mujoco.MjModel.from_xml_string(BOX_XML)
    force, height = 3.0, 0.15
    shift = force * height / (FOOT_MASS * G)  # 22.9 mm
    data = mujoco.MjData(model)
    settle(model, data, 0.5)
    push_at_height(model, data, 0, force, height)
    settle(model, data, 1.0)
    cop = CenterOfPressure(model, ["foot"])(data)
    centre = data.xpos[model.body("foot").id, :2]
    np.testing.assert_allclose(cop.cop_w[:2] - centre, [shift, 0.0], atol=1e-3)
    np.testing.assert_allclose(cop.force_w, [-force, 0.0, FOOT_MASS * G], atol=1e-3)  # friction balances F


def test_cop_in_a_batch_of_worlds():
    model = mujoco.MjModel.from_xml_string(BOX_XML)
    engine = CpuEngine(model, num_worlds=3, num_threads=1)
    forces = [0.0, 3.0, -2.0]
    engine.step(250)
    for world, force in enumerate(forces):
        push_at_height(engine.model, engine, world, force, 0.15)
    engine.step(500)
    cop = CenterOfPressure(engine.model, ["foot"]).batch(engine)
    foot = engine.model.body("foot").id
    centre = engine.xpos[:, foot, :2].numpy()
    shift = np.array(forces) * 0.15 / (FOOT_MASS * G)
    np.testing.assert_allclose(cop[:, 0] - centre[:, 0], shift, atol=1e-3)
    np.testing.assert_allclose(cop[:, 1] - centre[:, 1], 0.0, atol=1e-3)
    # a world where the foot is lifted off the ground has no CoP
    engine.field("qpos")[0, 2] = 1.0
    engine.forward([0])
    assert np.isnan(CenterOfPressure(engine.model, ["foot"]).batch(engine, [0])).any()
