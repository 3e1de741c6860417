"""Isaac Sim "Hello Robot" ported: a Jetbot driven with random wheel velocities,
first through a physics callback on a plain Articulation, then through WheeledRobot.

    python examples/hello_robot.py [--steps 500]
"""

from __future__ import annotations

import argparse

import numpy as np

from ambulo.sim import (
    Articulation,
    ArticulationAction,
    WheeledRobot,
    World,
    add_reference_to_stage,
    get_assets_root_path,
)


def main(argv=None) -> dict:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--steps", type=int, default=500)
    parser.add_argument("--seed", type=int, default=0)
    args = parser.parse_args(argv)
    rng = np.random.default_rng(args.seed)

    # part 1: an Articulation and a physics callback sending random wheel velocities
    world = World()
    world.scene.add_default_ground_plane()
    jetbot_asset_path = get_assets_root_path() + "/jetbot.xml"
    add_reference_to_stage(usd_path=jetbot_asset_path, prim_path="/World/Fancy_Robot")
    jetbot = world.scene.add(Articulation(prim_path="/World/Fancy_Robot", name="fancy_robot"))
    print(f"before reset: num of joints {jetbot.num_dof}")
    world.reset()
    print(f"num of joints {jetbot.num_dof}: {jetbot.dof_names}")
    controller = jetbot.get_articulation_controller()
    controller.switch_control_mode("velocity")

    def send_robot_actions(step_size):
        controller.apply_action(ArticulationAction(joint_positions=None, joint_efforts=None,
                                                   joint_velocities=5 * rng.random(2)))

    world.add_physics_callback("sending_actions", callback_fn=send_robot_actions)
    start = jetbot.get_world_pose()[0]
    for _ in range(args.steps):
        world.step(render=False)
    callback_distance = float(np.linalg.norm(jetbot.get_world_pose()[0][:2] - start[:2]))
    print(f"physics callback drove the jetbot {callback_distance:.2f} m")

    # part 2: the same robot as a WheeledRobot
    world = World()
    world.scene.add_default_ground_plane()
    jetbot = world.scene.add(WheeledRobot(
        prim_path="/World/Fancy_Robot", name="fancy_robot", wheel_dof_names=["left_wheel_joint", "right_wheel_joint"],
        create_robot=True, usd_path=jetbot_asset_path))
    world.reset()
    world.add_physics_callback("sending_actions", callback_fn=lambda step_size: jetbot.apply_wheel_actions(
        ArticulationAction(joint_positions=None, joint_efforts=None, joint_velocities=5 * rng.random(2))))
    start = jetbot.get_world_pose()[0]
    for _ in range(args.steps):
        world.step(render=False)
    wheeled_distance = float(np.linalg.norm(jetbot.get_world_pose()[0][:2] - start[:2]))
    print(f"WheeledRobot drove the jetbot {wheeled_distance:.2f} m")
    return {"callback_distance": callback_distance, "wheeled_distance": wheeled_distance,
            "seconds": world.current_time}


if __name__ == "__main__":
    main()
