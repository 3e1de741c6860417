"""Lidar ranges against walls at known distances; foot contact of a standing humanoid."""

import math

import mujoco
import numpy as np
import pytest

from ambulo import assets
from ambulo.engine import CpuEngine
from ambulo.sensors import ContactSensor, Lidar, LidarCfg, lidar_vlp16

BOX = mujoco.mjtGeom.mjGEOM_BOX


def walled_room(sensor, num_worlds=1):
    """Sensor post at the origin, 0.5 m up; walls whose near faces are at x=+2.5, y=+1.5, x=-4."""
    spec = mujoco.MjSpec()
    spec.worldbody.add_geom(type=mujoco.mjtGeom.mjGEOM_PLANE, size=[10, 10, 0.1])
    spec.worldbody.add_geom(type=BOX, pos=[2.6, 0, 1], size=[0.1, 5, 1])
    spec.worldbody.add_geom(type=BOX, pos=[0, 1.6, 1], size=[5, 0.1, 1])
    spec.worldbody.add_geom(type=BOX, pos=[-4.1, 0, 1], size=[0.1, 5, 1])
    post = spec.worldbody.add_body(name="/World/post", pos=[0, 0, 0.5])
    post.add_geom(type=mujoco.mjtGeom.mjGEOM_CYLINDER, size=[0.05, 0.05])
    sensor.build(spec)
    engine = CpuEngine(spec.compile(), num_worlds, num_threads=1)
    sensor.initialize(engine)
    return engine, sensor


def test_2d_scan_ranges_to_walls_within_1cm():
    _engine, lidar = walled_room(Lidar(LidarCfg(prim_path="/World/post/lidar", horizontal_resolution_deg=1.0)))
    data = lidar.get_current_frame()
    assert tuple(data.ranges.shape) == (1, 1, 360)
    scan = data.ranges[0, 0].numpy()
    assert scan[0] == pytest.approx(2.5, abs=0.01)      # +x
    assert scan[90] == pytest.approx(1.5, abs=0.01)     # +y
    assert scan[180] == pytest.approx(4.0, abs=0.01)    # -x
    assert scan[30] == pytest.approx(2.5 / math.cos(math.radians(30)), abs=0.01)
    assert not data.hit[0, 0, 270]                      # -y is open up to 10 m: floor-parallel miss
    assert scan[270] == lidar.cfg.max_range_m
    # returned points lie on the walls
    points = data.points_w[0].numpy()
    assert points[0] == pytest.approx([2.5, 0, 0.5], abs=0.01)


def test_3d_channels_follow_elevation_and_noise_is_seeded():
    cfg = lidar_vlp16("/World/post/lidar", range_noise_std_m=0.0, horizontal_resolution_deg=1.0)
    _engine, lidar = walled_room(Lidar(cfg))
    data = lidar.get_current_frame()
    v, h = lidar.shape
    assert (v, h) == (16, 360)
    elevation = lidar.elevations_rad
    expected = 2.5 / np.cos(elevation)
    # channels below -11 deg hit the floor (0.5 m down) before the wall
    floor = 0.5 / np.sin(-elevation)
    expected = np.where((elevation < 0) & (floor < expected), floor, expected)
    assert np.allclose(data.ranges[0, :, 0].numpy(), expected, atol=0.01)
    noisy = [Lidar(lidar_vlp16("/World/post/lidar", seed=5, horizontal_resolution_deg=1.0)) for _ in range(2)]
    scans = [walled_room(n)[1].get_current_frame().ranges for n in noisy]
    assert np.array_equal(scans[0].numpy(), scans[1].numpy())
    assert 0.01 < np.std(scans[0].numpy() - data.ranges.numpy()) < 0.05


def test_standing_humanoid_feet_touch_and_airborne_ones_do_not():
    spec = mujoco.MjSpec.from_file(assets.path("humanoid"))
    spec.worldbody.add_geom(type=mujoco.mjtGeom.mjGEOM_PLANE, size=[10, 10, 0.1])
    feet = ContactSensor(prim_paths=("left_foot", "right_foot"))
    feet.build(spec)
    model = spec.compile()
    engine = CpuEngine(model, 2, num_threads=1)
    feet.initialize(engine)
    engine.qpos[1, 2] += 1.0  # world 1 starts 1 m up
    engine.forward()
    for _ in range(5):
        engine.step()
    data = feet.get_current_frame()
    assert data.in_contact[0].all() and not data.in_contact[1].any()
    assert (data.num_contacts[0] > 0).all() and (data.num_contacts[1] == 0).all()
    # the floor pushes up on the feet; the total is of the order of the robot's weight
    weight = model.body_subtreemass[model.body("pelvis").id] * 9.81
    up = data.net_force_w[0, :, 2].sum().item()
    assert (data.net_force_w[0, :, 2] > 0).all() and 0.5 * weight < up < 2.0 * weight
    assert np.allclose(data.net_force_w[1].numpy(), 0)


def test_contact_sensor_names_missing_bodies():
    spec = mujoco.MjSpec.from_file(assets.path("humanoid"))
    with pytest.raises(ValueError, match="no body matches 'left_hoof'"):
        ContactSensor(prim_paths=("left_hoof",)).build(spec)


@pytest.mark.parametrize("right_half_body", ["ground", "step"])
def test_against_body_counts_contacts_with_each_geom_of_that_body_only(right_half_body):
    """The feet stand on two halves (as a terrain's hfield and boxes): ``against_body`` counts a
    foot on any geom of that body, and none on another body's; ``against`` one geom counts only the
    foot on that geom."""
    spec = mujoco.MjSpec.from_file(assets.path("humanoid"))
    ground = spec.worldbody.add_body(name="ground")
    other = ground if right_half_body == "ground" else spec.worldbody.add_body(name=right_half_body)
    ground.add_geom(name="ground/left", type=mujoco.mjtGeom.mjGEOM_BOX, size=[5, 0.5, 0.1], pos=[0, 0.5, -0.1])
    other.add_geom(name="ground/right", type=mujoco.mjtGeom.mjGEOM_BOX, size=[5, 0.5, 0.1], pos=[0, -0.5, -0.1])
    body = ContactSensor(prim_paths=("left_foot", "right_foot"), against_body="ground", name="body")
    left = ContactSensor(prim_paths=("left_foot", "right_foot"), against="ground/left", name="left")
    for sensor in (body, left):
        sensor.build(spec)
    model = spec.compile()
    engine = CpuEngine(model, 1, num_threads=1)
    for sensor in (body, left):
        sensor.initialize(engine)
    engine.forward()
    data = engine.get_data(0)
    assert data.xpos[model.body("left_foot").id][1] > 0 > data.xpos[model.body("right_foot").id][1]  # halves meet at y = 0
    for _ in range(5):
        engine.step()
    on_body, on_left = body.get_current_frame().in_contact[0], left.get_current_frame().in_contact[0]
    assert on_body.tolist() == [True, right_half_body == "ground"]
    assert on_left.tolist() == [True, False]


def test_against_and_against_body_together_are_refused_in_one_line():
    with pytest.raises(ValueError, match="give one of against and against_body"):
        ContactSensor(prim_paths=("left_foot",), against="ground/left", against_body="ground")
