"""The grid of worlds and the overlays, read from viser's server-side scene (no browser): the
grid's bodies at their slot offsets, a contact arrow where a resting box touches the floor with
the box's weight, the box's CoM / ZMP / capture point, and the nodes features feed (plan,
footsteps, walked path, map, points, images with detections) at the positions they were given.
Waits are on conditions with generous limits; nothing asserts a duration."""

from __future__ import annotations

import time

import numpy as np
import pytest

pytest.importorskip("viser")
import ambulo.viewer
from ambulo.sim import World
from ambulo.viewer.geometry import is_ground
from ambulo.viewer.layout import grid_offsets_w
from ports import free_port

LIMIT_S = 120.0
BOX_XY_M = (0.5, 0.2)
BOX_HALF_M = 0.1



def nodes(viewer) -> dict:
    """viser's server-side scene graph: node name -> handle."""
    return viewer.page.server.scene._handle_from_node_name


def step_until(world, condition, what: str) -> None:
    """Step the world (each step may hand the streaming thread a frame) until ``condition()``."""
    deadline = time.monotonic() + LIMIT_S
    while not condition():
        assert time.monotonic() < deadline, f"timed out waiting for {what}"
        world.step(render=False)
        time.sleep(0.005)


@pytest.fixture
def world(box_world):
    w = box_world((*BOX_XY_M, BOX_HALF_M + 0.002), 2 * BOX_HALF_M, physics_dt=0.005, num_worlds=4)
    w.reset()
    for _ in range(200):  # 1 s: the box settles on the floor
        w.step(render=False)
    yield w
    World.clear_instance()


@pytest.fixture
def viewer(world):
    v = ambulo.viewer.serve(world, port=free_port(), announce=False, grid=4, process=False)
    v.controls.speed = None
    yield v
    v.close()


def box_body(viewer) -> int:
    return viewer.page._follow_body


def test_grid_draws_each_world_at_its_offset(world, viewer):
    grid = viewer.page.grid
    step_until(world, lambda: grid.count == 4 and viewer.frames_sent > 2, "a grid of 4 worlds")
    expected = grid_offsets_w(4, grid.spacing_m)
    assert grid.spacing_m >= 2.0 and np.allclose(expected[0], 0.0)
    box = box_body(viewer)
    (geom,) = [g for g in grid.geoms if int(grid.model.geom_bodyid[g]) == box]
    # one mesh for the 4 worlds: each instance at its world's offset + the box's pose in that world
    drawn = grid.instance_positions_w(geom)
    assert drawn.shape == (4, 3)
    np.testing.assert_allclose(drawn[:, :2] - expected[:, :2], np.tile(BOX_XY_M, (4, 1)), atol=0.01)
    (floor,) = [s for s in grid.shapes if is_ground(s)]  # drawn once, with its grid, not per world
    assert f"/ground/b{floor.body_id}/g{floor.geom_id}" in nodes(viewer) and floor.geom_id not in grid.geoms
    viewer.controls.show(1)  # back to one world: one instance each
    step_until(world, lambda: grid.count == 1 and len(grid.instance_positions_w(geom)) == 1, "one world")
    np.testing.assert_allclose(grid.instance_positions_w(geom)[0, :2], BOX_XY_M, atol=0.01)


def test_contact_arrows_carry_the_box_weight(world, viewer):
    viewer.page.overlays.contacts.value = True
    name = "/overlay/contacts"
    step_until(world, lambda: name in nodes(viewer) and nodes(viewer)[name].visible, "contact arrows")
    arrows = np.asarray(nodes(viewer)[name].points, dtype=float)  # (K, 2, 3) start, end
    start, end = arrows[:, 0], arrows[:, 1]
    assert np.all(np.abs(start[:, 2]) < 0.01)  # on the floor
    assert np.all(np.abs(start[:, :2] - BOX_XY_M) <= BOX_HALF_M + 0.01)  # under the box
    weight_n = float(viewer._model.body_mass[box_body(viewer)]) * 9.81
    total_n = (end - start).sum(axis=0) / 1e-3  # FORCE_SCALE_M_PER_N
    np.testing.assert_allclose(total_n, [0.0, 0.0, weight_n], atol=0.02 * weight_n)
    viewer.page.overlays.contacts.value = False
    step_until(world, lambda: not nodes(viewer)[name].visible, "the arrows hidden")


