"""``physics:jointEnabled = false``: the joint does not connect its bodies, as in PhysX."""

import warnings

import mujoco
import numpy as np
import pytest

pytest.importorskip("pxr")
from pxr import Gf, Usd, UsdGeom, UsdPhysics

from ambulo.core.importers.usd import load_usd


def _box(stage, path, z):
    cube = UsdGeom.Cube.Define(stage, path)
    cube.CreateSizeAttr(0.2)
    cube.AddTranslateOp().Set(Gf.Vec3d(0, 0, z))
    UsdPhysics.RigidBodyAPI.Apply(cube.GetPrim())
    UsdPhysics.CollisionAPI.Apply(cube.GetPrim())
    UsdPhysics.MassAPI.Apply(cube.GetPrim()).CreateMassAttr(1.0)


def _chain(path, disabled: set[str], robot_file: str | None = None) -> None:
    """World -fixed- a -revolute j1- b -revolute j2- c, hanging 0.5 m apart (in ``robot_file``,
    referenced from ``path``, when given: relative references must survive)."""
    stage = Usd.Stage.CreateNew(str(robot_file or path))
    UsdGeom.SetStageUpAxis(stage, "Z")
    UsdGeom.SetStageMetersPerUnit(stage, 1.0)
    stage.SetDefaultPrim(UsdGeom.Xform.Define(stage, "/World").GetPrim())
    for name, z in (("a", 2.0), ("b", 1.5), ("c", 1.0)):
        _box(stage, f"/World/{name}", z)
    fixed = UsdPhysics.FixedJoint.Define(stage, "/World/j0")
    fixed.CreateBody1Rel().SetTargets(["/World/a"])
    fixed.CreateLocalPos0Attr(Gf.Vec3f(0, 0, 2.0))
    for name, parent, child in (("j1", "a", "b"), ("j2", "b", "c")):
        joint = UsdPhysics.RevoluteJoint.Define(stage, f"/World/{name}")
        joint.CreateBody0Rel().SetTargets([f"/World/{parent}"])
        joint.CreateBody1Rel().SetTargets([f"/World/{child}"])
        joint.CreateAxisAttr("X")
        joint.CreateLocalPos0Attr(Gf.Vec3f(0, 0, -0.25))
        joint.CreateLocalPos1Attr(Gf.Vec3f(0, 0, 0.25))
    for name in disabled:
        UsdPhysics.Joint(stage.GetPrimAtPath(f"/World/{name}")).CreateJointEnabledAttr(False)
    stage.GetRootLayer().Save()
    if robot_file:
        top = Usd.Stage.CreateNew(str(path))
        UsdGeom.SetStageUpAxis(top, "Z")
        UsdGeom.SetStageMetersPerUnit(top, 1.0)
        top.SetDefaultPrim(top.DefinePrim("/World"))
        top.GetPrimAtPath("/World").GetReferences().AddReference(f"./{robot_file.name}")
        top.GetRootLayer().Save()


def _load(path):
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        spec = load_usd(path)
    assert not [w for w in caught if "dropped" in str(w.message)]  # left out on purpose: no warning
    return spec


def _joint_types(spec, body: str) -> list:
    return [j.type for j in spec.body(body).joints]


def test_enabled_joints_make_one_tree(tmp_path):
    _chain(tmp_path / "chain.usda", set())
    spec = _load(tmp_path / "chain.usda")
    assert spec.body("c").parent.name == "b" and spec.body("b").parent.name == "a"
    assert _joint_types(spec, "a") == [] and spec.body("a").parent.name == "world"  # welded to the world


@pytest.mark.parametrize("referenced", [False, True])
def test_a_disabled_joint_frees_its_body_which_keeps_the_links_below_it(tmp_path, referenced):
    _chain(tmp_path / "chain.usda", {"j1"}, tmp_path / "robot.usda" if referenced else None)
    spec = _load(tmp_path / "chain.usda")
    assert spec.joint("j1") is None and spec.joint("j2") is not None
    assert spec.body("b").parent.name == "world" and _joint_types(spec, "b") == [mujoco.mjtJoint.mjJNT_FREE]
    assert spec.body("c").parent.name == "b"
    model = spec.compile()
    data = mujoco.MjData(model)
    for _ in range(250):  # 0.5 s at MuJoCo's 2 ms
        mujoco.mj_step(model, data)
    b, c, a = (model.body(name).id for name in ("b", "c", "a"))
    fallen = 0.5 * 9.81 * data.time ** 2  # free fall, g t^2 / 2 (to 1%: MuJoCo's Euler steps)
    # b and c fall together (nothing below them yet); a stays welded to the world
    assert 1.5 - data.xpos[b][2] == pytest.approx(fallen, rel=0.01)
    assert np.linalg.norm(data.xpos[b] - data.xpos[c]) == pytest.approx(0.5, abs=1e-6)
    assert data.xpos[a][2] == pytest.approx(2.0)


def test_a_disabled_fixed_joint_to_the_world_lets_the_body_fall(tmp_path):
    _chain(tmp_path / "chain.usda", {"j0"})
    spec = _load(tmp_path / "chain.usda")
    assert _joint_types(spec, "a") == [mujoco.mjtJoint.mjJNT_FREE]
    model = spec.compile()
    data = mujoco.MjData(model)
    for _ in range(250):
        mujoco.mj_step(model, data)
    assert 2.0 - data.xpos[model.body("a").id][2] == pytest.approx(0.5 * 9.81 * data.time ** 2, rel=0.01)
