"""Kit's PhysX commands (``omni.physx.commands``): a physics scene, a ground plane, rigid bodies and
static colliders, authored with UsdPhysics as ``omni.physx.scripts.utils`` authors them.

The World simulates the authored prims from the next ``world.reset()``: the scene's gravity,
``RigidBodyAPI`` bodies, ``CollisionAPI`` colliders. MuJoCo collides a mesh by its convex
hull whatever ``approximationShape`` says (PhysX's "none" is the triangle mesh of a static
collider; a convex decomposition is several hulls).
"""

from __future__ import annotations

from .kit_commands import Command
from .physics_utils import add_ground_plane
from .usd_edit import command_stage as _stage


def _pxr():
    from pxr import Gf, Usd, UsdGeom, UsdPhysics

    return Gf, Usd, UsdGeom, UsdPhysics


def _prim(path, what: str):
    prim = _stage().GetPrimAtPath(str(path))
    if not prim.IsValid():
        raise ValueError(f"{what}: no prim at {str(path)!r}; check the path")
    return prim


def _colliders(prim, approximation: str) -> list:
    """CollisionAPI on the prim and every gprim under it (MeshCollisionAPI's approximation on meshes)."""
    _, Usd, UsdGeom, UsdPhysics = _pxr()
    applied = []
    for each in Usd.PrimRange(prim):
        if not each.IsA(UsdGeom.Gprim):
            continue
        UsdPhysics.CollisionAPI.Apply(each)
        if each.IsA(UsdGeom.Mesh):
            UsdPhysics.MeshCollisionAPI.Apply(each).CreateApproximationAttr().Set(approximation)
        applied.append(each)
    return applied


class AddPhysicsSceneCommand(Command):
    """A ``UsdPhysics.Scene`` at ``path``: Earth gravity down the stage's up axis, in stage units."""

    def __init__(self, stage=None, path: str = "/physicsScene"):
        self._stage, self._path = _stage(stage), str(path)

    def do(self):
        Gf, _, UsdGeom, UsdPhysics = _pxr()
        scene = UsdPhysics.Scene.Define(self._stage, self._path)
        scene.CreateGravityDirectionAttr().Set(Gf.Vec3f(0.0, 0.0, -1.0))
        scene.CreateGravityMagnitudeAttr().Set(9.81 / UsdGeom.GetStageMetersPerUnit(self._stage))

    def undo(self):
        self._stage.RemovePrim(self._path)


class AddGroundPlaneCommand(Command):
    """``physicsUtils.add_ground_plane``: a static collision plane; returns its path."""

    def __init__(self, stage=None, planePath: str = "/groundPlane", axis: str = "Z", size: float = 25.0,
                 position=None, color=None):
        self._stage, self._args = _stage(stage), (str(planePath), axis, size, position, color)

    def do(self) -> str:
        self._path = add_ground_plane(self._stage, *self._args)
        return self._path

    def undo(self):
        self._stage.RemovePrim(self._path)


class SetRigidBodyCommand(Command):
    """``utils.setRigidBody``: ``RigidBodyAPI`` on the prim (kinematic if asked) and ``CollisionAPI``
    on it and the gprims under it."""

    def __init__(self, path, approximationShape: str = "convexHull", kinematic: bool = False):
        self._path, self._approximation, self._kinematic = str(path), approximationShape, kinematic

    def do(self):
        _, _, _, UsdPhysics = _pxr()
        prim = _prim(self._path, "SetRigidBody")
        _colliders(prim, self._approximation)
        body = UsdPhysics.RigidBodyAPI.Apply(prim)
        if self._kinematic:
            body.CreateKinematicEnabledAttr().Set(True)

    def undo(self):
        RemoveRigidBodyCommand(self._path).do()
        RemoveStaticColliderCommand(self._path).do()


class SetStaticColliderCommand(Command):
    """``utils.setStaticCollider``: ``CollisionAPI`` on the prim and the gprims under it, no rigid body."""

    def __init__(self, path, approximationShape: str = "none"):
        self._path, self._approximation = str(path), approximationShape

    def do(self):
        _colliders(_prim(self._path, "SetStaticCollider"), self._approximation)

    def undo(self):
        RemoveStaticColliderCommand(self._path).do()


class RemoveRigidBodyCommand(Command):
    def __init__(self, path):
        self._path = str(path)

    def do(self):
        _, _, _, UsdPhysics = _pxr()
        _prim(self._path, "RemoveRigidBody").RemoveAPI(UsdPhysics.RigidBodyAPI)


class RemoveStaticColliderCommand(Command):
    def __init__(self, path):
        self._path = str(path)

    def do(self):
        _, Usd, _, UsdPhysics = _pxr()
        for each in Usd.PrimRange(_prim(self._path, "RemoveStaticCollider")):
            each.RemoveAPI(UsdPhysics.CollisionAPI)
            each.RemoveAPI(UsdPhysics.MeshCollisionAPI)


__all__: list[str] = []
