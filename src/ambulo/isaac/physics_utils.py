"""The parts of ``omni.physx.scripts.physicsUtils`` that Isaac scripts use: authoring physics prims with pxr.

Everything here authors UsdGeom + UsdPhysics on the stage, exactly what the PhysX helpers
write; the World simulates those prims from the next ``reset()`` (``ambulo.sim.usd_stage``).
Vectors may be ``Gf`` values, tuples or arrays.
"""

from __future__ import annotations


def _pxr():
    from pxr import Gf, UsdGeom, UsdPhysics

    return Gf, UsdGeom, UsdPhysics


def _vec3(value, default=(0.0, 0.0, 0.0)):
    Gf, _, _ = _pxr()
    v = default if value is None else tuple(float(c) for c in value)
    return Gf.Vec3d(*v)


def _quat(value):
    Gf, _, _ = _pxr()
    if value is None:
        return Gf.Quatd(1.0, 0.0, 0.0, 0.0)
    if hasattr(value, "GetReal"):
        return Gf.Quatd(value.GetReal(), *value.GetImaginary())
    w, x, y, z = (float(c) for c in value)
    return Gf.Quatd(w, x, y, z)


def set_or_add_translate_op(xformable, translate) -> None:
    _, UsdGeom, _ = _pxr()
    xform = UsdGeom.Xformable(xformable)
    ops = [op for op in xform.GetOrderedXformOps() if op.GetOpType() == UsdGeom.XformOp.TypeTranslate]
    (ops[0] if ops else xform.AddTranslateOp(UsdGeom.XformOp.PrecisionDouble)).Set(_vec3(translate))


def set_or_add_orient_op(xformable, orient) -> None:
    _, UsdGeom, _ = _pxr()
    xform = UsdGeom.Xformable(xformable)
    ops = [op for op in xform.GetOrderedXformOps() if op.GetOpType() == UsdGeom.XformOp.TypeOrient]
    (ops[0] if ops else xform.AddOrientOp(UsdGeom.XformOp.PrecisionDouble)).Set(_quat(orient))


def set_or_add_scale_op(xformable, scale) -> None:
    _, UsdGeom, _ = _pxr()
    xform = UsdGeom.Xformable(xformable)
    ops = [op for op in xform.GetOrderedXformOps() if op.GetOpType() == UsdGeom.XformOp.TypeScale]
    (ops[0] if ops else xform.AddScaleOp(UsdGeom.XformOp.PrecisionDouble)).Set(_vec3(scale, (1.0, 1.0, 1.0)))


def _place(gprim, position, orientation, color) -> None:
    set_or_add_translate_op(gprim, position)
    set_or_add_orient_op(gprim, orientation)
    if color is not None:
        gprim.CreateDisplayColorAttr([_vec3(color)])


def _make_rigid(prim, density, lin_velocity, ang_velocity) -> None:
    _, _, UsdPhysics = _pxr()
    UsdPhysics.CollisionAPI.Apply(prim)
    body = UsdPhysics.RigidBodyAPI.Apply(prim)
    if lin_velocity is not None:
        body.CreateVelocityAttr(_vec3(lin_velocity))
    if ang_velocity is not None:
        body.CreateAngularVelocityAttr(_vec3(ang_velocity))
    if density is not None:
        UsdPhysics.MassAPI.Apply(prim).CreateDensityAttr(float(density))


def add_ground_plane(stage, planePath: str, axis: str = "Z", size: float = 25.0, position=None, color=None) -> str:
    """A static collision plane of half extent ``size`` through ``position``, normal along ``axis``."""
    _, UsdGeom, UsdPhysics = _pxr()
    UsdGeom.Xform.Define(stage, planePath)
    plane = UsdGeom.Plane.Define(stage, f"{planePath}/CollisionPlane")
    plane.CreateAxisAttr(str(axis).upper())
    plane.CreateWidthAttr(2.0 * float(size))
    plane.CreateLengthAttr(2.0 * float(size))
    _place(plane, position, None, color if color is not None else (0.5, 0.5, 0.5))
    UsdPhysics.CollisionAPI.Apply(plane.GetPrim())
    return planePath


def add_box(stage, path: str, size=(1.0, 1.0, 1.0), position=None, orientation=None, color=None):
    """A static box collider (a Cube of edge 1 scaled by ``size``)."""
    _, UsdGeom, UsdPhysics = _pxr()
    cube = UsdGeom.Cube.Define(stage, path)
    cube.CreateSizeAttr(1.0)
    _place(cube, position, orientation, color)
    set_or_add_scale_op(cube, size)
    UsdPhysics.CollisionAPI.Apply(cube.GetPrim())
    return cube.GetPrim()


def add_rigid_box(stage, path: str, size=(1.0, 1.0, 1.0), position=None, orientation=None, color=None,
                  density=None, lin_velocity=None, ang_velocity=None):
    """A dynamic box of edges ``size`` (a Cube of edge 1 scaled)."""
    prim = add_box(stage, path, size, position, orientation, color)
    _make_rigid(prim, density, lin_velocity, ang_velocity)
    return prim


def add_rigid_sphere(stage, path: str, radius: float = 1.0, position=None, orientation=None, color=None,
                     density=None, lin_velocity=None, ang_velocity=None):
    _, UsdGeom, _ = _pxr()
    sphere = UsdGeom.Sphere.Define(stage, path)
    sphere.CreateRadiusAttr(float(radius))
    _place(sphere, position, orientation, color)
    _make_rigid(sphere.GetPrim(), density, lin_velocity, ang_velocity)
    return sphere.GetPrim()


def _add_rigid_round(schema, stage, path, radius, height, axis, position, orientation, color, density,
                     lin_velocity, ang_velocity):
    """A dynamic capsule or cylinder (``schema``) of ``radius`` and ``height`` along ``axis``."""
    shape = schema.Define(stage, path)
    shape.CreateRadiusAttr(float(radius))
    shape.CreateHeightAttr(float(height))
    shape.CreateAxisAttr(str(axis).upper())
    _place(shape, position, orientation, color)
    _make_rigid(shape.GetPrim(), density, lin_velocity, ang_velocity)
    return shape.GetPrim()


def add_rigid_capsule(stage, path: str, radius: float = 1.0, height: float = 1.0, axis: str = "Y", position=None,
                      orientation=None, color=None, density=None, lin_velocity=None, ang_velocity=None):
    _, UsdGeom, _ = _pxr()
    return _add_rigid_round(UsdGeom.Capsule, stage, path, radius, height, axis, position, orientation, color,
                            density, lin_velocity, ang_velocity)


def add_rigid_cylinder(stage, path: str, radius: float = 1.0, height: float = 1.0, axis: str = "Y", position=None,
                       orientation=None, color=None, density=None, lin_velocity=None, ang_velocity=None):
    _, UsdGeom, _ = _pxr()
    return _add_rigid_round(UsdGeom.Cylinder, stage, path, radius, height, axis, position, orientation, color,
                            density, lin_velocity, ang_velocity)


__all__ = ["add_box", "add_ground_plane", "add_rigid_box", "add_rigid_capsule", "add_rigid_cylinder",
           "add_rigid_sphere", "set_or_add_orient_op", "set_or_add_scale_op", "set_or_add_translate_op"]
