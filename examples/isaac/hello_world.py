"""A standalone Isaac Sim script (the "Hello World" flow): an app, a World, a falling cube.

Written with Isaac Sim's module names only. Run it with `ambulo run examples/isaac/hello_world.py`
(or with Isaac Sim's python.sh): it prints the cube's height while it falls and comes to rest.
"""

from isaacsim import SimulationApp

simulation_app = SimulationApp({"headless": True})

import numpy as np  # Isaac modules can be imported only after the app starts
from isaacsim.core.api import World
from isaacsim.core.api.objects import DynamicCuboid

world = World(stage_units_in_meters=1.0)
world.scene.add_default_ground_plane()
cube = world.scene.add(
    DynamicCuboid(
        prim_path="/World/random_cube",
        name="fancy_cube",
        position=np.array([0.0, 0.0, 1.0]),
        scale=np.array([0.5015, 0.5015, 0.5015]),
        color=np.array([0.0, 0.0, 1.0]),
    )
)
world.reset()
for i in range(120):
    position, orientation = cube.get_world_pose()
    linear_velocity = cube.get_linear_velocity()
    if i % 20 == 0:
        print(f"step {i}: cube position is {np.round(position, 3)}, linear velocity {np.round(linear_velocity, 3)}")
    world.step(render=True)
position, _ = cube.get_world_pose()
print(f"cube at rest at height {position[2]:.3f} m")
simulation_app.close()
