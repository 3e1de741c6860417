"""A standalone Isaac Sim script that tunes PhysX through ``pxr.PhysxSchema``, as Isaac's
physics tutorials do: scene settings, rigid-body damping, contact offsets, an articulation's
solver iterations and self-collisions, and joint armature and friction.

Run it with `ambulo run examples/isaac/physx_schema.py`: it prints the physics step, how the
damped ball slowed, where the offset box rests and the arm's joint angle. Settings MuJoCo has
no counterpart for (CCD, GPU dynamics, the broadphase, ...) are named in one warning.
"""

from isaacsim import SimulationApp

simulation_app = SimulationApp({"headless": True})

import math  # Isaac modules can be imported only after the app starts

import numpy as np
import omni.usd
from isaacsim.core.api import World
from isaacsim.core.prims import SingleArticulation, SingleRigidPrim
from omni.physx.scripts import physicsUtils
from pxr import Gf, PhysxSchema, UsdGeom, UsdPhysics

stage = omni.usd.get_context().get_stage()

# the physics scene: PhysX's step and solver settings
scene = UsdPhysics.Scene.Define(stage, "/World/physicsScene")
scene.CreateGravityDirectionAttr(Gf.Vec3f(0.0, 0.0, -1.0))
scene.CreateGravityMagnitudeAttr(9.81)
physx_scene = PhysxSchema.PhysxSceneAPI.Apply(scene.GetPrim())
physx_scene.CreateTimeStepsPerSecondAttr(120)
physx_scene.CreateEnableCCDAttr(True)
physx_scene.CreateEnableGPUDynamicsAttr(False)
physx_scene.CreateBroadphaseTypeAttr("MBP")
physx_scene.CreateSolverTypeAttr("TGS")
physicsUtils.add_ground_plane(stage, "/World/groundPlane", "Z", 10.0, Gf.Vec3f(0.0), Gf.Vec3f(0.5))

# a ball that floats (no gravity) and is slowed by PhysX's linear and angular damping
ball = physicsUtils.add_rigid_sphere(stage, "/World/ball", radius=0.1, position=Gf.Vec3f(0.0, -1.0, 1.0),
                                     density=1000.0, lin_velocity=Gf.Vec3f(2.0, 0.0, 0.0),
                                     ang_velocity=Gf.Vec3f(0.0, 0.0, 360.0))
ball_physx = PhysxSchema.PhysxRigidBodyAPI.Apply(ball)
ball_physx.CreateDisableGravityAttr(True)
ball_physx.CreateLinearDampingAttr(0.5)
ball_physx.CreateAngularDampingAttr(1.0)
ball_physx.CreateEnableCCDAttr(True)

# a box whose collider keeps a 2 cm rest offset from whatever it lies on
box = physicsUtils.add_rigid_box(stage, "/World/box", size=Gf.Vec3f(0.2, 0.2, 0.2), position=Gf.Vec3f(1.0, 0.0, 0.5),
                                 density=500.0)
collision = PhysxSchema.PhysxCollisionAPI.Apply(box)
collision.CreateContactOffsetAttr(0.04)
collision.CreateRestOffsetAttr(0.02)
PhysxSchema.PhysxContactReportAPI.Apply(box).CreateThresholdAttr(0.0)


def add_link(path: str, size, position) -> None:
    """A link as Isaac's robots have them: a rigid-body Xform with a collision Cube under it."""
    link = UsdGeom.Xform.Define(stage, path)
    link.AddTranslateOp().Set(Gf.Vec3d(*position))
    UsdPhysics.RigidBodyAPI.Apply(link.GetPrim())
    collider = UsdGeom.Cube.Define(stage, f"{path}/collision")
    collider.CreateSizeAttr(1.0)
    collider.AddScaleOp().Set(Gf.Vec3f(*size))
    UsdPhysics.CollisionAPI.Apply(collider.GetPrim())
    UsdPhysics.MassAPI.Apply(collider.GetPrim()).CreateMassAttr(0.5)


