"""PhysX's schema attributes on a USD stage do in MuJoCo what they do in PhysX, where MuJoCo can."""

import math
import warnings

import mujoco
import numpy as np
import pytest

pytest.importorskip("pxr")
from pxr import Gf, UsdGeom, UsdPhysics

from ambulo.isaac.physx_schema import SCHEMAS  # the pxr.PhysxSchema classes
from ambulo.sim.usd_stage import UsdStage


def _sphere(stage, path, radius=0.1, position=(0.0, 0.0, 1.0), mass=1.0):
    sphere = UsdGeom.Sphere.Define(stage, path)
    sphere.CreateRadiusAttr(radius)
    sphere.AddTranslateOp().Set(Gf.Vec3d(*position))
    UsdPhysics.RigidBodyAPI.Apply(sphere.GetPrim())
    UsdPhysics.CollisionAPI.Apply(sphere.GetPrim())
    UsdPhysics.MassAPI.Apply(sphere.GetPrim()).CreateMassAttr(mass)
    return sphere.GetPrim()


def _compile(usd: UsdStage, timestep=1 / 120):
    model = usd.physics_spec().compile()
    model.opt.timestep = timestep
    model.opt.integrator = mujoco.mjtIntegrator.mjINT_IMPLICITFAST  # the World's integrator
    return model, mujoco.MjData(model)


@pytest.mark.parametrize("mass", [0.5, 4.0])
def test_damped_free_body_slows_as_exp_minus_c_t_whatever_its_mass(mass):
    usd = UsdStage()
    ball = _sphere(usd.stage, "/World/ball", mass=mass)
    physx = SCHEMAS["PhysxRigidBodyAPI"].Apply(ball)
    physx.CreateLinearDampingAttr(0.5)  # 1/s
    physx.CreateAngularDampingAttr(2.0)
    physx.CreateDisableGravityAttr(True)
    h = 1 / 120
    model, data = _compile(usd, h)
    data.qvel[:] = [2.0, -1.0, 0.5, 0.0, 3.0, 1.0]  # m/s; rad/s about the (isotropic) sphere's axes
    for _ in range(120):
        mujoco.mj_step(model, data)
    # dv/dt = -c v: exp(-c t) in continuous time; PhysX and implicit Euler both step v / (1 + c h).
    # (Gravity is disabled on the body: it would have taken 9.81 m/s off the vertical velocity.)
    np.testing.assert_allclose(data.qvel[:3], np.array([2.0, -1.0, 0.5]) / (1 + 0.5 * h) ** 120, rtol=1e-9, atol=1e-12)
    np.testing.assert_allclose(data.qvel[3:], np.array([0.0, 3.0, 1.0]) / (1 + 2.0 * h) ** 120, rtol=1e-9, atol=1e-12)
    np.testing.assert_allclose(data.qvel[:3], np.array([2.0, -1.0, 0.5]) * math.exp(-0.5), rtol=3e-3)


def test_contact_and_rest_offsets_set_the_margin_gap_and_rest_distance():
    usd = UsdStage()
    ground = UsdGeom.Cube.Define(usd.stage, "/World/ground")
    ground.AddScaleOp().Set(Gf.Vec3f(5, 5, 0.5))  # a 10 x 10 x 1 box, top at z = 0
    ground.AddTranslateOp().Set(Gf.Vec3d(0, 0, -1))
    UsdPhysics.CollisionAPI.Apply(ground.GetPrim())
    ball = _sphere(usd.stage, "/World/ball", position=(0.0, 0.0, 0.5))
    offsets = SCHEMAS["PhysxCollisionAPI"].Apply(ball)
    offsets.CreateContactOffsetAttr(0.05)
    offsets.CreateRestOffsetAttr(0.03)
    model, data = _compile(usd, 0.002)
    geom = model.geom("ball").id
    # MuJoCo 4 pushes closer than margin and detects at margin + gap; PhysX at restOffset and
    # contactOffset: margin = rest, gap = contact - rest
    assert model.geom_margin[geom] == pytest.approx(0.03)
    assert model.geom_gap[geom] == pytest.approx(0.02)
    for _ in range(1500):
        mujoco.mj_step(model, data)
    assert data.qpos[2] == pytest.approx(0.1 + 0.03, abs=1e-3)  # radius + rest offset above the ground


