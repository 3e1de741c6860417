"""Isaac Sim's "Import URDF" tutorial, scripted: Kit's URDF commands import a robot onto the stage,
then the core API drives it.

Written with Isaac Sim 4.x module names only, as the tutorial's python snippet is:
``URDFCreateImportConfig``, the config's fields, ``URDFParseAndImportFile``, then a
``SingleArticulation`` on the returned prim path. The URDF is the cart-pole bundled with ambulo
(or the path given as the first argument). Run it with `ambulo run examples/isaac/import_urdf.py`:
it prints where the robot landed, its joints, and the pose its position drives hold, which a
stiffer drive holds closer to the target against gravity.
"""

from isaacsim import SimulationApp

simulation_app = SimulationApp({"headless": True})

import os  # Isaac modules can be imported only after the app starts
import sys

import numpy as np
import omni.kit.commands
import omni.usd
from isaacsim.asset.importer.urdf import _urdf
from isaacsim.core.api import World
from isaacsim.core.prims import SingleArticulation
from isaacsim.core.utils.types import ArticulationAction

HERE = os.path.dirname(os.path.abspath(__file__))
urdf_path = sys.argv[1] if len(sys.argv) > 1 else os.path.join(HERE, "..", "..", "src", "ambulo", "assets", "data",
                                                               "cartpole.urdf")

world = World(stage_units_in_meters=1.0)
world.scene.add_default_ground_plane()

# setting up import configuration:
status, import_config = omni.kit.commands.execute("URDFCreateImportConfig")
import_config.merge_fixed_joints = False
import_config.convex_decomp = False
import_config.import_inertia_tensor = True
import_config.fix_base = True
import_config.default_drive_type = _urdf.UrdfJointTargetType.JOINT_DRIVE_POSITION
import_config.default_drive_strength = 20.0  # stiffness: N m/rad (the hinge), N/m (the slider)
import_config.default_position_drive_damping = 2.0

# import URDF, prim_path contains the path to the robot's prim on the stage
status, prim_path = omni.kit.commands.execute(
    "URDFParseAndImportFile",
    urdf_path=urdf_path,
    import_config=import_config,
    get_articulation_root=True,
)
stage = omni.usd.get_context().get_stage()
print(f"imported {os.path.basename(urdf_path)} at {prim_path}: status {status}, "
      f"prim valid {stage.GetPrimAtPath(prim_path).IsValid()}")

robot = world.scene.add(SingleArticulation(prim_path=prim_path, name="cartpole"))
world.reset()
kps, kds = robot.get_articulation_controller().get_gains()
print(f"joints: {robot.dof_names}, drive stiffness {kps.tolist()}, damping {kds.tolist()}")
base_before = robot.get_world_pose()[0]

target = np.array([0.5, 0.3])  # the cart 0.5 m along the rail, the pole tilted 0.3 rad
robot.apply_action(ArticulationAction(joint_positions=target))
for _ in range(600):  # 10 s at 60 Hz
    world.step(render=False)
q = robot.get_joint_positions()
base_after = robot.get_world_pose()[0]
print(f"held joint positions: slider {q[0]:.5f} m, hinge {q[1]:.5f} rad (targets {target[0]}, {target[1]})")
print(f"fixed base moved {np.linalg.norm(base_after - base_before):.6f} m")
simulation_app.close()
