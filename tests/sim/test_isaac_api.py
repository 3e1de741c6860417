"""Isaac's tutorial-common prim/robot members and the view classes, checked against physics and hand values."""

import numpy as np
import pytest

from ambulo import assets
from ambulo.sim import (
    ArticulationAction,
    DynamicCuboid,
    Robot,
    WheeledRobot,
    World,
    XFormPrim,
    add_reference_to_stage,
)
from ambulo.sim.actions import ArticulationActions
from ambulo.sim.views import ArticulationView, RigidPrimView, match_prim_paths

SLIDER_MJCF = """
<mujoco>
  <compiler angle="radian"/>
  <worldbody>
    <body name="base" pos="0 0 1">
      <body name="carriage">
        <joint name="rail" type="slide" axis="1 0 0" range="-0.5 0.5"/>
        <geom type="box" size="0.05 0.05 0.05" mass="1"/>
        <body name="arm">
          <joint name="hinge" type="hinge" axis="0 1 0" range="-1 1"/>
          <geom type="capsule" fromto="0 0 0 0 0 -0.2" size="0.01" mass="0.1"/>
        </body>
      </body>
    </body>
  </worldbody>
</mujoco>
"""


def _jetbots(positions, num_worlds=1):
    world = World(num_worlds=num_worlds)
    world.scene.add_default_ground_plane()
    for i in range(len(positions)):
        add_reference_to_stage(usd_path=assets.path("jetbot"), prim_path=f"/World/envs/env_{i}/Jetbot")
    view = world.scene.add(ArticulationView("/World/envs/env_.*/Jetbot", name="jetbots", positions=positions))
    world.reset()
    return world, view


def test_view_over_three_jetbots_reports_their_poses_and_moves_only_selected_rows():
    placed = np.array([[0.0, 0.0, 0.0], [1.0, 0.5, 0.0], [-2.0, 1.0, 0.0]])
    world, view = _jetbots(placed)
    assert view.count == 3 and view.prim_paths == [f"/World/envs/env_{i}/Jetbot" for i in range(3)]
    positions, orientations = view.get_world_poses()
    # the chassis origin sits 0.03 m (the wheel radius) above its prim, as in the Jetbot file
    np.testing.assert_allclose(positions, placed + [0.0, 0.0, 0.03], atol=1e-9)
    np.testing.assert_allclose(orientations, np.tile([1.0, 0.0, 0.0, 0.0], (3, 1)), atol=1e-12)
    assert view.num_dof == 2 and view.dof_names == ["left_wheel_joint", "right_wheel_joint"]
    assert view.get_dof_index("right_wheel_joint") == 1
    view.set_world_poses(positions=np.array([[5.0, 5.0, 0.03]]), indices=[1])
    moved = view.get_world_poses()[0]
    np.testing.assert_allclose(moved[1], [5.0, 5.0, 0.03])
    np.testing.assert_allclose(moved[[0, 2]], (placed + [0, 0, 0.03])[[0, 2]], atol=1e-9)
    world.reset()  # back to the poses of initialization
    np.testing.assert_allclose(view.get_world_poses()[0], placed + [0.0, 0.0, 0.03], atol=1e-9)


def test_view_wheel_velocity_targets_drive_each_jetbot_its_own_way():
    world, view = _jetbots(np.array([[0.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 2.0, 0.0]]))
    for prim in view._prims:  # pure velocity control: kp = 0 (Isaac's "velocity" mode)
        prim.get_articulation_controller().switch_control_mode("velocity")
    view.apply_action(ArticulationActions(joint_velocities=np.array([[10.0, 10.0], [0.0, 0.0], [-10.0, -10.0]])))
    for _ in range(60):  # 1 s
        world.step()
    x = view.get_world_poses()[0][:, 0]
    # 10 rad/s on 0.03 m wheels is 0.3 m/s: forward, still, backward
    assert x[0] > 0.2 and abs(x[1]) < 0.01 and x[2] < -0.2
    np.testing.assert_allclose(view.get_applied_actions().joint_velocities[0], [10.0, 10.0])
    assert view.get_velocities().shape == (3, 6) and view.get_velocities()[0, 0] > 0.2
    view.set_joint_velocity_targets(np.array([[0.0, 0.0]]), indices=[2])
    np.testing.assert_allclose(view.get_applied_actions().joint_velocities[:, 0], [10.0, 0.0, 0.0])


