"""A scene built with Kit commands (``omni.kit.commands.execute``), as Isaac Sim scripts and the
Script Editor's command log write them, then simulated.

PhysX's commands add a physics scene, a ground plane, a rigid cube from Kit's mesh generator
and a static table; USD commands place, copy, move, deactivate and delete prims;
``ChangeProperty`` turns Earth's gravity into the Moon's; a command of the script's own is
registered, executed and undone. Written with Isaac Sim 4.x module names only. Run it with
`ambulo run examples/isaac/kit_commands.py`: it prints how far the cube falls under each
gravity, where it comes to rest, and what each command left on the stage.
"""

from isaacsim import SimulationApp

simulation_app = SimulationApp({"headless": True})

import omni.kit.commands  # Isaac modules can be imported only after the app starts
import omni.kit.undo
import omni.usd
from isaacsim.core.api import World
from isaacsim.core.prims import SingleRigidPrim
from pxr import Gf, UsdPhysics

world = World()
stage = omni.usd.get_context().get_stage()
omni.kit.commands.execute("AddPhysicsSceneCommand", stage=stage, path="/World/PhysicsScene")
omni.kit.commands.execute("AddGroundPlaneCommand", stage=stage, planePath="/World/GroundPlane", axis="Z", size=10.0,
                          position=Gf.Vec3f(0.0), color=Gf.Vec3f(0.5))

# a 0.2 m cube (half_scale is in centimetres), a rigid body 2 m up
result, cube_path = omni.kit.commands.execute("CreateMeshPrimWithDefaultXform", prim_type="Cube", half_scale=10.0)
omni.kit.commands.execute("TransformPrimSRT", path=cube_path, new_translation=Gf.Vec3d(0.0, 0.0, 2.0))
omni.kit.commands.execute("SetRigidBody", path=cube_path, approximationShape="convexHull", kinematic=False)

# a static table under it: a unit cube scaled to 0.5 m, its top at 0.5 m
omni.kit.commands.execute("CreatePrim", prim_type="Cube", prim_path="/World/Table", attributes={"size": 1.0})
table = Gf.Matrix4d().SetScale(Gf.Vec3d(0.5)) * Gf.Matrix4d().SetTranslate(Gf.Vec3d(0.0, 0.0, 0.25))
omni.kit.commands.execute("TransformPrim", path="/World/Table", new_transform_matrix=table)
omni.kit.commands.execute("SetStaticCollider", path="/World/Table")

# balls: one made, one copied and moved under a group Xform (keeping where it is), one deleted
omni.kit.commands.execute("CreatePrim", prim_type="Sphere", prim_path="/World/Ball", attributes={"radius": 0.1})
omni.kit.commands.execute("TransformPrimSRT", path="/World/Ball", new_translation=Gf.Vec3d(1.0, 0.0, 0.1))
omni.kit.commands.execute("SetRigidBody", path="/World/Ball")
omni.kit.commands.execute("CopyPrim", path_from="/World/Ball", path_to="/World/Ball_copy")
omni.kit.commands.execute("TransformPrimSRT", path="/World/Ball_copy", new_translation=Gf.Vec3d(2.0, 0.0, 0.1))
omni.kit.commands.execute("CreatePrim", prim_type="Xform", prim_path="/World/Balls")
omni.kit.commands.execute("TransformPrimSRT", path="/World/Balls", new_translation=Gf.Vec3d(0.0, 1.0, 0.0))
omni.kit.commands.execute("MovePrim", path_from="/World/Ball_copy", path_to="/World/Balls/Ball_copy")

# a second cube (the generator names it Cube_01), deactivated: not simulated
result, spare_path = omni.kit.commands.execute("CreateMeshPrimWithDefaultXform", prim_type="Cube", half_scale=10.0)
omni.kit.commands.execute("SetRigidBody", path=spare_path)
omni.kit.commands.execute("ToggleActivePrims", prim_paths=[spare_path], active=False)
print(f"made {cube_path} and {spare_path} (active {stage.GetPrimAtPath(spare_path).IsActive()})")

cube = world.scene.add(SingleRigidPrim(prim_path=cube_path, name="cube"))
ball = world.scene.add(SingleRigidPrim(prim_path="/World/Balls/Ball_copy", name="ball"))
world.reset()
for _ in range(30):  # 0.5 s
    world.step(render=False)
print(f"after 0.5 s under 9.81 m/s^2: cube at z = {cube.get_world_pose()[0][2]:.4f} m")
print(f"moved ball at {ball.get_world_pose()[0].round(4).tolist()}, "
      f"local translate {stage.GetPrimAtPath('/World/Balls/Ball_copy').GetAttribute('xformOp:translate').Get()}")

# the Moon's gravity, and one ball fewer
omni.kit.commands.execute("ChangeProperty", prop_path="/World/PhysicsScene.physics:gravityMagnitude", value=1.62,
                          prev=9.81)
omni.kit.commands.execute("DeletePrims", paths=["/World/Ball"])
print(f"/World/Ball after DeletePrims: valid {stage.GetPrimAtPath('/World/Ball').IsValid()}")
world.reset()
for _ in range(30):
    world.step(render=False)
print(f"after 0.5 s under 1.62 m/s^2: cube at z = {cube.get_world_pose()[0][2]:.4f} m")
for _ in range(210):  # to 4 s: it lands on the table
    world.step(render=False)
print(f"after 4 s: cube at rest at z = {cube.get_world_pose()[0][2]:.4f} m")


class SetGravityCommand(omni.kit.commands.Command):
    """The script's own command: set the scene's gravity, undoably."""

    def __init__(self, scene_path: str, magnitude: float):
        self._scene = UsdPhysics.Scene.Get(omni.usd.get_context().get_stage(), scene_path)
        self._magnitude, self._previous = magnitude, None

    def do(self):
        self._previous = self._scene.GetGravityMagnitudeAttr().Get()
        self._scene.GetGravityMagnitudeAttr().Set(self._magnitude)
        return self._previous

    def undo(self):
        self._scene.GetGravityMagnitudeAttr().Set(self._previous)


omni.kit.commands.register(SetGravityCommand)
result, previous = omni.kit.commands.execute("SetGravity", scene_path="/World/PhysicsScene", magnitude=3.71)
gravity = stage.GetPrimAtPath("/World/PhysicsScene").GetAttribute("physics:gravityMagnitude")
print(f"SetGravity: {result}, was {previous:.2f}, now {gravity.Get():.2f}")
omni.kit.undo.undo()
print(f"after undo: gravity {gravity.Get():.2f}")
simulation_app.close()
