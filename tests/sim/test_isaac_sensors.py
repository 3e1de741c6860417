"""Isaac's Camera, IMUSensor and ContactSensor on ambulo, checked against physics and hand math."""

import math
import re
from pathlib import Path

import numpy as np
import pytest

from ambulo.isaac import run_script
from ambulo.sim import DynamicCuboid, FixedCuboid, World
from ambulo.sim.base_sensor import due
from ambulo.sim.camera import Camera
from ambulo.sim.camera_axes import quat_from_usd, quat_to_usd
from ambulo.sim.contact_sensor import ContactSensor
from ambulo.sim.current import set_current_world
from ambulo.sim.imu_sensor import IMUSensor

G = 9.81
W, H = 64, 48
CUBE_X, CUBE_SIZE = 3.0, 0.5  # a fixed cube centred 3 m ahead of the camera, at its height
ROS_OF_WORLD_IDENTITY = np.array([0.5, -0.5, 0.5, -0.5])  # x fwd/z up -> z fwd/y down, by hand
USD_OF_WORLD_IDENTITY = np.array([0.5, 0.5, -0.5, -0.5])  # x fwd/z up -> -z fwd/y up, by hand


def same_rotation(q1, q2, tol=1e-5) -> bool:
    return abs(abs(float(np.dot(q1, q2))) - 1.0) < tol


def quat_about(axis, deg):
    half = math.radians(deg) / 2
    return np.array([math.cos(half), *(math.sin(half) * np.asarray(axis, float))])


@pytest.fixture(scope="module")
def scene():
    world = World(physics_dt=0.01)
    world.scene.add_default_ground_plane()
    world.scene.add(FixedCuboid(prim_path="/World/target", position=[CUBE_X, 0.0, 1.0], size=CUBE_SIZE,
                                semantic_label="cube"))
    camera = Camera("/World/camera", position=[0.0, 0.0, 1.0], orientation=[1, 0, 0, 0], resolution=(W, H))
    world.reset()
    camera.initialize()
    for add in (camera.add_distance_to_image_plane_to_frame, camera.add_semantic_segmentation_to_frame,
                camera.add_instance_segmentation_to_frame, camera.add_bounding_box_2d_tight_to_frame,
                camera.add_pointcloud_to_frame):
        add()
    world.step()
    return world, camera


