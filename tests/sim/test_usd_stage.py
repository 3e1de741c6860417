"""The World's USD stage: pxr-authored prims become physics, mirrored ones stay placeholders."""

import mujoco
import numpy as np
import pytest

pxr = pytest.importorskip("pxr")
from pxr import Gf, Sdf, UsdGeom, UsdPhysics

from ambulo.sim.usd_stage import UsdStage


def _rigid_cube(stage, path, size, z):
    cube = UsdGeom.Cube.Define(stage, path)
    cube.GetSizeAttr().Set(size)
    cube.AddTranslateOp().Set(Gf.Vec3d(0, 0, z))
    UsdPhysics.RigidBodyAPI.Apply(cube.GetPrim())
    UsdPhysics.CollisionAPI.Apply(cube.GetPrim())
    return cube


def test_only_authored_prims_are_converted_and_mirrored_subtrees_are_skipped():
    usd = UsdStage()
    assert usd.physics_spec() is None  # nothing authored yet
    usd.mirror("/World/Robot")
    UsdGeom.Cube.Define(usd.stage, "/World/Robot/extra")  # under a mirrored prim: the MjSpec owns it
    _rigid_cube(usd.stage, "/World/cube", 0.5, 2.0)
    assert usd.authored_paths() == ["/World/cube"]
    spec = usd.physics_spec()
    assert [b.name for b in spec.bodies if b.name != "world"] == ["cube"]


def test_stage_units_are_converted_to_metres_and_the_cube_falls_to_rest():
    usd = UsdStage(meters_per_unit=0.01)  # centimetres
    _rigid_cube(usd.stage, "/World/cube", 50.0, 200.0)
    ground = UsdGeom.Cube.Define(usd.stage, "/World/ground")
    ground.GetSizeAttr().Set(100.0)
    ground.AddScaleOp().Set(Gf.Vec3f(10, 10, 0.1))  # 10 m x 10 m x 0.1 m, top at z = 0.05 m
    UsdPhysics.CollisionAPI.Apply(ground.GetPrim())
    scene = UsdPhysics.Scene.Define(usd.stage, "/World/physicsScene")
    scene.CreateGravityDirectionAttr(Gf.Vec3f(0, 0, -1))
    scene.CreateGravityMagnitudeAttr(981.0)  # cm/s^2
    assert usd.scene_gravity_m_s2() == pytest.approx((0, 0, -9.81))
    spec = usd.physics_spec()
    spec.option.gravity = usd.scene_gravity_m_s2()
    model = spec.compile()
    data = mujoco.MjData(model)
    for _ in range(int(2.0 / model.opt.timestep)):
        mujoco.mj_step(model, data)
    cube = model.body("cube").id
    np.testing.assert_allclose(data.xpos[cube], [0, 0, 0.05 + 0.25], atol=2e-3)


def test_physx_iteration_counts_are_read_from_bodies():
    usd = UsdStage()
    cube = _rigid_cube(usd.stage, "/World/cube", 0.5, 1.0).GetPrim()
    assert usd.solver_iterations() is None
    cube.CreateAttribute("physxRigidBody:solverPositionIterationCount", Sdf.ValueTypeNames.UInt).Set(32)
    assert usd.solver_iterations() == 32


def test_open_replaces_the_content_and_needs_a_default_prim(tmp_path):
    other = UsdStage()
    _rigid_cube(other.stage, "/World/box", 0.2, 0.5)
    file = tmp_path / "scene.usda"
    other.stage.GetRootLayer().Export(str(file))
    usd = UsdStage()
    usd.open(file)
    assert usd.stage.GetPrimAtPath("/World/box").IsValid()
    bare = tmp_path / "bare.usda"
    bare.write_text('#usda 1.0\n\ndef Xform "Thing"\n{\n}\n')
    with pytest.raises(ValueError, match="no default prim"):
        UsdStage().open(bare)
    with pytest.raises(FileNotFoundError, match="cannot open"):
        usd.open(tmp_path / "missing.usda")


def test_mirror_spec_makes_placeholders_for_api_objects_with_their_ancestors():
    spec = mujoco.MjSpec()
    frame = spec.worldbody.add_frame(name="/World/Robot")
    frame.add_body(name="/World/Robot/base").add_body(name="/World/Robot/base/wheel")
    spec.worldbody.add_body(name="unnamed_style")
    usd = UsdStage()
    usd.mirror_spec(spec)
    for path in ("/World/Robot", "/World/Robot/base", "/World/Robot/base/wheel"):
        assert usd.stage.GetPrimAtPath(path).IsValid() and usd.is_mirrored(path)
    assert not usd.stage.GetPrimAtPath("/World/unnamed_style")
    assert usd.authored_paths() == [] and usd.physics_spec() is None
