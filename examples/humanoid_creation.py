"""Isaac Lab "create a humanoid" ported: load the 10-joint tutorial humanoid, inspect its
joints and limits, and let it stand under its PD drives.

    python examples/humanoid_creation.py [--seconds 3]
"""

from __future__ import annotations

import argparse

import numpy as np

from ambulo import assets
from ambulo.sim import Robot, World, add_reference_to_stage


def main(argv=None) -> dict:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--seconds", type=float, default=3.0)
    args = parser.parse_args(argv)

    world = World(physics_dt=0.005)
    world.scene.add_default_ground_plane()
    add_reference_to_stage(usd_path=assets.path("humanoid_tutorial"), prim_path="/World/Humanoid")
    humanoid = world.scene.add(Robot(prim_path="/World/Humanoid", name="humanoid"))
    world.reset()
    kps, kds = humanoid.get_articulation_controller().get_gains()
    limits = humanoid.get_dof_limits()
    print(f"{humanoid.num_dof} joints")
    for name, (low, high), kp, kd in zip(humanoid.dof_names, limits, kps, kds):
        print(f"  {name:15s} range [{low:+.2f}, {high:+.2f}] rad   kp {kp:6.1f}   kd {kd:5.2f}")
    height0 = humanoid.get_world_pose()[0][2]
    while world.current_time < args.seconds - 1e-9:
        world.step(render=False)
    height = humanoid.get_world_pose()[0][2]
    print(f"torso height {height0:.3f} m -> {height:.3f} m after {world.current_time:.1f} s")
    return {"num_dof": humanoid.num_dof, "dof_names": humanoid.dof_names,
            "height_start": float(height0), "height_end": float(height), "limits": np.asarray(limits)}


if __name__ == "__main__":
    main()