# an arm: a base fixed to the world and two links on vertical hinges. The second link overlaps
# the base, which is fine because the articulation's self-collisions are disabled (enabled,
# the contact would swing it about 10 degrees off its drive's target).
UsdGeom.Xform.Define(stage, "/World/arm")
add_link("/World/arm/base", (0.4, 0.1, 0.1), (0.0, 1.0, 0.3))
add_link("/World/arm/link1", (0.1, 0.1, 0.1), (0.25, 1.0, 0.45))
add_link("/World/arm/link2", (0.4, 0.1, 0.1), (0.0, 1.08, 0.3))  # 2 cm into the base, sideways
arm_root = stage.GetPrimAtPath("/World/arm/base")
UsdPhysics.ArticulationRootAPI.Apply(arm_root)
arm_physx = PhysxSchema.PhysxArticulationAPI.Apply(arm_root)
arm_physx.CreateEnabledSelfCollisionsAttr(False)
arm_physx.CreateSolverPositionIterationCountAttr(64)
arm_physx.CreateSolverVelocityIterationCountAttr(4)
fixed = UsdPhysics.FixedJoint.Define(stage, "/World/arm/root_joint")
fixed.CreateBody1Rel().SetTargets(["/World/arm/base"])
fixed.CreateLocalPos0Attr(Gf.Vec3f(0.0, 1.0, 0.3))
for name, parent, child, parent_pos, child_pos in (("joint1", "base", "link1", (0.25, 0.0, 0.1), (0.0, 0.0, -0.05)),
                                                  ("joint2", "link1", "link2", (0.0, 0.0, -0.05), (0.25, -0.08, 0.1))):
    hinge = UsdPhysics.RevoluteJoint.Define(stage, f"/World/arm/{name}")
    hinge.CreateBody0Rel().SetTargets([f"/World/arm/{parent}"])
    hinge.CreateBody1Rel().SetTargets([f"/World/arm/{child}"])
    hinge.CreateAxisAttr("Z")
    hinge.CreateLocalPos0Attr(Gf.Vec3f(*parent_pos))
    hinge.CreateLocalPos1Attr(Gf.Vec3f(*child_pos))
    joint_physx = PhysxSchema.PhysxJointAPI.Apply(hinge.GetPrim())
    joint_physx.CreateArmatureAttr(0.01)
    joint_physx.CreateJointFrictionAttr(0.05)
    joint_physx.CreateMaxJointVelocityAttr(100.0)
    drive = UsdPhysics.DriveAPI.Apply(hinge.GetPrim(), "angular")
    drive.CreateStiffnessAttr(1.0)  # per degree: 57 N m/rad
    drive.CreateDampingAttr(0.1)

world = World(stage_units_in_meters=1.0)
ball_prim = world.scene.add(SingleRigidPrim(prim_path="/World/ball", name="ball"))
box_prim = world.scene.add(SingleRigidPrim(prim_path="/World/box", name="box"))
arm = world.scene.add(SingleArticulation(prim_path="/World/arm", name="arm"))
world.reset()
print(f"physics step: {world.get_physics_dt():.6f} s")
while world.current_time < 1.0 - 1e-9:
    world.step(render=False)
speed = float(np.linalg.norm(ball_prim.get_linear_velocity()))
spin = float(np.linalg.norm(ball_prim.get_angular_velocity()))
print(f"after {world.current_time:.3f} s the ball moves at {speed:.4f} m/s (launched at 2 m/s) "
      f"and spins at {spin:.4f} rad/s (launched at 2 pi rad/s)")
print(f"box at rest at height {box_prim.get_world_pose()[0][2]:.4f} m")
print(f"arm joint2 at {math.degrees(float(arm.get_joint_positions()[1])):.2f} degrees")
simulation_app.close()
