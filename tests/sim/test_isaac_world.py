"""The World with Isaac's defaults and its USD stage: pxr-authored prims are simulated."""

import asyncio
import math

import numpy as np
import pytest

pytest.importorskip("pxr")
from pxr import Gf, Sdf, UsdGeom, UsdPhysics

from ambulo import assets
from ambulo.isaac import physics_utils
from ambulo.isaac.semantics import add_update_semantics
from ambulo.isaac.stage_utils import get_current_stage
from ambulo.sim import (
    Articulation,
    DynamicCuboid,
    RigidPrim,
    Robot,
    World,
    add_reference_to_stage,
)


def test_default_step_is_isaacs_sixtieth_split_into_substeps_of_at_most_5_ms():
    world = World()
    assert world.get_physics_dt() == pytest.approx(1 / 60) and world.get_rendering_dt() == pytest.approx(1 / 60)
    assert world.substeps == 4 and world.physics.timestep_s == pytest.approx(1 / 240)
    world.set_simulation_dt(physics_dt=1 / 100)
    assert world.substeps == 2 and world.physics.timestep_s == pytest.approx(1 / 200)


def test_the_stiff_humanoid_stands_at_the_default_step():
    world = World()
    world.scene.add_default_ground_plane()
    add_reference_to_stage(usd_path=assets.path("humanoid"), prim_path="/World/Humanoid")
    humanoid = world.scene.add(Robot(prim_path="/World/Humanoid"))
    world.reset()
    start = humanoid.get_world_pose()[0][2]
    for _ in range(120):  # 2 s
        world.step(render=False)
    assert world.engine.num_diverged == 0
    assert humanoid.get_world_pose()[0][2] > 0.95 * start


def test_rendering_dt_not_a_multiple_of_physics_dt_keeps_time_on_average():
    world = World()
    world.scene.add_default_ground_plane()
    world.set_simulation_dt(physics_dt=1 / 500, rendering_dt=1 / 60)
    world.reset()
    counts = []
    for _ in range(60):
        before = world.current_time_step_index
        world.step(render=False)
        counts.append(world.current_time_step_index - before)
    assert set(counts) == {8, 9}  # 500/60 = 8.33 physics steps per frame
    assert sum(counts) in (499, 500)
    assert world.current_time == pytest.approx(1.0, abs=1 / 500 + 1e-9)


def test_render_refreshes_without_advancing_and_calls_render_callbacks():
    world = World()
    world.scene.add_default_ground_plane()
    world.reset()
    seen = []
    world.add_render_callback("count", lambda event: seen.append(event))
    world.render()
    assert world.current_time == 0.0 and len(seen) == 1
    world.step(render=True)
    assert len(seen) == 2 and world.current_time == pytest.approx(1 / 60)


def test_coroutine_forms_work_for_extension_samples():
    world = World()
    world.scene.add_default_ground_plane()

    async def load():
        await world.reset_async()
        await world.pause_async()
        assert not world.is_playing()
        await world.play_async()

    asyncio.run(load())
    assert world.is_playing()


def _cube(stage, path, edge, position, color=None):
    return physics_utils.add_rigid_box(stage, path, (edge, edge, edge), position, color=color)


def test_pxr_authored_prims_are_simulated_with_api_objects_and_referenced_files():
    world = World()
    world.scene.add_default_ground_plane()
    api_cube = world.scene.add(DynamicCuboid(prim_path="/World/api_cube", position=[1.0, 0, 0.5], size=0.2))
    add_reference_to_stage(usd_path=assets.path("jetbot"), prim_path="/World/Jetbot")
    stage = get_current_stage()  # a real Usd.Stage with the API objects mirrored on it
    assert stage.GetPrimAtPath("/World/Jetbot").IsValid() and stage.GetPrimAtPath("/World/api_cube").IsValid()
    _cube(stage, "/World/usd_cube", 0.4, (0, 1.0, 1.0), color=(1, 0, 0))
    add_update_semantics(stage.GetPrimAtPath("/World/usd_cube"), "crate")
    usd_cube = world.scene.add(RigidPrim(prim_path="/World/usd_cube", name="usd_cube"))
    world.reset()
    for _ in range(90):  # 1.5 s
        world.step(render=False)
    np.testing.assert_allclose(usd_cube.get_world_pose()[0], [0, 1.0, 0.2], atol=2e-3)  # resting on z = 0
    assert api_cube.get_world_pose()[0][2] == pytest.approx(0.1, abs=2e-3)
    model = world.model
    geom = model.geom("/World/usd_cube")
    np.testing.assert_allclose(geom.rgba, [1, 0, 0, 1])
    from ambulo.core.semantics import semantic_labels

    assert semantic_labels(model)[model.body("/World/usd_cube").id] == "crate"


def test_a_stage_edited_after_reset_is_recompiled_at_the_next_reset():
    world = World()
    world.scene.add_default_ground_plane()
    world.reset()
    bodies = world.model.nbody
    _cube(get_current_stage(), "/World/late_cube", 0.2, (0, 0, 0.5))
    world.reset()
    assert world.model.nbody == bodies + 1 and world.model.body("/World/late_cube").id > 0


