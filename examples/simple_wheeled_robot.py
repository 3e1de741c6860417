"""Isaac Sim wheeled-robot tutorial ported: a Jetbot under DifferentialController drives
forward, then turns, as a physics callback.

    python examples/simple_wheeled_robot.py [--seconds 4]
"""

from __future__ import annotations

import argparse
import math

import numpy as np

from ambulo import assets
from ambulo.sim import DifferentialController, WheeledRobot, World


def main(argv=None) -> dict:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--seconds", type=float, default=4.0)
    args = parser.parse_args(argv)

    world = World(physics_dt=0.005)
    world.scene.add_default_ground_plane()
    jetbot = world.scene.add(WheeledRobot(
        prim_path="/World/Jetbot", name="my_jetbot", wheel_dof_names=["left_wheel_joint", "right_wheel_joint"],
        create_robot=True, usd_path=assets.path("jetbot"), position=np.array([0, 0.0, 0.0])))
    controller = DifferentialController(name="simple_control", wheel_radius=0.03, wheel_base=0.1125)
    world.reset()
    half = args.seconds / 2

    def drive(step_size):
        # forward at 0.2 m/s for the first half, then turn in place at pi/4 rad/s
        command = [0.2, 0.0] if world.current_time < half else [0.0, math.pi / 4]
        jetbot.apply_wheel_actions(controller.forward(command=command))

    world.add_physics_callback("drive", drive)
    while world.current_time < args.seconds - 1e-9:
        world.step(render=False)
    position, orientation = jetbot.get_world_pose()
    w, x, y, z = orientation
    yaw = math.atan2(2 * (w * z + x * y), 1 - 2 * (y * y + z * z))
    print(f"after {world.current_time:.1f} s: position {np.round(position, 3)} m, heading {yaw:.2f} rad "
          f"(expected ~{0.2 * half:.2f} m forward, ~{math.pi / 4 * half:.2f} rad)")
    return {"position": position, "yaw": yaw, "half_s": half}


if __name__ == "__main__":
    main()
