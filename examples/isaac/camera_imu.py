"""A standalone Isaac Sim script with sensors: a camera looking at a cube that carries an IMU.

Written with Isaac Sim's module names only. Run it with `ambulo run examples/isaac/camera_imu.py`
(or with Isaac Sim's python.sh). The cube (0.5 m edge) rests on the ground 2 m in front of the
camera, so the camera's centre pixel sees its face 1.75 m away, and the IMU on the cube reads
gravity's reaction, +9.81 m/s^2 up.
"""

from isaacsim import SimulationApp

simulation_app = SimulationApp({"headless": True})

import numpy as np  # Isaac modules can be imported only after the app starts
from isaacsim.core.api import World
from isaacsim.core.api.objects import DynamicCuboid
from isaacsim.core.utils.rotations import euler_angles_to_quat
from isaacsim.sensors.camera import Camera
from isaacsim.sensors.physics import IMUSensor

world = World(stage_units_in_meters=1.0)
world.scene.add_default_ground_plane()
cube = world.scene.add(
    DynamicCuboid(
        prim_path="/World/cube",
        name="cube",
        position=np.array([0.0, 2.0, 0.25]),
        scale=np.array([0.5, 0.5, 0.5]),
        color=np.array([0.8, 0.2, 0.1]),
    )
)
# "world" camera axes: +X forward, +Z up; a 90 deg yaw turns the camera to look along +Y
camera = Camera(
    prim_path="/World/camera",
    position=np.array([0.0, 0.0, 0.25]),
    frequency=20,
    resolution=(64, 48),
    orientation=euler_angles_to_quat(np.array([0.0, 0.0, 90.0]), degrees=True),
)
imu = world.scene.add(IMUSensor(prim_path="/World/cube/imu_sensor", name="imu", frequency=100))

world.reset()
camera.initialize()
camera.add_distance_to_image_plane_to_frame()
camera.add_pointcloud_to_frame()

for i in range(60):
    world.step(render=True)
    if i % 20 == 19:
        reading = imu.get_current_frame()
        print(f"t={reading['time']:.2f} s imu lin_acc {np.round(reading['lin_acc'], 2)} "
              f"ang_vel {np.round(reading['ang_vel'], 2)}")

frame = camera.get_current_frame()
depth = camera.get_depth()
width, height = camera.get_resolution()
print(f"frame keys: {sorted(frame)}")
print(f"rgba {frame['rgba'].shape} {frame['rgba'].dtype}, rendered at t={frame['rendering_time']:.2f} s")
print(f"centre depth: {depth[height // 2, width // 2]:.3f} m")
points = camera.get_pointcloud()
above_ground = points[points[:, 2] > 0.05]  # the rest is the ground below the cube
print(f"pointcloud: {len(points)} points; cube face at y = {above_ground[:, 1].min():.3f} m")
position, orientation = camera.get_world_pose(camera_axes="ros")
print(f"camera ros orientation (w, x, y, z): {np.round(orientation, 3)}")
print(f"intrinsics:\n{np.round(camera.get_intrinsics_matrix(), 2)}")
simulation_app.close()
