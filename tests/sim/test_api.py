"""The public API surface and its errors for bad input."""

import numpy as np
import pytest

from ambulo import assets
from ambulo.sim import ArticulationAction, Robot, World, add_reference_to_stage


def test_public_names_importable_from_ambulo_sim():
    import ambulo.sim as sim

    for name in ("World", "Robot", "Articulation", "WheeledRobot", "ArticulationAction",
                 "DifferentialController", "XFormPrim", "RigidPrim", "add_reference_to_stage",
                 "get_assets_root_path", "set_camera_view"):
        assert hasattr(sim, name) and name in sim.__all__


def test_world_defaults_and_clock():
    world = World()
    assert world.current_time == 0.0
    world.scene.add_default_ground_plane()
    world.reset()
    for _ in range(10):
        world.step()
    assert world.current_time == pytest.approx(10 * world.get_physics_dt())
    world.pause()
    world.step()
    assert world.current_time == pytest.approx(10 * world.get_physics_dt())
    world.play()
    world.reset()
    assert world.current_time == 0.0


def test_physics_callbacks_run_every_physics_step_and_can_be_removed():
    world = World(physics_dt=0.01, rendering_dt=0.05)
    world.reset()
    calls = []
    world.add_physics_callback("count", lambda dt: calls.append(dt))
    world.step()
    assert calls == [0.01] * 5
    assert world.physics_callback_exists("count")
    world.remove_physics_callback("count")
    world.step()
    assert len(calls) == 5
    with pytest.raises(KeyError, match="no physics callback"):
        world.remove_physics_callback("count")


@pytest.fixture
def jetbot_world():
    world = World()
    world.scene.add_default_ground_plane()
    add_reference_to_stage(usd_path=assets.path("jetbot"), prim_path="/World/Jetbot")
    robot = world.scene.add(Robot(prim_path="/World/Jetbot", name="jetbot"))
    world.reset()
    return world, robot


def test_bad_actions_name_the_problem(jetbot_world):
    world, robot = jetbot_world
    with pytest.raises(ValueError, match=r"expected shape \(2,\)"):
        robot.apply_action(ArticulationAction(joint_velocities=[1.0, 2.0, 3.0]))
    with pytest.raises(ValueError, match="NaN"):
        robot.apply_action(ArticulationAction(joint_velocities=[float("nan"), 1.0]))
    with pytest.raises(KeyError, match="unknown joint 'front_wheel'"):
        robot.get_dof_index("front_wheel")
    with pytest.raises(KeyError, match="did you mean|Did you mean"):
        world.scene.get_object("jetbott")


def test_none_leaves_joints_uncommanded(jetbot_world):
    world, robot = jetbot_world
    robot.apply_action(ArticulationAction(joint_velocities=[3.0, 4.0]))
    robot.apply_action(ArticulationAction(joint_velocities=[None, -1.0]))
    applied = robot.get_applied_action().joint_velocities
    np.testing.assert_allclose(applied, [3.0, -1.0])


def test_batched_worlds_share_the_single_robot_api():
    world = World(num_worlds=4, backend="torch")
    world.scene.add_default_ground_plane()
    add_reference_to_stage(usd_path=assets.path("jetbot"), prim_path="/World/Jetbot")
    robot = world.scene.add(Robot(prim_path="/World/Jetbot"))
    world.reset()
    robot.get_articulation_controller().switch_control_mode("velocity")
    speeds = np.array([[0, 0], [5, 5], [10, 10], [-5, -5]], dtype=float)
    robot.apply_action(ArticulationAction(joint_velocities=speeds))
    for _ in range(200):
        world.step()
    x = robot.get_world_pose()[0][:, 0]
    assert x.shape == (4,)
    assert abs(float(x[0])) < 1e-3 and float(x[2]) > float(x[1]) > 0 > float(x[3])