def test_view_counts_every_world_world_major():
    world, view = _jetbots(np.array([[0.0, 0.0, 0.0], [1.0, 0.0, 0.0]]), num_worlds=2)
    assert view.count == 4
    positions = view.get_world_poses()[0]
    np.testing.assert_allclose(positions[:, 0], [0.0, 1.0, 0.0, 1.0], atol=1e-9)
    view.set_joint_positions(np.array([[0.5, -0.5]]), indices=[3])  # world 1, second robot
    np.testing.assert_allclose(view.get_joint_positions()[3], [0.5, -0.5])
    np.testing.assert_allclose(view.get_joint_positions()[:3], 0.0, atol=1e-12)


def test_path_expressions_match_whole_components():
    paths = ["/World/envs/env_0/Robot", "/World/envs/env_12/Robot", "/World/envs/env_1/Robot/chassis",
             "/World/envs/env_x/Robot"]
    assert match_prim_paths(["/World/envs/env_[0-9]+/Robot"], paths) == paths[:2]
    assert match_prim_paths(["/World/envs/env_1/Robot", "/World/envs/env_0/.*"], paths) == [paths[0]]


def test_rigid_prim_view_sets_and_reads_velocities_of_cubes():
    world = World(gravity=(0.0, 0.0, 0.0))
    for i in range(3):
        DynamicCuboid(prim_path=f"/World/cube_{i}", position=[0.0, 2.0 * i, 1.0], size=0.2)
    view = world.scene.add(RigidPrimView("/World/cube_[0-2]"))
    world.reset()
    view.set_velocities(np.array([[1.0, 0, 0, 0, 0, 0], [0, 2.0, 0, 0, 0, 0], [0, 0, 0, 0, 0, 3.0]]))
    world.step()
    velocities = view.get_velocities()
    np.testing.assert_allclose(velocities[:, :3], [[1.0, 0, 0], [0, 2.0, 0], [0, 0, 0]], atol=1e-9)
    np.testing.assert_allclose(velocities[2, 3:], [0, 0, 3.0], atol=1e-9)
    # no gravity, no contact: x = v t
    np.testing.assert_allclose(view.get_world_poses()[0][0], [1.0 / 60.0, 0.0, 1.0], atol=1e-9)
    np.testing.assert_allclose(view.get_masses(), 8 * 0.1**3 * 1000.0)


def test_joints_state_round_trips_and_defaults_return_after_reset():
    world = World()
    add_reference_to_stage(usd_path=assets.path("humanoid_tutorial"), prim_path="/World/Humanoid", fixed_base=True)
    robot = world.scene.add(Robot(prim_path="/World/Humanoid"))
    world.reset()
    start = robot.get_joints_default_state()
    positions = np.linspace(-0.04, 0.3, robot.num_dof)
    velocities = np.linspace(0.1, -0.1, robot.num_dof)
    robot.set_joints_state(positions=positions, velocities=velocities)
    state = robot.get_joints_state()
    np.testing.assert_allclose(state.positions, positions)
    np.testing.assert_allclose(state.velocities, velocities)
    assert state.efforts is None
    robot.set_joints_default_state(positions=positions)
    world.reset()
    np.testing.assert_allclose(robot.get_joint_positions(), positions)
    np.testing.assert_allclose(robot.get_joints_default_state().positions, positions)
    np.testing.assert_allclose(start.positions, 0.0)


