"""``from pxr import PhysxSchema`` under ``ambulo run``: PhysX's APIs author the stage as Isaac's do,
and the tutorial script's settings reach the simulation."""

import math
import sys
import warnings
from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("pxr")
from pxr import Sdf, Usd, UsdGeom, UsdPhysics

from ambulo.isaac import isaac_names, run_script
from script_loader import printed_number

ISAAC_EXAMPLES = Path(__file__).resolve().parents[2] / "examples" / "isaac"


def test_physx_schema_exists_only_under_ambulo_run():
    has_api = Usd.Prim.HasAPI
    with pytest.raises(ImportError):
        from pxr import PhysxSchema
    with isaac_names():
        import pxr
        from pxr import Gf, PhysxSchema, UsdPhysics  # noqa: F401 - Isaac's import line

        assert pxr.PhysxSchema is PhysxSchema and sys.modules["pxr.PhysxSchema"] is PhysxSchema
    assert "pxr.PhysxSchema" not in sys.modules and not hasattr(sys.modules["pxr"], "PhysxSchema")
    assert Usd.Prim.HasAPI is has_api  # usd-core's own method again


def test_apply_authors_the_api_schema_and_typed_attributes_as_isaac_does():
    stage = Usd.Stage.CreateInMemory()
    cube = UsdGeom.Cube.Define(stage, "/World/cube").GetPrim()
    scene = UsdPhysics.Scene.Define(stage, "/World/physicsScene").GetPrim()
    with isaac_names():
        from pxr import PhysxSchema

        assert PhysxSchema.PhysxRigidBodyAPI.CanApply(cube)
        body = PhysxSchema.PhysxRigidBodyAPI.Apply(cube)
        assert cube.HasAPI(PhysxSchema.PhysxRigidBodyAPI) and not cube.HasAPI(PhysxSchema.PhysxCollisionAPI)
        assert cube.HasAPI(UsdPhysics.RigidBodyAPI) is False  # usd-core's schemas still answer as before
        assert body.GetAngularDampingAttr().Get() == pytest.approx(0.05)  # PhysX's fallback, not authored
        body.CreateLinearDampingAttr(0.5)
        body.GetSolverPositionIterationCountAttr().Set(8)
        physx_scene = PhysxSchema.PhysxSceneAPI.Apply(scene)
        physx_scene.CreateSolverTypeAttr("TGS")
        physx_scene.CreateTimeStepsPerSecondAttr(120)
        PhysxSchema.PhysxLimitAPI.Apply(cube, "rotX").CreateDampingAttr(2.0)
        report = PhysxSchema.PhysxContactReportAPI.Get(stage, "/World/cube")
        report.CreateReportPairsRel().AddTarget("/World/physicsScene")
        assert PhysxSchema.Tokens.physxRigidBodyLinearDamping == "physxRigidBody:linearDamping"
    spec = stage.GetRootLayer().GetPrimAtPath("/World/cube")
    assert list(spec.GetInfo("apiSchemas").prependedItems) == ["PhysxRigidBodyAPI", "PhysxLimitAPI:rotX"]
    types = {name: (cube.GetAttribute(name).GetTypeName(), cube.GetAttribute(name).Get())
             for name in ("physxRigidBody:linearDamping", "physxRigidBody:solverPositionIterationCount",
                          "physxLimit:rotX:damping")}
    assert types == {"physxRigidBody:linearDamping": (Sdf.ValueTypeNames.Float, 0.5),
                     "physxRigidBody:solverPositionIterationCount": (Sdf.ValueTypeNames.Int, 8),
                     "physxLimit:rotX:damping": (Sdf.ValueTypeNames.Float, 2.0)}
    solver = scene.GetAttribute("physxScene:solverType")
    assert solver.GetVariability() == Sdf.VariabilityUniform and solver.GetTypeName() == Sdf.ValueTypeNames.Token
    assert scene.GetAttribute("physxScene:timeStepsPerSecond").GetTypeName() == Sdf.ValueTypeNames.UInt
    assert cube.GetRelationship("physxContactReport:reportPairs").GetTargets() == [Sdf.Path("/World/physicsScene")]


def test_physx_schema_tutorial_runs_and_its_settings_reach_the_simulation(capsys):
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        run_script(ISAAC_EXAMPLES / "physx_schema.py")
    out = capsys.readouterr().out
    # physxScene:timeStepsPerSecond = 120 is the World's physics step
    assert printed_number(out, "physics step: ", " s") == pytest.approx(1 / 120, abs=1e-6)
    # linear damping 0.5 and angular damping 1.0 for 1 s: 2 exp(-0.5) m/s and 2 pi exp(-1) rad/s
    # (stepped as PhysX does, v / (1 + c h) per step of h = 1/120 s)
    assert printed_number(out, "the ball moves at ", " m/s") == pytest.approx(2 * math.exp(-0.5), rel=3e-3)
    assert printed_number(out, "spins at ", " rad/s") == pytest.approx(2 * math.pi * math.exp(-1.0), rel=3e-3)
    # rest offset 0.02: the 0.2 m box rests 2 cm above the ground
    assert printed_number(out, "box at rest at height ", " m") == pytest.approx(0.1 + 0.02, abs=1e-3)
    # self-collisions disabled: the overlapping link is not pushed off its target
    assert abs(printed_number(out, "arm joint2 at ", " degrees")) < 0.05
    from ambulo.sim import World

    model = World.instance().engine.model
    assert model.opt.iterations == 64  # physxArticulation:solverPositionIterationCount
    g = float(np.linalg.norm(model.opt.gravity))
    for joint, carried_kg in (("/World/arm/joint1", 1.0), ("/World/arm/joint2", 0.5)):
        dof = model.jnt_dofadr[model.joint(joint).id]
        assert model.dof_armature[dof] == pytest.approx(0.01)
        assert model.dof_frictionloss[dof] == pytest.approx(0.05 * carried_kg * g)
    named = [str(w.message) for w in caught if "PhysX attributes" in str(w.message)]
    assert len(named) == 1
    assert named[0].split("ignored: ")[1].split(" (")[0] == ", ".join([
        "physxArticulation:solverVelocityIterationCount", "physxContactReport:threshold",
        "physxJoint:maxJointVelocity", "physxRigidBody:enableCCD", "physxScene:broadphaseType",
        "physxScene:enableCCD", "physxScene:enableGPUDynamics"])


def test_time_steps_per_second_sets_physics_dt_until_the_script_sets_another():
    from ambulo.sim import World

    world = World()
    scene = UsdPhysics.Scene.Define(world.usd.stage, "/World/physicsScene").GetPrim()
    with isaac_names():
        from pxr import PhysxSchema

        steps = PhysxSchema.PhysxSceneAPI.Apply(scene).CreateTimeStepsPerSecondAttr(100)
    world.reset()
    assert world.get_physics_dt() == pytest.approx(0.01)
    world.set_simulation_dt(physics_dt=1 / 50)  # Isaac writes this to the same attribute: it wins
    world.reset()
    assert world.get_physics_dt() == pytest.approx(0.02)
    steps.Set(200)  # until the stage's value changes again
    world.reset()
    assert world.get_physics_dt() == pytest.approx(0.005)
    assert world.engine.model.opt.timestep * world.substeps == pytest.approx(0.005)
