"""A URDF imported with the importer's Python interface, as Isaac Sim 2023.1 scripts do
(``omni.importer.urdf._urdf``), before the World exists, with one joint's drive edited.

``acquire_urdf_interface()``, ``ImportConfig()`` and its ``set_*`` methods, ``parse_urdf``, then an
edit of the parsed robot: the slider becomes a velocity drive (its strength is the damping
gain) while the hinge keeps a position drive. ``import_robot`` places the robot; the World
made afterwards simulates it, and an ``ArticulationView`` drives it. Run it with
`ambulo run examples/isaac/import_urdf_interface.py`: it prints the cart's speed against the
commanded one and the hinge angle its drive holds.
"""

from omni.isaac.kit import SimulationApp

simulation_app = SimulationApp({"headless": True})

import os  # Isaac modules can be imported only after the app starts

import numpy as np
from omni.importer.urdf import _urdf
from omni.isaac.core import World
from omni.isaac.core.articulations import ArticulationView

HERE = os.path.dirname(os.path.abspath(__file__))
root_path = os.path.join(HERE, "..", "..", "src", "ambulo", "assets", "data")
file_name = "cartpole.urdf"

urdf_interface = _urdf.acquire_urdf_interface()
import_config = _urdf.ImportConfig()
import_config.set_merge_fixed_joints(False)
import_config.set_fix_base(True)
import_config.set_self_collision(False)
import_config.set_default_drive_type(_urdf.UrdfJointTargetType.JOINT_DRIVE_POSITION)
import_config.set_default_drive_strength(400.0)
import_config.set_default_position_drive_damping(40.0)

imported_robot = urdf_interface.parse_urdf(root_path, file_name, import_config)
print(f"parsed {imported_robot.name}: links {sorted(imported_robot.links)}, joints {sorted(imported_robot.joints)}")
slider = imported_robot.joints["slider"]
slider.drive.target_type = _urdf.UrdfJointTargetType.JOINT_DRIVE_VELOCITY
slider.drive.strength = 50.0  # a velocity drive's damping, N s/m
prim_path = urdf_interface.import_robot(root_path, file_name, imported_robot, import_config, "")
print(f"imported at {prim_path}")

world = World()
cartpoles = world.scene.add(ArticulationView(prim_paths_expr=prim_path, name="cartpoles"))
world.reset()
print(f"joints {cartpoles.dof_names}")

cartpoles.set_joint_velocity_targets(np.array([[0.2]]), joint_indices=[0])  # the cart at 0.2 m/s
cartpoles.set_joint_position_targets(np.array([[0.3]]), joint_indices=[1])  # the pole held at 0.3 rad
for _ in range(120):  # 2 s
    world.step(render=False)
velocity = cartpoles.get_joint_velocities()[0]
position = cartpoles.get_joint_positions()[0]
print(f"cart speed {velocity[0]:.4f} m/s (commanded 0.2), at {position[0]:.4f} m; hinge {position[1]:.5f} rad")
simulation_app.close()
