"""A standalone Isaac Sim script with several robots: three Jetbots driven at once through one view.

Written with Isaac Sim 4.5+ module names only. Run it with `ambulo run examples/isaac/multiple_robots.py`
(or with Isaac Sim's python.sh). Each Jetbot is referenced under its own environment prim,
`/World/envs/env_<i>/Jetbot`, 0.5 m apart in y; `Articulation("/World/envs/env_.*/Jetbot")` wraps all
three, so one call sets the wheel speeds of every robot ((3, 2) rad/s): the first drives forward, the
second stays, the third backs up, and the view reports their (3, 3) positions.
"""

from isaacsim import SimulationApp

simulation_app = SimulationApp({"headless": True})

import numpy as np  # Isaac modules can be imported only after the app starts
from isaacsim.core.api import World
from isaacsim.core.prims import Articulation
from isaacsim.core.utils.nucleus import get_assets_root_path
from isaacsim.core.utils.stage import add_reference_to_stage

NUM_ROBOTS = 3
WHEEL_SPEEDS = np.array([[10.0, 10.0], [0.0, 0.0], [-10.0, -10.0]])  # rad/s, (left, right) per robot

world = World(stage_units_in_meters=1.0)
world.scene.add_default_ground_plane()
jetbot_usd = get_assets_root_path() + "/Isaac/Robots/Jetbot/jetbot.usd"
for i in range(NUM_ROBOTS):
    add_reference_to_stage(usd_path=jetbot_usd, prim_path=f"/World/envs/env_{i}/Jetbot")
jetbots = Articulation(
    prim_paths_expr="/World/envs/env_.*/Jetbot",
    name="jetbot_view",
    positions=np.array([[0.0, 0.5 * i, 0.0] for i in range(NUM_ROBOTS)]),
)
world.scene.add(jetbots)
world.reset()
print(f"{jetbots.count} Jetbots with joints {jetbots.dof_names}")
start, _ = jetbots.get_world_poses()

for _ in range(120):  # 2 s at Isaac's 60 Hz
    jetbots.set_joint_velocity_targets(WHEEL_SPEEDS)
    world.step(render=True)
positions, _ = jetbots.get_world_poses()
for path, before, after in zip(jetbots.prim_paths, start, positions):
    print(f"{path}: x {before[0]:+.3f} -> {after[0]:+.3f} m")
simulation_app.close()