def test_balance_points_of_a_resting_box(world, viewer):
    viewer.page.overlays.balance.value = True
    names = [f"/overlay/balance/{k}" for k in ("com", "zmp", "capture_point")]
    step_until(world, lambda: all(n in nodes(viewer) for n in names), "the balance points")
    com, zmp, cp = (np.asarray(nodes(viewer)[n].position) for n in names)
    np.testing.assert_allclose(com, [*BOX_XY_M, BOX_HALF_M + 0.005], atol=0.005)  # drawn 5 mm up
    np.testing.assert_allclose(zmp, [*BOX_XY_M, 0.005], atol=0.005)  # the CoP under a resting box
    np.testing.assert_allclose(cp, [*BOX_XY_M, 0.005], atol=0.005)  # at rest: the CoM's ground point


def test_fed_layers_are_drawn_where_given(world, viewer):
    plan = np.array([[0.0, 0.0], [1.0, 0.0], [1.0, 2.0]])
    steps = np.array([[0.0, 0.1, 0.0], [0.3, -0.1, 0.5]])
    occupancy = np.zeros((4, 6), np.int8)
    occupancy[0, :] = 100
    cloud = np.array([[1.0, 2.0, 0.5], [2.0, 1.0, 0.3]])
    viewer.show_plan(plan)
    viewer.show_path(plan[:2])
    viewer.show_footsteps(steps, sides=[1, -1])
    viewer.show_map(occupancy, origin_xy_m=(-1.0, -2.0), resolution_m=0.5)
    viewer.show_points("lidar", cloud)
    image = np.zeros((40, 60, 3), np.uint8)
    viewer.show_image("front", image)
    viewer.show_detections("front", (np.array([[10, 5, 30, 25]]), ["chair"], np.array([0.9])))
    want = ["/overlay/plan", "/overlay/path", "/overlay/footsteps", "/overlay/map", "/overlay/points/lidar"]
    step_until(world, lambda: all(n in nodes(viewer) for n in want) and "front" in viewer.page.overlays._image_handles,
               "the fed layers")
    segments = np.asarray(nodes(viewer)["/overlay/plan"].points)
    np.testing.assert_allclose(segments[:, 0, :2], plan[:-1], atol=1e-6)
    np.testing.assert_allclose(segments[:, 1, :2], plan[1:], atol=1e-6)
    feet = nodes(viewer)["/overlay/footsteps"]
    np.testing.assert_allclose(np.asarray(feet.batched_positions)[:, :2], steps[:, :2], atol=1e-6)
    yaw = 2 * np.arctan2(np.asarray(feet.batched_wxyzs)[:, 3], np.asarray(feet.batched_wxyzs)[:, 0])
    np.testing.assert_allclose(yaw, steps[:, 2], atol=1e-5)
    np.testing.assert_allclose(nodes(viewer)["/overlay/map"].position[:2], (-1.0 + 1.5, -2.0 + 1.0), atol=1e-6)
    np.testing.assert_allclose(nodes(viewer)["/overlay/points/lidar"].points, cloud, atol=1e-6)
    shown = viewer.page.overlays._image_handles["front"].image
    assert shown[5, 20].tolist() != [0, 0, 0] and shown[15, 20].tolist() == [0, 0, 0]  # the box's edge, not inside


def test_map_image_puts_the_largest_y_on_top_and_unknown_clear():
    from ambulo.viewer.feed import MapLayer
    from ambulo.viewer.overlays import map_image

    occupancy = np.array([[100, 0], [-1, 0]], np.int8)  # row 0: y = origin (the bottom of the map)
    rgba = map_image(MapLayer(occupancy=occupancy, origin_xy_m=(0.0, 0.0), resolution_m=1.0))
    assert rgba[1, 0, 0] < rgba[1, 1, 0]  # bottom-left (occupied) darker than bottom-right (free)
    assert rgba[0, 0, 3] == 0 and rgba[0, 1, 3] > 0  # top-left unknown: clear


