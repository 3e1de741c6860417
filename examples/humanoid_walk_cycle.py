"""Isaac Lab humanoid walk cycle ported: the tutorial humanoid on a gantry (fixed base)
swings its legs and arms through a walking gait given as joint position targets.

    python examples/humanoid_walk_cycle.py [--seconds 4] [--video out/walk_cycle.mp4]
"""

from __future__ import annotations

import argparse
import math

import numpy as np

from ambulo import assets
from ambulo.sim import ArticulationAction, Robot, World, add_reference_to_stage, set_camera_view

GAIT_HZ = 1.0
# amplitudes (rad) of the sinusoidal gait, and offsets so knees/elbows only bend one way
HIP_AMP, KNEE_AMP, ANKLE_AMP, SHOULDER_AMP = 0.5, 0.6, 0.25, 0.4


def gait_targets(names: list[str], t: float) -> np.ndarray:
    """Joint targets (rad) of the walk cycle at time t: legs in antiphase, arms opposite legs."""
    phase = 2 * math.pi * GAIT_HZ * t
    targets = np.zeros(len(names))
    for i, name in enumerate(names):
        side = 0.0 if name.startswith("left") else math.pi
        s = math.sin(phase + side)
        if name.endswith("hip"):
            targets[i] = -HIP_AMP * s
        elif name.endswith("knee"):
            targets[i] = KNEE_AMP * max(0.0, math.sin(phase + side + math.pi / 2))
        elif name.endswith("ankle"):
            targets[i] = ANKLE_AMP * s
        elif name.endswith("shoulder"):
            targets[i] = SHOULDER_AMP * s
        elif name.endswith("elbow"):
            targets[i] = 0.3
    return targets


def main(argv=None) -> dict:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--seconds", type=float, default=4.0)
    parser.add_argument("--video", default=None)
    args = parser.parse_args(argv)

    world = World(physics_dt=0.005, rendering_dt=0.02)
    world.scene.add_default_ground_plane()
    add_reference_to_stage(usd_path=assets.path("humanoid_tutorial"), prim_path="/World/Humanoid",
                           fixed_base=True)
    humanoid = world.scene.add(Robot(prim_path="/World/Humanoid", position=[0, 0, 0.25]))
    world.reset()
    set_camera_view(eye=[2.5, -2.5, 1.6], target=[0, 0, 1.0])
    recorder = None
    if args.video:
        from ambulo.sim.recorder import Recorder

        recorder = Recorder(world, args.video)
    errors = []
    while world.current_time < args.seconds - 1e-9:
        targets = gait_targets(humanoid.dof_names, world.current_time)
        humanoid.apply_action(ArticulationAction(joint_positions=targets))
        world.step(render=recorder is not None)
        if recorder:
            recorder.capture()
        if world.current_time > 1.0:  # after the first second's transient
            errors.append(humanoid.get_joint_positions() - gait_targets(humanoid.dof_names, world.current_time))
    if recorder:
        recorder.close()
    rms = np.sqrt(np.mean(np.square(errors), axis=0))
    for name, e in zip(humanoid.dof_names, rms):
        print(f"  {name:15s} tracking RMS error {math.degrees(e):5.1f} deg")
    return {"rms_error_rad": dict(zip(humanoid.dof_names, rms.tolist()))}


if __name__ == "__main__":
    main()
