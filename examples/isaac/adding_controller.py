"""A standalone Isaac Sim script (the "Adding a Controller" flow): a custom controller drives a Jetbot.

Written with Isaac Sim's module names only. Run it with `ambulo run examples/isaac/adding_controller.py`
(or with Isaac Sim's python.sh). `OpenLoopUnicycle` subclasses Isaac's `BaseController`: it turns a
(forward m/s, yaw rad/s) command into wheel speeds with the differential-drive model
w_left = (v - yaw_rate * L / 2) / r, w_right = (v + yaw_rate * L / 2) / r. Driven at 0.2 m/s and
pi/4 rad/s, the Jetbot follows a circle of radius v / yaw_rate = 0.255 m, so after 2 s it has turned
by pi/2 and stays within that circle's diameter of its start.
"""

from isaacsim import SimulationApp

simulation_app = SimulationApp({"headless": True})

import math  # Isaac modules can be imported only after the app starts

import numpy as np
from isaacsim.core.api import World
from isaacsim.core.api.controllers import BaseController
from isaacsim.core.utils.nucleus import get_assets_root_path
from isaacsim.core.utils.types import ArticulationAction
from isaacsim.robot.wheeled_robots.robots import WheeledRobot


class OpenLoopUnicycle(BaseController):
    """(v m/s, yaw rate rad/s) -> wheel velocities (rad/s) of a differential-drive robot."""

    def __init__(self, wheel_radius: float = 0.03, wheel_base: float = 0.1125):
        super().__init__(name="open_loop_unicycle")
        self._wheel_radius = wheel_radius
        self._wheel_base = wheel_base

    def forward(self, command):
        v, yaw_rate = command
        half_track = yaw_rate * self._wheel_base / 2.0
        wheels = [(v - half_track) / self._wheel_radius, (v + half_track) / self._wheel_radius]
        return ArticulationAction(joint_velocities=np.array(wheels))


world = World(stage_units_in_meters=1.0)
world.scene.add_default_ground_plane()
jetbot = world.scene.add(
    WheeledRobot(
        prim_path="/World/Fancy_Robot",
        name="fancy_robot",
        wheel_dof_names=["left_wheel_joint", "right_wheel_joint"],
        create_robot=True,
        usd_path=get_assets_root_path() + "/Isaac/Robots/Jetbot/jetbot.usd",
    )
)
controller = OpenLoopUnicycle()
world.reset()
start, _ = jetbot.get_world_pose()


def send_robot_actions(step_size):
    jetbot.apply_wheel_actions(controller.forward(command=[0.2, math.pi / 4]))


world.add_physics_callback("sending_actions", callback_fn=send_robot_actions)
for i in range(120):  # 2 s at Isaac's 60 Hz
    world.step(render=True)
    if i % 30 == 29:
        position, _ = jetbot.get_world_pose()
        print(f"t = {world.current_time:.2f} s: Jetbot at {np.round(position[:2], 3)}, "
              f"wheels {np.round(jetbot.get_wheel_velocities(), 2)} rad/s")
position, orientation = jetbot.get_world_pose()
heading = 2.0 * math.atan2(orientation[3], orientation[0])
print(f"turned {math.degrees(heading):.1f} deg, {np.linalg.norm(position[:2] - start[:2]):.3f} m from the start")
simulation_app.close()