def test_camera_overlay_renders_a_world_camera_on_the_streaming_thread(box_world):
    from ambulo.sim.camera import Camera

    w = box_world((0.0, 0.0, 0.1), physics_dt=0.005)
    # looking straight down (Isaac's camera axes: +X forward, turned +90 deg about y): the sensor puts
    # this pose into the world's own row of the model's cameras, which the viewer must copy
    w.scene.add(Camera("/World/cam", position=[0.0, 0.0, 3.0], orientation=[0.7071068, 0.0, 0.7071068, 0.0],
                       resolution=(64, 48)))
    w.reset()
    v = ambulo.viewer.serve(w, port=free_port(), announce=False, process=False)
    try:
        overlays = v.page.overlays
        assert overlays.camera_name.options == ("/World/cam",)
        overlays.camera_kind.value = "depth"
        overlays.camera.value = True
        def centre():
            return None if overlays.camera_image is None else np.asarray(overlays.camera_image.image)[120, 160]

        # the box's top 2.8 m below the camera: a depth colour at the centre (black is no return)
        step_until(w, lambda: centre() is not None and centre().any(), "the box in the camera's depth image")
    finally:
        v.close()
        World.clear_instance()
    assert overlays._renders is None  # freed by the streaming thread that owned its GL context


def test_a_lidars_last_scan_is_drawn_without_feeding_it(box_world):
    from ambulo.sensors import Lidar, LidarCfg

    w = box_world((*BOX_XY_M, BOX_HALF_M + 0.002), 2 * BOX_HALF_M, physics_dt=0.005)
    # 12 rays 30 deg below the horizon from 0.6 m up: they meet the floor 0.6 / tan 30 deg away
    lidar = Lidar(LidarCfg(prim_path="/World/Box", offset_pos=(0.0, 0.0, 0.5), elevations_deg=(-30.0,),
                           horizontal_resolution_deg=30.0))
    w.scene.add(lidar)
    w.reset()
    v = ambulo.viewer.serve(w, port=free_port(), announce=False, process=False)
    name = "/overlay/points/lidar_World_Box"
    try:
        v.controls.speed = None
        step_until(w, lambda: v.frames_sent > 3, "a few frames")
        assert name not in nodes(v)  # no scan yet: the viewer casts no rays of its own
        scan = lidar.get_current_frame()
        step_until(w, lambda: name in nodes(v), "the lidar's points")
        points = np.asarray(nodes(v)[name].points, dtype=float)
        origin = scan.points_w[0, 0].numpy() - scan.points_s[0, 0].numpy()  # (a level box: no rotation)
        assert points.shape == (12, 3)
        np.testing.assert_allclose(points[:, 2], 0.0, atol=1e-3)
        np.testing.assert_allclose(np.hypot(*(points[:, :2] - origin[:2]).T), origin[2] / np.tan(np.radians(30.0)),
                                   atol=1e-3)
    finally:
        v.close()
        World.clear_instance()


def test_balance_ground_is_the_floor_not_every_fixed_geom():
    import mujoco

    from ambulo.viewer.physics_overlay import BalanceProbe

    model = mujoco.MjModel.from_xml_string("""
    <mujoco><worldbody>
      <geom name="floor" type="plane" size="5 5 0.1"/>
      <geom name="rug" type="box" size="0.5 0.5 0.005" pos="1 0 0.005"/>
      <geom name="wall" type="box" size="0.05 2 1.2" pos="2 0 1.2"/>
      <geom name="table" type="box" size="0.4 0.4 0.02" pos="-1 0 0.75"/>
      <geom name="picture" type="plane" size="0.3 0.3 0.1" pos="1.9 0 1.5" zaxis="-1 0 0"/>
      <body name="robot" pos="0 0 0.5"><freejoint/><geom name="foot" type="box" size="0.1 0.1 0.1"/></body>
    </worldbody></mujoco>""")
    robot = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, "robot")
    probe = BalanceProbe(model, robot, [robot])
    names = {mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_GEOM, int(g)) for g in probe.cop.ground_geom_ids}
    assert names == {"floor", "rug"} and probe.cop.ground_height_m == 0.0