def test_position_places_the_prim_and_default_state_places_the_root_exactly():
    world = World()
    world.scene.add_default_ground_plane()
    add_reference_to_stage(usd_path=assets.path("jetbot"), prim_path="/World/Jetbot")
    chassis = world.scene.add(XFormPrim(prim_path="/World/Jetbot/chassis", name="chassis"))
    robot = world.scene.add(Robot(prim_path="/World/Jetbot", position=[1.0, 2.0, 0.0]))
    world.reset()
    # Isaac places the referenced prim (the file's origin); the root body keeps its 0.03 m offset
    np.testing.assert_allclose(robot.get_world_pose()[0], [1.0, 2.0, 0.03])
    np.testing.assert_allclose(robot.get_local_pose()[0], [1.0, 2.0, 0.03])  # its parent is /World
    np.testing.assert_allclose(chassis.get_local_pose()[0], [0.0, 0.0, 0.03])  # relative to the robot prim
    robot.set_default_state(position=[3.0, -1.0, 0.5], orientation=[0.0, 0.0, 0.0, 1.0])
    world.reset()
    np.testing.assert_allclose(robot.get_world_pose()[0], [3.0, -1.0, 0.5])
    np.testing.assert_allclose(np.abs(robot.get_world_pose()[1]), [0.0, 0.0, 0.0, 1.0], atol=1e-12)
    default = robot.get_default_state()
    np.testing.assert_allclose(default.position, [3.0, -1.0, 0.5])
    assert robot.num_bodies == 3 and robot.body_names == ["chassis", "left_wheel", "right_wheel"]
    assert robot.prim.IsValid() and str(robot.prim.GetPath()) == "/World/Jetbot"


def test_a_cube_in_centimetres_falls_from_100_and_rests_at_half_its_size():
    world = World(stage_units_in_meters=0.01)
    world.scene.add_default_ground_plane()
    cube = world.scene.add(DynamicCuboid(prim_path="/World/cube", position=[0.0, 0.0, 100.0], size=50.0))
    world.reset()
    assert world.model.geom("/World/cube/geom").size[0] == pytest.approx(0.25)  # 50 cm edge = 0.25 m half
    for _ in range(6):  # 0.1 s of free fall: v = -g t in cm/s
        world.step()
    assert cube.get_linear_velocity()[2] == pytest.approx(-981.0 * 0.1, rel=0.02)
    for _ in range(114):
        world.step()
    assert cube.get_world_pose()[0][2] == pytest.approx(25.0, abs=0.5)
    assert cube.get_mass() == pytest.approx(0.5**3 * 1000.0)  # kg whatever the units


def test_prismatic_joints_scale_with_stage_units_and_revolute_do_not(tmp_path):
    file = tmp_path / "slider.xml"
    file.write_text(SLIDER_MJCF)
    world = World(stage_units_in_meters=0.01)
    add_reference_to_stage(usd_path=file, prim_path="/World/Slider")  # its base has no joint: fixed
    robot = world.scene.add(Robot(prim_path="/World/Slider"))
    world.reset()
    assert robot.dof_names == ["rail", "hinge"]
    robot.set_joint_positions([20.0, 0.5])  # 20 cm, 0.5 rad
    np.testing.assert_allclose(robot.entity.data.joint_pos[0].numpy(), [0.2, 0.5])
    np.testing.assert_allclose(robot.get_joint_positions(), [20.0, 0.5])
    np.testing.assert_allclose(robot.get_dof_limits(), [[-50.0, 50.0], [-1.0, 1.0]])
    carriage = world.scene.add(XFormPrim(prim_path="/World/Slider/carriage", name="carriage"))
    world.scene.add(carriage)
    carriage.initialize(world)
    assert carriage.get_world_pose()[0][0] == pytest.approx(20.0)  # cm
    robot.apply_action(ArticulationAction(joint_positions=[10.0, None]))
    assert robot.get_applied_action().joint_positions[0] == pytest.approx(10.0)
    assert robot.get_articulation_controller()._q_target[0, 0] == pytest.approx(0.1)


