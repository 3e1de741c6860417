"""Sensors registered on a World through world.scene.add, as in the Isaac tutorials."""

import numpy as np
import pytest

from ambulo import assets
from ambulo.sensors import Camera, Imu
from ambulo.sim import DynamicCuboid, Robot, World, add_reference_to_stage


def test_world_builds_and_initializes_sensors_on_robot_prims():
    world = World()
    world.scene.add_default_ground_plane()
    add_reference_to_stage(usd_path=assets.path("humanoid"), prim_path="/World/Humanoid")
    humanoid = world.scene.add(Robot(prim_path="/World/Humanoid"))
    world.scene.add(DynamicCuboid(prim_path="/World/crate", position=[1.5, 0, 0.2], size=0.4,
                                  semantic_label="crate"))
    imu = world.scene.add(Imu(prim_path="/World/Humanoid/imu"))
    camera = world.scene.add(Camera(prim_path="/World/Humanoid/head_camera_mount/camera",
                                    annotators=("rgb", "depth", "semantic_segmentation")))
    world.reset()
    for _ in range(20):
        world.step()
    frame = camera.get_current_frame()
    rgb = np.asarray(frame["rgb"])
    assert rgb.shape[-3:] == (240, 320, 3) and rgb.std() > 1.0
    depth = np.asarray(frame["depth"]).reshape(240, 320)
    floor = depth[-1]  # the bottom row sees the ground in front of the robot (the sky is inf)
    assert np.isfinite(floor).all() and (floor > 0.3).all() and (floor < 10).all()
    reading = imu.get_current_frame()
    acc = reading.lin_acc_b[0].numpy()
    assert acc[2] == pytest.approx(9.81, abs=0.05)  # standing still: gravity on the up axis
    assert humanoid.num_dof == 21
