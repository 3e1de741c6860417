"""A standalone Isaac Sim script that disables joints with ``physics:jointEnabled = false``, as
PhysX does to "break" them: the bodies a disabled joint held are no longer connected by it.

Two boxes hang from the world on fixed joints, and a two-link chain hangs from a post on
revolute joints. The second box's joint and the chain's top joint are disabled: that box falls
to the ground, and the chain falls as one piece, its lower joint still holding. Run it with
`ambulo run examples/isaac/joint_enabled.py`: it prints where everything ends up.
"""

from isaacsim import SimulationApp

simulation_app = SimulationApp({"headless": True})

import numpy as np  # Isaac modules can be imported only after the app starts
import omni.usd
from isaacsim.core.api import World
from isaacsim.core.prims import SingleRigidPrim
from omni.physx.scripts import physicsUtils
from pxr import Gf, UsdPhysics

stage = omni.usd.get_context().get_stage()
UsdPhysics.Scene.Define(stage, "/World/physicsScene")
physicsUtils.add_ground_plane(stage, "/World/groundPlane", "Z", 10.0, Gf.Vec3f(0.0), Gf.Vec3f(0.5))


def hang_from_world(name: str, position, enabled: bool) -> None:
    """A 0.2 m box held at ``position`` by a fixed joint to the world."""
    physicsUtils.add_rigid_box(stage, f"/World/{name}", size=Gf.Vec3f(0.2, 0.2, 0.2), position=Gf.Vec3f(*position),
                               density=500.0)
    joint = UsdPhysics.FixedJoint.Define(stage, f"/World/{name}_joint")
    joint.CreateBody1Rel().SetTargets([f"/World/{name}"])
    joint.CreateLocalPos0Attr(Gf.Vec3f(*position))
    joint.CreateJointEnabledAttr(enabled)


hang_from_world("held_box", (0.0, -1.0, 1.0), enabled=True)
hang_from_world("dropped_box", (0.0, 0.0, 1.0), enabled=False)

# a chain: upper link on a revolute joint to the world, lower link on a revolute joint to it
for name, z in (("upper", 1.4), ("lower", 1.0)):
    link = physicsUtils.add_rigid_sphere(stage, f"/World/chain/{name}", radius=0.1, position=Gf.Vec3f(0.0, 1.0, z),
                                         density=500.0)
top = UsdPhysics.RevoluteJoint.Define(stage, "/World/chain/top_joint")
top.CreateBody1Rel().SetTargets(["/World/chain/upper"])
top.CreateAxisAttr("X")
top.CreateLocalPos0Attr(Gf.Vec3f(0.0, 1.0, 1.6))
top.CreateLocalPos1Attr(Gf.Vec3f(0.0, 0.0, 0.2))
top.CreateJointEnabledAttr(False)  # the chain comes off its post
middle = UsdPhysics.RevoluteJoint.Define(stage, "/World/chain/middle_joint")
middle.CreateBody0Rel().SetTargets(["/World/chain/upper"])
middle.CreateBody1Rel().SetTargets(["/World/chain/lower"])
middle.CreateAxisAttr("X")
middle.CreateLocalPos0Attr(Gf.Vec3f(0.0, 0.0, -0.2))
middle.CreateLocalPos1Attr(Gf.Vec3f(0.0, 0.0, 0.2))

world = World(stage_units_in_meters=1.0)
boxes = {name: world.scene.add(SingleRigidPrim(prim_path=f"/World/{name}", name=name))
         for name in ("held_box", "dropped_box")}
links = {name: world.scene.add(SingleRigidPrim(prim_path=f"/World/chain/{name}", name=name))
         for name in ("upper", "lower")}
world.reset()
for _ in range(120):
    world.step(render=False)
for name, box in boxes.items():
    print(f"{name} at height {box.get_world_pose()[0][2]:.3f} m")
upper, lower = (links[name].get_world_pose()[0] for name in ("upper", "lower"))
print(f"chain's upper link at height {upper[2]:.3f} m, "
      f"{float(np.linalg.norm(upper - lower)):.3f} m from its lower link")
simulation_app.close()