def test_efforts_turn_free_wheels_their_way_and_max_efforts_clip_them():
    world = World()
    add_reference_to_stage(usd_path=assets.path("jetbot"), prim_path="/World/Jetbot", fixed_base=True)
    robot = world.scene.add(WheeledRobot(prim_path="/World/Jetbot", wheel_dof_names=["left_wheel_joint",
                                                                                      "right_wheel_joint"]))
    world.reset()
    controller = robot.get_articulation_controller()
    controller.switch_control_mode("effort")
    controller.set_max_efforts(0.02)
    np.testing.assert_allclose(controller.get_max_efforts(), [0.02, 0.02])
    robot.set_joint_efforts([1.0, -1.0])  # clipped to +-0.02 N m
    np.testing.assert_allclose(controller.get_applied_action().joint_efforts, [0.02, -0.02])
    for _ in range(6):
        world.step()
    left, right = robot.get_wheel_velocities()
    assert left > 0.0 > right
    # omega = tau t / I with I the wheel's 1.8e-5 + 2e-4 armature (kg m^2), little damping
    assert left == pytest.approx(0.02 * 0.1 / 2.18e-4, rel=0.1)
    # the cap holds for the drives' PD output too: a far velocity target pulls with 0.02 N m only
    controller.switch_control_mode("velocity")
    robot.set_joint_efforts([0.0, 0.0])
    robot.apply_action(ArticulationAction(joint_velocities=[1000.0, -1000.0]))
    world.step()
    np.testing.assert_allclose(robot.get_measured_joint_efforts(), [0.02, -0.02], rtol=1e-6)
    robot.set_wheel_velocities([3.0, 4.0])
    np.testing.assert_allclose(robot.get_wheel_velocities(), [3.0, 4.0])
    robot.set_wheel_positions([1.0, 2.0])
    np.testing.assert_allclose(robot.get_wheel_positions(), [1.0, 2.0])


def test_rigid_prim_constructor_mass_and_velocity_and_gravity_switch():
    world = World(gravity=(0.0, 0.0, 0.0))
    cube = world.scene.add(DynamicCuboid(prim_path="/World/cube", position=[0, 0, 2.0], size=0.1, mass=2.0,
                                         linear_velocity=[1.0, 0.0, 0.0], angular_velocity=[0.0, 0.0, 1.0]))
    world.reset()
    assert cube.get_mass() == pytest.approx(2.0)
    state = cube.get_current_dynamic_state()
    np.testing.assert_allclose(state.linear_velocity, [1.0, 0.0, 0.0])
    np.testing.assert_allclose(state.angular_velocity, [0.0, 0.0, 1.0])
    for _ in range(30):
        world.step()
    world.reset()  # the constructor's velocities are the default state
    np.testing.assert_allclose(cube.get_linear_velocity(), [1.0, 0.0, 0.0])
    np.testing.assert_allclose(cube.get_default_state().position, [0.0, 0.0, 2.0])


def test_disable_gravity_keeps_a_robot_floating():
    world = World()
    add_reference_to_stage(usd_path=assets.path("jetbot"), prim_path="/World/Jetbot")
    robot = world.scene.add(Robot(prim_path="/World/Jetbot", position=[0.0, 0.0, 1.0]))
    world.reset()
    robot.disable_gravity()
    for _ in range(30):
        world.step()
    assert robot.get_world_pose()[0][2] == pytest.approx(1.03, abs=1e-6)
    robot.enable_gravity()
    for _ in range(30):  # 0.5 s of free fall (no ground): semi-implicit Euler drops g h^2 n (n + 1) / 2
        world.step()
    h, n = world.physics_dt / world.substeps, 30 * world.substeps
    assert robot.get_world_pose()[0][2] == pytest.approx(1.03 - 9.81 * h**2 * n * (n + 1) / 2, abs=1e-6)
    velocity = robot.get_world_velocity()
    assert velocity.shape == (6,) and velocity[2] == pytest.approx(-9.81 * 0.5, rel=0.01)


def test_articulation_action_helpers_follow_isaac():
    action = ArticulationAction(joint_positions=np.array([0.1, 0.2]), joint_velocities=[None, 3.0],
                                joint_efforts=[1.0, None])
    assert action.get_length() == 2
    assert action.get_dict() == {"joint_positions": [0.1, 0.2], "joint_velocities": [None, 3.0],
                                 "joint_efforts": [1.0, None]}
    assert action.get_dof_action(0) == {"effort": 1.0}
    assert action.get_dof_action(1) == {"velocity": 3.0, "position": 0.2}
    assert ArticulationAction().get_length() is None