def _arm(usd: UsdStage, self_collisions: bool | None) -> None:
    """A base fixed to the world and two links on vertical hinges; link2 overlaps the base."""
    stage = usd.stage
    for name, size, position in (("base", (0.4, 0.1, 0.1), (0.0, 0.0, 0.3)), ("link1", (0.1, 0.1, 0.1), (0.25, 0, 0.45)),
                                 ("link2", (0.4, 0.1, 0.1), (0.0, 0.0, 0.36))):
        link = UsdGeom.Xform.Define(stage, f"/World/arm/{name}")
        link.AddTranslateOp().Set(Gf.Vec3d(*position))
        UsdPhysics.RigidBodyAPI.Apply(link.GetPrim())
        collider = UsdGeom.Cube.Define(stage, f"/World/arm/{name}/collision")
        collider.AddScaleOp().Set(Gf.Vec3f(*(s / 2 for s in size)))
        UsdPhysics.CollisionAPI.Apply(collider.GetPrim())
        UsdPhysics.MassAPI.Apply(collider.GetPrim()).CreateMassAttr(0.5)
    base = stage.GetPrimAtPath("/World/arm/base")
    UsdPhysics.ArticulationRootAPI.Apply(base)
    if self_collisions is not None:
        SCHEMAS["PhysxArticulationAPI"].Apply(base).CreateEnabledSelfCollisionsAttr(self_collisions)
    fixed = UsdPhysics.FixedJoint.Define(stage, "/World/arm/root_joint")
    fixed.CreateBody1Rel().SetTargets(["/World/arm/base"])
    fixed.CreateLocalPos0Attr(Gf.Vec3f(0.0, 0.0, 0.3))
    for name, parent, child, pos0, pos1 in (("joint1", "base", "link1", (0.25, 0, 0.1), (0, 0, -0.05)),
                                            ("joint2", "link1", "link2", (0, 0, -0.05), (0.25, 0, 0.04))):
        hinge = UsdPhysics.RevoluteJoint.Define(stage, f"/World/arm/{name}")
        hinge.CreateBody0Rel().SetTargets([f"/World/arm/{parent}"])
        hinge.CreateBody1Rel().SetTargets([f"/World/arm/{child}"])
        hinge.CreateAxisAttr("Z")
        hinge.CreateLocalPos0Attr(Gf.Vec3f(*pos0))
        hinge.CreateLocalPos1Attr(Gf.Vec3f(*pos1))


@pytest.mark.parametrize("self_collisions, expect_contacts", [(None, True), (True, True), (False, False)])
def test_disabling_self_collisions_removes_contacts_between_the_articulations_links(self_collisions, expect_contacts):
    usd = UsdStage()
    _arm(usd, self_collisions)
    model, data = _compile(usd)
    mujoco.mj_forward(model, data)
    base, link2 = model.body("arm/base").id, model.body("arm/link2").id
    pairs = {tuple(sorted(model.geom_bodyid[c.geom])) for c in data.contact[:data.ncon]}
    # base and link2 overlap by 4 cm; they are not parent and child, so MuJoCo's own filter keeps them
    assert (tuple(sorted((base, link2))) in pairs) is expect_contacts


def test_joint_armature_and_friction_reach_the_joint():
    usd = UsdStage()
    _arm(usd, None)
    for name in ("joint1", "joint2"):
        joint = SCHEMAS["PhysxJointAPI"].Apply(usd.stage.GetPrimAtPath(f"/World/arm/{name}"))
        joint.CreateArmatureAttr(0.01)
        joint.CreateJointFrictionAttr(0.05)
    model, _ = _compile(usd)
    g = float(np.linalg.norm(model.opt.gravity))
    for name, carried in (("joint1", 1.0), ("joint2", 0.5)):  # joint1 carries link1 and link2, 0.5 kg each
        dof = model.jnt_dofadr[model.joint(f"arm/{name}").id]
        assert model.dof_armature[dof] == pytest.approx(0.01)
        assert model.dof_frictionloss[dof] == pytest.approx(0.05 * carried * g)


def test_attributes_without_a_mujoco_meaning_are_named_in_one_warning():
    usd = UsdStage()
    ball = _sphere(usd.stage, "/World/ball")
    body = SCHEMAS["PhysxRigidBodyAPI"].Apply(ball)
    body.CreateEnableCCDAttr(True)
    body.CreateMaxLinearVelocityAttr(5.0)
    body.CreateSolverVelocityIterationCountAttr(1)  # PhysX's fallback: changes nothing, not named
    body.CreateLinearDampingAttr(0.1)  # honoured
    scene = UsdPhysics.Scene.Define(usd.stage, "/World/physicsScene")
    SCHEMAS["PhysxSceneAPI"].Apply(scene.GetPrim()).CreateBroadphaseTypeAttr("MBP")
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        usd.physics_spec()
    physx = [str(w.message) for w in caught if "PhysX attributes" in str(w.message)]
    assert len(physx) == 1 and len(physx[0].splitlines()) == 1
    assert physx[0].split("ignored: ")[1].split(" (")[0] == (
        "physxRigidBody:enableCCD, physxRigidBody:maxLinearVelocity, physxScene:broadphaseType")


def test_solver_iterations_are_the_largest_count_within_the_scenes_bounds():
    usd = UsdStage()
    for name, count in (("a", 8), ("b", 40)):
        SCHEMAS["PhysxRigidBodyAPI"].Apply(_sphere(usd.stage, f"/World/{name}")).CreateSolverPositionIterationCountAttr(
            count)
    assert usd.solver_iterations() == 40  # the island that asks most gets its count
    scene = SCHEMAS["PhysxSceneAPI"].Apply(UsdPhysics.Scene.Define(usd.stage, "/World/physicsScene").GetPrim())
    scene.CreateMaxPositionIterationCountAttr(32)
    assert usd.solver_iterations() == 32
    scene.GetMaxPositionIterationCountAttr().Set(255)
    scene.CreateMinPositionIterationCountAttr(100)
    assert usd.solver_iterations() == 100