def test_frame_has_isaacs_keys_shapes_and_replicator_ids(scene):
    world, camera = scene
    frame = camera.get_current_frame()
    assert {"rendering_time", "rendering_frame", "rgba", "distance_to_image_plane", "semantic_segmentation",
            "instance_segmentation", "bounding_box_2d_tight", "pointcloud"} <= set(frame)
    assert frame["rendering_time"] == pytest.approx(world.current_time) and frame["rendering_frame"] == 1
    assert frame["rgba"].shape == (H, W, 4) and frame["rgba"].dtype == np.uint8 and (frame["rgba"][..., 3] == 255).all()
    assert camera.get_rgb().shape == (H, W, 3) and camera.get_rgb().std() > 1.0
    assert frame["distance_to_image_plane"].shape == (H, W) and frame["distance_to_image_plane"].dtype == np.float32
    semantic = frame["semantic_segmentation"]
    assert semantic["data"].shape == (H, W) and semantic["data"].dtype == np.uint32
    assert semantic["info"]["idToLabels"] == {"0": {"class": "BACKGROUND"}, "1": {"class": "UNLABELLED"},
                                              "2": {"class": "cube"}}
    # the cube in the centre, the unlabelled ground in the bottom row, the sky in the top row
    assert semantic["data"][H // 2, W // 2] == 2 and (semantic["data"][-1] == 1).all() and (semantic["data"][0] == 0).all()
    instance = frame["instance_segmentation"]
    assert instance["info"]["idToLabels"]["2"] == "/World/target" and instance["data"][H // 2, W // 2] == 2
    boxes = frame["bounding_box_2d_tight"]
    assert boxes["data"].dtype.names == ("semanticId", "x_min", "y_min", "x_max", "y_max", "occlusionRatio")
    assert boxes["info"]["primPaths"] == ["/World/target"] and boxes["data"]["occlusionRatio"][0] == pytest.approx(0.0)
    cloud = frame["pointcloud"]
    assert cloud["data"].ndim == 2 and cloud["data"].shape[1] == 3 and cloud["info"]["pointRgb"].shape[1] == 4


def test_depth_and_pointcloud_see_the_cube_face_where_it_is(scene):
    _, camera = scene
    depth = camera.get_depth()
    face_x = CUBE_X - CUBE_SIZE / 2
    assert depth[H // 2, W // 2] == pytest.approx(face_x, abs=2e-3)  # the camera sits at x = 0
    cloud = camera.get_current_frame()["pointcloud"]
    face = cloud["data"][cloud["info"]["pointInstance"] == 2]
    assert len(face) > 100 and np.allclose(face[:, 0], face_x, atol=2e-3)
    assert np.abs(face[:, 1]).max() == pytest.approx(CUBE_SIZE / 2, abs=0.03)  # its edges, to about a pixel
    from_depth = camera.get_pointcloud()  # annotator data; the depth-based fallback must agree
    camera.remove_pointcloud_from_frame()
    fallback = camera.get_pointcloud()
    camera.add_pointcloud_to_frame(include_unlabelled=False)  # the cube only, not the ground
    labelled = camera.get_pointcloud()
    camera.remove_pointcloud_from_frame()
    camera.add_pointcloud_to_frame()
    assert len(labelled) == len(face) < len(from_depth) and np.allclose(labelled[:, 0], face_x, atol=2e-3)
    assert len(fallback) == len(from_depth) and np.allclose(np.sort(fallback[:, 0]), np.sort(from_depth[:, 0]), atol=1e-4)
    ros = camera.get_pointcloud(world_frame=False)  # z forward in the ROS camera frame
    assert ros[:, 2].min() == pytest.approx(face_x, abs=2e-3)


def test_intrinsics_follow_focal_length_aperture_and_resolution_and_the_render_does_too(scene):
    world, camera = scene
    f, aperture = camera.get_focal_length(), camera.get_horizontal_aperture()
    assert (f, aperture) == (5.0, 2.0955)  # a new USD camera: focalLength 50, horizontalAperture 20.955
    fx = W * f / aperture
    expected = np.array([[fx, 0, W / 2], [0, fx, H / 2], [0, 0, 1]])
    assert np.allclose(camera.get_intrinsics_matrix(), expected, rtol=1e-6)
    assert camera.get_horizontal_fov() == pytest.approx(2 * math.atan(aperture / (2 * f)))
    assert camera.get_vertical_fov() == pytest.approx(2 * math.atan(aperture * H / W / (2 * f)))

    def box_width_px():
        world.step()
        row = camera.get_current_frame()["bounding_box_2d_tight"]["data"][0]
        return row["x_max"] - row["x_min"] + 1

    face_distance = CUBE_X - CUBE_SIZE / 2
    assert box_width_px() == pytest.approx(fx * CUBE_SIZE / face_distance, abs=1.5)
    camera.set_focal_length(f / 2)  # half the focal length: the cube looks half as wide
    assert camera.get_intrinsics_matrix()[0, 0] == pytest.approx(fx / 2)
    assert box_width_px() == pytest.approx(fx / 2 * CUBE_SIZE / face_distance, abs=1.5)
    camera.set_focal_length(f)
    camera.set_resolution((2 * W, 2 * H))  # twice the pixels over the same field of view
    assert camera.get_current_frame()["rgba"].shape == (2 * H, 2 * W, 4)
    assert camera.get_intrinsics_matrix()[0, 0] == pytest.approx(2 * fx)
    camera.set_resolution((W, H))
    assert camera.get_clipping_range() == (1.0, 1.0e6)
    camera.set_clipping_range(far_distance=2.0)  # the cube face at 2.75 m is now beyond the far plane
    world.step()
    assert not np.isfinite(camera.get_depth()[H // 2, W // 2])
    camera.set_clipping_range(far_distance=1.0e6)


def test_camera_axes_conversions_round_trip_and_match_hand_computed_quaternions(scene):
    world, camera = scene
    _, q_world = camera.get_world_pose()
    assert same_rotation(q_world, [1, 0, 0, 0])
    assert same_rotation(camera.get_world_pose(camera_axes="ros")[1], ROS_OF_WORLD_IDENTITY)
    assert same_rotation(camera.get_world_pose(camera_axes="usd")[1], USD_OF_WORLD_IDENTITY)
    rng = np.random.default_rng(0)
    for axes in ("world", "ros", "usd"):
        q = rng.normal(size=4)
        q /= np.linalg.norm(q)
        assert same_rotation(quat_from_usd(quat_to_usd(q, axes), axes), q)
    # looking at the cube from 1 m closer, given as a ROS orientation: the face is 1 m nearer
    camera.set_world_pose(position=[1.0, 0.0, 1.0], orientation=ROS_OF_WORLD_IDENTITY, camera_axes="ros")
    position, q = camera.get_world_pose()
    assert np.allclose(position, [1, 0, 1]) and same_rotation(q, [1, 0, 0, 0])
    world.step()
    assert camera.get_depth()[H // 2, W // 2] == pytest.approx(CUBE_X - CUBE_SIZE / 2 - 1.0, abs=2e-3)
    camera.set_local_pose(translation=[0.0, 0.0, 1.0], orientation=[1, 0, 0, 0])
    with pytest.raises(ValueError, match="camera_axes"):
        camera.get_world_pose(camera_axes="opencv")


def test_camera_on_a_body_and_its_render_rate():
    world = World(physics_dt=0.01)
    world.scene.add(FixedCuboid(prim_path="/World/mast", position=[1.0, 2.0, 0.5], size=0.1))
    yaw = quat_about([0, 0, 1], 90)
    camera = Camera("/World/mast/cam", frequency=20, translation=[0.0, 0.0, 0.3], orientation=yaw, resolution=(8, 6))
    world.reset()
    camera.initialize()
    position, q = camera.get_world_pose()
    assert np.allclose(position, [1.0, 2.0, 0.8]) and same_rotation(q, yaw)
    translation, q_local = camera.get_local_pose()
    assert np.allclose(translation, [0, 0, 0.3]) and same_rotation(q_local, yaw)
    times = set()
    for _ in range(12):  # read every 0.01 s: the 20 Hz camera renders once in each 0.05 s period
        world.step()
        times.add(round(camera.get_current_frame()["rendering_time"], 6))
    assert sorted(times) == [0.01, 0.05, 0.1]
    assert camera.get_frequency() == pytest.approx(20.0) and camera.get_dt() == pytest.approx(0.05)
    world.reset()
    camera.initialize()  # Isaac scripts call it again after a reset
    assert camera.get_current_frame()["rendering_time"] == 0.0


def test_sensor_lifecycle_errors_name_the_fix_and_initialize_reattaches_rgb():
    set_current_world(None)
    orphan = IMUSensor("/World/box/imu")
    with pytest.raises(RuntimeError, match="create the World"):
        orphan.initialize()
    world = resting_box_world()
    IMUSensor("/World/box/imu", name="imu")
    with pytest.raises(ValueError, match="unique name"):
        IMUSensor("/World/box/imu2", name="imu")
    world.reset()
    late = Camera("/World/late_camera", resolution=(8, 6))
    with pytest.raises(RuntimeError, match="call world.reset"):
        late.initialize()
    world.reset()  # the stage changed: it is recompiled with the camera in it
    late.initialize()
    world.step()
    late.remove_rgb_from_frame()
    assert late.get_rgba() is None and "rgba" not in late.get_current_frame()
    late.initialize()  # as Isaac's, it attaches the rgb annotator again
    assert late.get_rgba().shape == (6, 8, 4)


def test_samples_fall_on_the_grid_of_periods_and_restart_with_the_clock():
    assert due(None, 0.0, 0.05) and not due(0.01, 0.04, 0.05) and due(0.04, 0.05, 0.05)
    assert due(0.04, 0.01, 0.05)  # a reset clock: the old sample is from another run
    assert due(0.01, 0.011, 0.0) and not due(0.01, 0.01, 0.0)


def resting_box_world():
    world = World(physics_dt=0.005)
    world.scene.add_default_ground_plane()
    world.scene.add(DynamicCuboid(prim_path="/World/box", position=[0.0, 0.0, 0.1], size=0.2, mass=2.0))
    return world


def test_imu_at_rest_reads_gravity_only_with_read_gravity_in_its_own_frame():
    world = resting_box_world()
    imu = world.scene.add(IMUSensor("/World/box/imu", name="imu"))
    tilted = IMUSensor("/World/box/tilted", name="tilted", orientation=quat_about([1, 0, 0], 90))
    world.reset()
    imu.initialize()
    for _ in range(60):
        world.step()
    frame = dict(imu.get_current_frame())
    assert set(frame) >= {"time", "physics_step", "lin_acc", "ang_vel", "orientation"}
    assert frame["lin_acc"].dtype == np.float32 and frame["orientation"].shape == (4,)
    assert np.allclose(frame["lin_acc"], [0, 0, G], atol=0.02) and np.allclose(frame["ang_vel"], 0, atol=1e-3)
    assert same_rotation(frame["orientation"], [1, 0, 0, 0], tol=1e-6)
    assert frame["time"] == pytest.approx(world.current_time) and frame["physics_step"] == 60.0
    assert np.allclose(imu.get_current_frame(read_gravity=False)["lin_acc"], 0, atol=0.02)
    # sensor z along world -y (90 deg about x): R^T (0, 0, g) = (0, g, 0), by hand
    assert np.allclose(tilted.get_current_frame()["lin_acc"], [0, G, 0], atol=0.02)
    assert np.allclose(tilted.get_current_frame(read_gravity=False)["lin_acc"], 0, atol=0.02)


def test_imu_rate_and_rolling_average_filter():
    world = World(physics_dt=0.005)
    world.scene.add_default_ground_plane()
    world.scene.add(DynamicCuboid(prim_path="/World/box", position=[0.0, 0.0, 0.3], size=0.2, mass=2.0,
                                  orientation=quat_about([1, 1, 0], 40)))  # lands on a corner and tips over
    raw = IMUSensor("/World/box/raw", name="raw")
    filtered = IMUSensor("/World/box/filtered", name="filtered", linear_acceleration_filter_size=4,
                         orientation_filter_size=3)
    slow = IMUSensor("/World/box/slow", name="slow", frequency=50)
    world.reset()
    history, quats = [], []
    for _ in range(80):  # the box falls and lands: the readings change
        world.step()
        history.append(raw.get_current_frame()["lin_acc"].copy())
        quats.append(raw.get_current_frame()["orientation"].astype(float))
        if len(history) >= 4:
            assert np.allclose(filtered.get_current_frame()["lin_acc"], np.mean(history[-4:], 0), atol=1e-4)
            mean = np.mean(quats[-3:], 0)
            assert np.allclose(filtered.get_current_frame()["orientation"], mean / np.linalg.norm(mean), atol=1e-5)
    assert np.ptp(np.array(history)[:, 2]) > 5.0  # free fall (0) then rest (g): the filter saw both
    assert 1 - abs(np.dot(quats[0], quats[-1])) > 1e-5  # and a turning orientation (about 1 deg)
    for _ in range(3):  # 0.415 s: the 50 Hz IMU sampled last at 0.40 s
        world.step()
    assert slow.get_current_frame()["time"] == pytest.approx(0.40) and slow.get_frequency() == 50
    slow.pause()
    world.step()
    assert slow.is_paused() and slow.get_current_frame()["time"] == pytest.approx(0.40)


def test_contact_sensor_under_a_resting_box_reads_its_weight():
    world = World(physics_dt=0.005)
    world.scene.add_default_ground_plane()
    world.scene.add(DynamicCuboid(prim_path="/World/box", position=[0.0, 0.0, 0.5], size=0.2, mass=2.0))
    sensor = world.scene.add(ContactSensor("/World/box/contact_sensor", name="box_contact"))
    strict = ContactSensor("/World/box/strict", name="strict", min_threshold=100.0)
    capped = ContactSensor("/World/box/capped", name="capped", max_threshold=5.0)
    world.reset()
    world.step()
    falling = dict(sensor.get_current_frame())
    assert falling["in_contact"] is False and falling["force"] == 0.0 and falling["number_of_contacts"] == 0
    for _ in range(300):
        world.step()
    frame = sensor.get_current_frame()
    assert set(frame) >= {"time", "physics_step", "in_contact", "force", "number_of_contacts"}
    assert frame["in_contact"] is True and frame["number_of_contacts"] >= 1
    assert frame["force"] == pytest.approx(2.0 * G, rel=0.03)
    assert frame["time"] == pytest.approx(world.current_time) and frame["physics_step"] == 301.0
    assert strict.get_current_frame()["in_contact"] is False  # 19.6 N is under its 100 N threshold
    assert capped.get_current_frame()["force"] == 5.0


def test_camera_imu_example_runs_as_an_isaac_script_and_reads_physics(capsys):
    result = run_script(Path(__file__).resolve().parents[2] / "examples" / "isaac" / "camera_imu.py")
    out = capsys.readouterr().out
    assert result.physics_steps == 60
    last_acc = re.findall(r"imu lin_acc \[([^\]]+)\]", out)[-1]
    assert np.allclose(np.array(last_acc.split(), float), [0, 0, G], atol=0.02)
    assert float(re.search(r"centre depth: ([\d.]+) m", out).group(1)) == pytest.approx(1.75, abs=0.005)
    assert float(re.search(r"cube face at y = ([\d.]+) m", out).group(1)) == pytest.approx(1.75, abs=0.005)
    ros = np.array(re.search(r"ros orientation \(w, x, y, z\): \[([^\]]+)\]", out).group(1).split(), float)
    assert same_rotation(ros, [math.sqrt(0.5), -math.sqrt(0.5), 0, 0], tol=1e-3)  # yaw 90 deg, by hand
    assert "rgba (48, 64, 4) uint8" in out and "'rendering_time'" in out
