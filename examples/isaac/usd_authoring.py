"""A standalone Isaac Sim script that authors physics with pxr: UsdGeom + UsdPhysics prims,
PhysX's authoring helpers, and Isaac API objects on the same stage.

The stage is authored before the World exists (as scripts that open or build a stage first
do), then the World adds a cube and a Jetbot through the Isaac API. Run it with
`ambulo run examples/isaac/usd_authoring.py`: it prints where the authored box, the API cube
and the driven pendulum come to rest.
"""

from isaacsim import SimulationApp

simulation_app = SimulationApp({"headless": True})

import math  # Isaac modules can be imported only after the app starts

import numpy as np
import omni.usd
from isaacsim.core.api import World
from isaacsim.core.api.objects import DynamicCuboid
from isaacsim.core.prims import SingleArticulation, SingleRigidPrim
from isaacsim.core.utils.types import ArticulationAction
from omni.physx.scripts import physicsUtils
from pxr import Gf, Sdf, UsdGeom, UsdPhysics

stage = omni.usd.get_context().get_stage()
UsdPhysics.Scene.Define(stage, "/World/physicsScene")
physicsUtils.add_ground_plane(stage, "/World/groundPlane", "Z", 10.0, Gf.Vec3f(0.0, 0.0, 0.0), Gf.Vec3f(0.5))
# a 0.3 m box sliding off at 1 m/s, with PhysX's solver iterations raised on it
box = physicsUtils.add_rigid_box(stage, "/World/box", size=Gf.Vec3f(0.3, 0.3, 0.3), position=Gf.Vec3f(0.0, -1.0, 0.6),
                                 color=Gf.Vec3f(0.9, 0.2, 0.1), density=200.0, lin_velocity=Gf.Vec3f(1.0, 0.0, 0.0))
box.CreateAttribute("physxRigidBody:solverPositionIterationCount", Sdf.ValueTypeNames.UInt).Set(16)

# a pendulum: one capsule link on a revolute joint to the world, held by an angular drive
UsdGeom.Xform.Define(stage, "/World/pendulum")
link = UsdGeom.Capsule.Define(stage, "/World/pendulum/link")
link.CreateRadiusAttr(0.04)
link.CreateHeightAttr(0.5)
link.AddTranslateOp().Set(Gf.Vec3d(0.0, 1.0, 1.0))
UsdPhysics.RigidBodyAPI.Apply(link.GetPrim())
UsdPhysics.CollisionAPI.Apply(link.GetPrim())
UsdPhysics.MassAPI.Apply(link.GetPrim()).CreateMassAttr(2.0)
hinge = UsdPhysics.RevoluteJoint.Define(stage, "/World/pendulum/hinge")
hinge.CreateBody1Rel().SetTargets(["/World/pendulum/link"])
hinge.CreateAxisAttr("X")
hinge.CreateLocalPos0Attr(Gf.Vec3f(0.0, 1.0, 1.3))
hinge.CreateLocalPos1Attr(Gf.Vec3f(0.0, 0.0, 0.3))
drive = UsdPhysics.DriveAPI.Apply(hinge.GetPrim(), "angular")
drive.CreateStiffnessAttr(10.0)  # per degree, as UsdPhysics states it: 573 N m/rad
drive.CreateDampingAttr(1.0)

world = World(stage_units_in_meters=1.0)
cube = world.scene.add(DynamicCuboid(prim_path="/World/api_cube", name="api_cube", position=np.array([1.0, 0.0, 0.5]),
                                     size=0.2, color=np.array([0.1, 0.4, 0.9])))
authored_box = world.scene.add(SingleRigidPrim(prim_path="/World/box", name="authored_box"))
pendulum = world.scene.add(SingleArticulation(prim_path="/World/pendulum", name="pendulum"))
world.reset()
print(f"the stage holds /World/api_cube: {stage.GetPrimAtPath('/World/api_cube').IsValid()}")
print(f"pendulum degrees of freedom: {pendulum.num_dof}")
pendulum.apply_action(ArticulationAction(joint_positions=np.array([math.radians(30.0)])))
for _ in range(180):
    world.step(render=False)
box_position = authored_box.get_world_pose()[0]
print(f"authored box at rest at {np.round(box_position, 3)} (slid {box_position[0]:.2f} m along x)")
print(f"API cube at rest at height {cube.get_world_pose()[0][2]:.3f} m")
print(f"pendulum held at {math.degrees(float(pendulum.get_joint_positions()[0])):.1f} degrees (target 30)")
simulation_app.close()