def test_an_authored_revolute_joint_with_a_drive_is_an_articulation_that_holds_its_target():
    world = World(gravity=(0.0, 0.0, -9.81))
    stage = get_current_stage()
    UsdGeom.Xform.Define(stage, "/World/pendulum")
    link = UsdGeom.Capsule.Define(stage, "/World/pendulum/link")
    link.CreateRadiusAttr(0.03)
    link.CreateHeightAttr(0.4)
    link.AddTranslateOp().Set(Gf.Vec3d(0, 0, 1.0))
    UsdPhysics.RigidBodyAPI.Apply(link.GetPrim())
    UsdPhysics.CollisionAPI.Apply(link.GetPrim())
    UsdPhysics.MassAPI.Apply(link.GetPrim()).CreateMassAttr(1.0)
    hinge = UsdPhysics.RevoluteJoint.Define(stage, "/World/pendulum/hinge")
    hinge.CreateBody1Rel().SetTargets(["/World/pendulum/link"])
    hinge.CreateAxisAttr("Y")
    hinge.CreateLocalPos0Attr(Gf.Vec3f(0, 0, 1.25))
    hinge.CreateLocalPos1Attr(Gf.Vec3f(0, 0, 0.25))
    drive = UsdPhysics.DriveAPI.Apply(hinge.GetPrim(), "angular")
    drive.CreateStiffnessAttr(math.radians(200.0))  # UsdPhysics gains are per degree: 200 N m/rad
    drive.CreateDampingAttr(math.radians(20.0))
    pendulum = world.scene.add(Articulation(prim_path="/World/pendulum", name="pendulum"))
    world.reset()
    assert pendulum.num_dof == 1
    from ambulo.sim import ArticulationAction

    pendulum.apply_action(ArticulationAction(joint_positions=np.array([0.3])))
    for _ in range(120):
        world.step(render=False)
    # gravity torque on the 1 kg link at 0.25 m from the hinge sags it by m g l sin(q) / kp
    q = float(pendulum.get_joint_positions()[0])
    sag = 1.0 * 9.81 * 0.25 * math.sin(q) / 200.0
    assert q == pytest.approx(0.3 - sag, abs=0.01) or q == pytest.approx(0.3 + sag, abs=0.01)


def test_centimetre_stage_units_and_authored_gravity_and_velocity():
    world = World(stage_units_in_meters=0.01)
    stage = get_current_stage()
    assert UsdGeom.GetStageMetersPerUnit(stage) == 0.01
    physics_utils.add_ground_plane(stage, "/World/ground", "Z", 500.0, (0, 0, 0))
    scene = UsdPhysics.Scene.Define(stage, "/World/physicsScene")
    scene.CreateGravityDirectionAttr(Gf.Vec3f(0, 0, -1))
    scene.CreateGravityMagnitudeAttr(490.5)  # cm/s^2: half of Earth's
    _cube(stage, "/World/cube", 50.0, (0, 0, 100.0))
    ball = physics_utils.add_rigid_sphere(stage, "/World/ball", 10.0, (0, 300.0, 500.0), lin_velocity=(100.0, 0, 0))
    ball.CreateAttribute("physxRigidBody:solverPositionIterationCount", Sdf.ValueTypeNames.UInt).Set(30)
    world.reset()
    assert world.physics.gravity_m_s2 == pytest.approx((0, 0, -4.905))
    assert world.physics.solver_iterations == 30
    for _ in range(6):  # 0.1 s: the ball flies at 1 m/s along x, the cube has not landed yet
        world.step(render=False)
    ball_x = world.engine.field("xpos")[0, world.model.body("/World/ball").id, 0].item()
    assert ball_x == pytest.approx(0.1, abs=2e-3)
    for _ in range(150):
        world.step(render=False)
    cube_z = world.engine.field("xpos")[0, world.model.body("/World/cube").id, 2].item()
    assert cube_z == pytest.approx(0.25, abs=2e-3)  # 50 cm cube resting on the plane, in metres inside


def test_physx_helpers_author_round_shapes_that_stand_on_the_ground():
    world = World()
    stage = get_current_stage()
    physics_utils.add_ground_plane(stage, "/World/ground", "Z", 5.0, (0, 0, 0))
    physics_utils.add_rigid_cylinder(stage, "/World/can", 0.1, 0.4, "Z", (0, 0, 0.5))
    physics_utils.add_rigid_capsule(stage, "/World/pill", 0.1, 0.4, "Z", (1, 0, 0.5))
    world.reset()
    for _ in range(90):
        world.step(render=False)
    z = {name: world.engine.field("xpos")[0, world.model.body(f"/World/{name}").id, 2].item() for name in ("can", "pill")}
    assert z["can"] == pytest.approx(0.2, abs=3e-3)  # half its height
    assert z["pill"] == pytest.approx(0.3, abs=3e-3)  # half its straight part plus the cap's radius


def test_world_stage_answers_usd_calls_and_mjspec_calls():
    world = World()
    world.scene.add(DynamicCuboid(prim_path="/World/cube", size=0.2))
    assert world.stage.GetPrimAtPath("/World/cube").IsValid()  # Isaac: a Usd.Stage
    assert world.stage.body("/World/cube") is not None  # ambulo: the MjSpec
    UsdGeom.Sphere.Define(world.stage.usd_stage, "/World/ball")
    assert [p.GetName() for p in world.stage.GetPrimAtPath("/World").GetChildren()] == ["cube", "ball"]


def test_create_prim_with_a_file_places_it_in_stage_units():
    from ambulo.isaac.prim_utils import create_prim

    world = World(stage_units_in_meters=0.01)
    create_prim("/World/Jetbot", usd_path=assets.path("jetbot"), position=(100.0, 0.0, 0.0))
    world.reset()
    chassis_x_m = world.engine.field("xpos")[0, world.model.body("/World/Jetbot/chassis").id, 0].item()
    assert chassis_x_m == pytest.approx(1.0)  # 100 cm
