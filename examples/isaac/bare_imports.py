"""A standalone Isaac Sim script that imports only the parent packages, as Kit's Script Editor
snippets do: `import omni` / `import omni.isaac.core`, then `omni.usd.get_context()`,
`omni.isaac.core.utils.stage.add_reference_to_stage(...)` and so on by attribute.

In Kit every extension's modules are already loaded, so the bare parent import is enough.
Run it with `ambulo run examples/isaac/bare_imports.py`: it prints what it found on the stage,
the Jetbot's degrees of freedom and where the dropped cube comes to rest.
"""

import isaacsim

simulation_app = isaacsim.SimulationApp({"headless": True})

import carb  # Isaac modules can be imported only after the app starts
import numpy as np
import omni
import omni.isaac.core

carb.log_info("building the scene through attribute access only")
stage = omni.usd.get_context().get_stage()
world = omni.isaac.core.World(stage_units_in_meters=1.0)
world.scene.add_default_ground_plane()

assets_root = omni.isaac.core.utils.nucleus.get_assets_root_path()
omni.isaac.core.utils.stage.add_reference_to_stage(usd_path=assets_root + "/Isaac/Robots/Jetbot/jetbot.usd",
                                                    prim_path="/World/Jetbot")
jetbot = world.scene.add(omni.isaac.core.robots.Robot(prim_path="/World/Jetbot", name="jetbot"))
cube = world.scene.add(omni.isaac.core.objects.DynamicCuboid(
    prim_path="/World/cube", name="cube", position=np.array([0.5, 0.0, 1.0]), size=0.2))
world.reset()

print(f"stage has /World/Jetbot: {stage.GetPrimAtPath('/World/Jetbot').IsValid()}")
print(f"jetbot degrees of freedom: {jetbot.num_dof}")
for _ in range(90):
    world.step(render=False)
omni.kit.app.get_app().update()  # one more rendering step, as a Kit loop would run
height = cube.get_world_pose()[0][2]
print(f"cube at rest at height {height:.3f} m")
simulation_app.close()
