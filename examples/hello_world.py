"""Isaac Sim "Hello World" ported: a cube falls onto the ground; print its pose as it goes.

    python examples/hello_world.py [--steps 500] [--video out/hello_world.mp4]
"""

from __future__ import annotations

import argparse

import numpy as np

from ambulo.sim import DynamicCuboid, World


def main(argv=None) -> dict:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--steps", type=int, default=500)
    parser.add_argument("--video", default=None)
    args = parser.parse_args(argv)

    world = World()
    world.scene.add_default_ground_plane()
    fancy_cube = world.scene.add(DynamicCuboid(
        prim_path="/World/random_cube", name="fancy_cube", position=np.array([0, 0, 1.0]),
        scale=np.array([0.5015, 0.5015, 0.5015]), size=1.0, color=np.array([0, 0, 1.0])))
    world.reset()
    recorder = None
    if args.video:
        from ambulo.sim.recorder import Recorder

        recorder = Recorder(world, args.video)
    for i in range(args.steps):
        position, orientation = fancy_cube.get_world_pose()
        linear_velocity = fancy_cube.get_linear_velocity()
        if i % 100 == 0:
            print(f"t={world.current_time:.2f} s  cube position {np.round(position, 3)}  "
                  f"orientation {np.round(orientation, 3)}  velocity {np.round(linear_velocity, 3)}")
        world.step(render=recorder is not None)
        if recorder:
            recorder.capture()
    if recorder:
        recorder.close()
    position, _ = fancy_cube.get_world_pose()
    print(f"final height {position[2]:.3f} m (half the cube's 0.5015 m edge is 0.251 m)")
    return {"final_position": position}


if __name__ == "__main__":
    main()
