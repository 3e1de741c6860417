"""Values are validated at the boundary, and each error names the problem and the fix.

One case per kind of value of issue 8 item 5: physics dt, solver iterations, gravity,
num_worlds/num_envs, joint indices, actions (with efforts clipped to the drive's limit and
reported), poses, camera and lidar parameters, and ``--env-cfg`` overrides. Each asserts
both halves of the one-line message: what is wrong, and what to pass instead.
"""

from __future__ import annotations

import math

import mujoco
import numpy as np
import pytest
import torch

from ambulo import assets, envs
from ambulo.core import PhysicsCfg, Simulation, new_scene
from ambulo.core.physics import MAX_TIMESTEP_S, fastest_drive, timestep_warning
from ambulo.sensors.camera import Camera, CameraCfg
from ambulo.sensors.lidar import LidarCfg
from ambulo.sim import ArticulationAction, Robot, World, add_reference_to_stage
from ambulo.sim.world import MAX_PHYSICS_DT_S, MAX_RENDERING_DT_S
from ambulo.utils.checks import check_all_finite
from ambulo.utils.overrides import OverrideError, apply_overrides
from one_line import raises_one_line


@pytest.fixture(scope="module")
def jetbot():
    world = World(num_threads=1)
    world.scene.add_default_ground_plane()
    add_reference_to_stage(usd_path=assets.path("jetbot"), prim_path="/World/Jetbot")
    robot = world.scene.add(Robot(prim_path="/World/Jetbot", name="jetbot"))
    world.reset()
    return world, robot


# --- physics ---------------------------------------------------------------------------------


@pytest.mark.parametrize("dt, why", [(0.0, "must be > 0"), (-0.01, "must be > 0"),
                                     (math.nan, "must be finite"), (math.inf, "must be finite"),
                                     ("0.005", "expected a real number, got str")])
def test_physics_dt_must_be_a_positive_finite_number(dt, why):
    raises_one_line(lambda: PhysicsCfg(timestep_s=dt), "timestep_s is", why, "pass seconds, e.g. 0.005")
    raises_one_line(lambda: World(physics_dt=dt), "physics_dt is", why, "pass seconds")


def test_physics_dt_above_the_ceiling_is_refused_with_the_reason():
    too_large = 2 * MAX_TIMESTEP_S
    raises_one_line(lambda: PhysicsCfg(timestep_s=too_large), f"timestep_s is {too_large}",
            "make contacts soft", f"pass a step <= {MAX_TIMESTEP_S} s")
    # the World divides physics_dt into substeps: 0.1 s in 4 substeps is a 0.025 s MuJoCo step
    assert World(physics_dt=too_large, substeps=4).physics.timestep_s == pytest.approx(too_large / 4)
    world = World(substeps=1)  # a fixed substep count: 0.5 s would be one 0.5 s MuJoCo step
    raises_one_line(lambda: world.set_simulation_dt(physics_dt=0.5), "physics_dt / substeps is 0.5",
            "rendering_dt")
    raises_one_line(lambda: world.set_simulation_dt(physics_dt=-1.0), "physics_dt is -1.0", "must be > 0")
    assert world.get_physics_dt() == pytest.approx(1 / 60)  # a refused change leaves the World as it was


@pytest.mark.parametrize("make", [lambda: World(physics_dt=10), lambda: World().set_simulation_dt(physics_dt=10),
                                  lambda: World().set_simulation_dt(10, 10),
                                  lambda: World(physics=PhysicsCfg(timestep_s=0.005), substeps=2000)])
def test_a_physics_step_longer_than_any_control_loop_is_refused(make):
    # 10 s passed MuJoCo's step check (2000 substeps of 5 ms) and ran physics callbacks every 10 s
    raises_one_line(make, "physics_dt", "is 10.0", f"the limit is {MAX_PHYSICS_DT_S} s", "pass seconds, e.g. physics_dt=1/60")
    assert World(physics_dt=MAX_PHYSICS_DT_S).get_physics_dt() == MAX_PHYSICS_DT_S  # the bound itself is fine


@pytest.mark.parametrize("make", [lambda: World(rendering_dt=10), lambda: World().set_simulation_dt(rendering_dt=10)])
def test_a_rendering_step_longer_than_a_second_is_refused(make):
    raises_one_line(make, "rendering_dt is 10", f"the limit is {MAX_RENDERING_DT_S} s", "pass seconds, e.g. rendering_dt=1/60")
    world = World(physics_dt=0.01)
    raises_one_line(lambda: world.set_simulation_dt(rendering_dt=10.0), "rendering_dt is 10")
    assert world.get_rendering_dt() == 0.01  # a refused change leaves the World as it was


def test_isaac_physics_context_and_step_async_step_sizes_are_checked():
    import asyncio

    from ambulo.isaac.physics_context import PhysicsContext

    world = World()
    raises_one_line(lambda: PhysicsContext(physics_dt=10.0), "physics_dt is 10.0", "pass seconds")
    raises_one_line(lambda: asyncio.run(world.step_async(10.0)), "step_size is 10.0", "the limit is")
    raises_one_line(lambda: asyncio.run(world.step_async(0.01)), "step_size is 0.01", "set_simulation_dt")


def test_a_config_edited_after_construction_is_checked_at_compile():
    cfg = PhysicsCfg()
    cfg.timestep_s = -1.0
    raises_one_line(lambda: Simulation(new_scene(), cfg).start(), "timestep_s is -1.0", "pass seconds")


def test_timestep_too_large_for_the_stiffest_drive_warns():
    xml = """<mujoco><option timestep="{dt}"/><worldbody><body><joint name="j" type="hinge"/>
             <geom type="sphere" size="0.05" pos="0.2 0 0" mass="0.1"/></body></worldbody>
             <actuator><general joint="j" gainprm="1" biastype="affine" biasprm="0 -1000 0"/></actuator></mujoco>"""
    fine = mujoco.MjModel.from_xml_string(xml.format(dt=0.0005))
    joint, period = fastest_drive(fine)
    inertia = 1.0 / fine.dof_invweight0[0]
    assert joint == "j" and period == pytest.approx(2 * math.pi * math.sqrt(inertia / 1000.0))
    assert timestep_warning(fine) is None
    coarse = mujoco.MjModel.from_xml_string(xml.format(dt=0.01))
    message = timestep_warning(coarse)
    assert message is not None and "joint 'j'" in message and "use a timestep below" in message


@pytest.mark.parametrize("iterations, why", [(0, "must be >= 1"), (1.5, "expected a whole number, got float"),
                                             ("50", "expected a whole number, got str"),
                                             (True, "expected a whole number, got bool")])
def test_solver_iterations_must_be_a_whole_number(iterations, why):
    raises_one_line(lambda: PhysicsCfg(solver_iterations=iterations), "solver_iterations is", why,
            "pass a whole number >= 1")
    raises_one_line(lambda: World(solver_iterations=iterations), "solver_iterations is", why)


@pytest.mark.parametrize("gravity, why", [((0.0, -9.81), "expected 3 numbers, got 2"),
                                          ((0.0, 0.0, math.inf), "finite real number, not inf"),
                                          ("down", "expected 3 numbers, got str")])
def test_gravity_is_three_finite_numbers(gravity, why):
    raises_one_line(lambda: World(gravity=gravity), "gravity_m_s2 is", why, "e.g. (0, 0, -9.81)")


# --- sizes -----------------------------------------------------------------------------------


@pytest.mark.parametrize("count, why", [(0, "must be >= 1"), (2.5, "got float"), ("4", "got str"),
                                        (np.float64(2.0), "got float")])
def test_num_worlds_is_a_whole_number_of_at_least_one(count, why):
    raises_one_line(lambda: World(num_worlds=count), "num_worlds is", why, "e.g. num_worlds=64")
    raises_one_line(lambda: Simulation(new_scene(), PhysicsCfg(), num_worlds=count), "num_worlds is", why)


def test_numpy_integers_are_whole_numbers():
    assert World(num_worlds=np.int64(2)).num_worlds == 2


def test_num_envs_is_checked_by_make():
    raises_one_line(lambda: envs.make("cartpole", num_envs=0), "num_envs is 0", "e.g. num_envs=64")
    raises_one_line(lambda: envs.make_cfg("cartpole", num_envs="4"), "bad value '4' for num_envs: expected int",
            "pass a value of that type", kind=OverrideError)
    raises_one_line(lambda: envs.make_cfg("cartpole", num_envs=2.5), "bad value 2.5 for num_envs",
            kind=OverrideError)


# --- joints and actions ----------------------------------------------------------------------


@pytest.mark.parametrize("indices, why", [([0.0, 1.0], "not all whole numbers"),
                                          ([1, 1], "index 1 appears more than once"),
                                          (torch.tensor([0.5]), "not integers"),
                                          (["left_wheel_joint"], "not all whole numbers")])
def test_joint_indices_are_distinct_whole_numbers(jetbot, indices, why):
    _, robot = jetbot
    raises_one_line(lambda: robot.get_joint_positions(joint_indices=indices), "joint_indices is", why,
            "get_dof_index(name)")


def test_joint_index_out_of_range_is_still_an_index_error(jetbot):
    _, robot = jetbot
    raises_one_line(lambda: robot.get_joint_positions(joint_indices=[2]), "index 2 is out of range for 2 joints",
            "0..1", kind=IndexError)


@pytest.mark.parametrize("efforts, why", [(["a", "b"], "expected real numbers, got str"),
                                          ([1 + 2j, 0.0], "expected real numbers, got complex"),
                                          (np.array([1j, 0]), "expected real numbers"),
                                          (torch.tensor([1j, 0j]), "expected real numbers"),
                                          ([math.inf, 0.0], "inf at some entries"),
                                          ("fast", "expected numbers, got text")])
def test_actions_must_be_finite_real_numbers(jetbot, efforts, why):
    _, robot = jetbot
    before = robot.get_applied_action().joint_efforts.copy()
    raises_one_line(lambda: robot.apply_action(ArticulationAction(joint_efforts=efforts)), "joint_efforts is", why,
            "pass finite real numbers of shape (2,)")
    np.testing.assert_array_equal(robot.get_applied_action().joint_efforts, before)


def test_efforts_beyond_the_drive_limit_are_clipped_and_reported(jetbot):
    world, robot = jetbot
    limits = robot.entity.joint_effort_limits.numpy()
    assert np.isfinite(limits).all() and (limits[:, 1] > 0).all()  # the Jetbot's motors are limited
    robot.apply_action(ArticulationAction(joint_efforts=[10 * limits[0, 1], -10 * limits[1, 1]]))
    applied = robot.get_applied_action().joint_efforts
    np.testing.assert_allclose(applied, [limits[0, 1], limits[1, 0]])
    robot.apply_action(ArticulationAction(joint_efforts=[0.5 * limits[0, 1], None]))
    np.testing.assert_allclose(robot.get_applied_action().joint_efforts, [0.5 * limits[0, 1], limits[1, 0]])
    # what was applied is what the drives were given: ctrl = kp q* + kd qd* + tau_ff
    kp, kd = robot.get_articulation_controller().get_gains()
    act = robot.get_applied_action()
    ctrl = world.engine.ctrl[0, robot.entity.actuator_idx].numpy()
    np.testing.assert_allclose(ctrl, kp * act.joint_positions + kd * act.joint_velocities + act.joint_efforts)
    robot.apply_action(ArticulationAction(joint_efforts=[0.0, 0.0]))


def test_value_checks_do_not_read_tensors_off_the_cpu():
    # reading a CUDA tensor's values syncs the GPU; "meta" tensors have no values to read at all
    on_device = torch.empty(3, device="meta")
    assert check_all_finite("x", on_device, "fix") is on_device
    raises_one_line(lambda: check_all_finite("x", torch.tensor([0.0, math.nan]), "pass finite x"),
            "x is NaN at some entries", "pass finite x")


# --- poses -----------------------------------------------------------------------------------


def test_poses_refuse_inf_and_zero_quaternions(jetbot):
    _, robot = jetbot
    pos, quat = robot.get_world_pose()
    raises_one_line(lambda: robot.set_world_pose(position=[0.0, math.inf, 0.0]), "position is inf at some entries",
            "pass finite real numbers of shape (3,)")
    raises_one_line(lambda: robot.set_world_pose(orientation=[0.0, 0.0, 0.0, 0.0]), "orientation is a zero quaternion",
            "pass a (w, x, y, z) quaternion such as (1, 0, 0, 0)")
    raises_one_line(lambda: robot.set_default_state(orientation=[0.0, 0.0, 0.0, 0.0]), "zero quaternion")
    raises_one_line(lambda: robot.set_world_pose(position=[0.0, 0.0]), "position is of shape (2,)", "expected shape (3,)")
    raises_one_line(lambda: robot.set_world_pose(position=torch.tensor([1j, 0, 0])), "position is a torch.complex64 tensor",
            "expected real numbers", "pass finite real numbers")
    new_pos, new_quat = robot.get_world_pose()
    np.testing.assert_array_equal(new_pos, pos)
    np.testing.assert_array_equal(new_quat, quat)


def test_prim_constructor_pose_is_checked():
    World()
    add_reference_to_stage(usd_path=assets.path("jetbot"), prim_path="/World/Jetbot")
    raises_one_line(lambda: Robot(prim_path="/World/Jetbot", orientation=[0, 0, 0, 0]), "orientation is",
            "a zero quaternion is no rotation", "such as (1, 0, 0, 0)")
    raises_one_line(lambda: Robot(prim_path="/World/Jetbot", position=[0, 0, math.nan]), "position is",
            "finite real number, not nan", "pass (x, y, z) in m")


# --- sensors ---------------------------------------------------------------------------------


@pytest.mark.parametrize("kwargs, parts", [
    ({"width": 0}, ("width is 0", "must be >= 1", "pass whole pixels")),
    ({"resolution": (320.5, 240)}, ("width is 320.5", "got float")),
    ({"resolution": (320,)}, ("resolution is (320,)", "expected (width, height)", "resolution=(320, 240)")),
    ({"fovy_deg": 0.0}, ("fovy_deg is 0.0", "must be > 0", "pass degrees in (0, 180)")),
    ({"fovy_deg": 180.0}, ("fovy_deg is 180.0", "less than 180 deg", "pass degrees in (0, 180)")),
    ({"focal_length_px": -1.0}, ("focal_length_px is -1.0", "must be > 0", "or None to use fovy_deg")),
    ({"clipping_range_m": (10.0, 1.0)}, ("clipping_range_m is (10.0, 1.0)", "below the high end",
                                         "0 < near < far")),
    ({"clipping_range_m": (0.0, 1.0)}, ("near plane must be > 0", "0 < near < far")),
    ({"frequency_hz": 0.0}, ("frequency_hz is 0.0", "must be > 0", "or None to render on every request")),
    ({"offset_quat": (0, 0, 0, 0)}, ("offset_quat is", "zero quaternion", "(1, 0, 0, 0)")),
])
def test_camera_parameters(kwargs, parts):
    raises_one_line(lambda: Camera(prim_path="/World/cam", **kwargs), *parts)


@pytest.mark.parametrize("kwargs, parts", [
    ({"horizontal_fov_deg": 0.0}, ("horizontal_fov_deg is 0.0", "must be > 0", "(0, 360]")),
    ({"horizontal_fov_deg": 400.0}, ("horizontal_fov_deg is 400.0", "at most a full circle")),
    ({"horizontal_resolution_deg": 0.0}, ("horizontal_resolution_deg is 0.0", "must be > 0", "e.g. 1.0")),
    ({"min_range_m": 5.0, "max_range_m": 1.0}, ("(5.0, 1.0)", "below the high end", "0 <= min < max")),
    ({"min_range_m": -1.0}, ("low end must be >= 0", "0 <= min < max")),
    ({"elevations_deg": ()}, ("elevations_deg is ()", "one angle per channel", "(0.0,) for a 2D scan")),
    ({"elevations_deg": (0.0, 95.0)}, ("95 deg is beyond straight up", "[-90, 90]")),
    ({"range_noise_std_m": -0.1}, ("range_noise_std_m is -0.1", "must be >= 0", "0: no noise")),
])
def test_lidar_parameters(kwargs, parts):
    raises_one_line(lambda: LidarCfg(prim_path="/World/post/lidar", **kwargs), *parts)


def test_valid_sensor_configs_still_build():
    assert Camera(prim_path="/World/cam", resolution=(64, 48)).resolution == (64, 48)
    assert CameraCfg(prim_path="/World/cam", focal_length_px=100.0, fovy_deg=0.0).focal_length_px == 100.0
    assert LidarCfg(prim_path="/World/post", horizontal_fov_deg=90.0).horizontal_fov_deg == 90.0


# --- --env-cfg overrides ---------------------------------------------------------------------


@pytest.mark.parametrize("pair, parts", [
    ("num_envs=2.5", ("bad value '2.5' for num_envs: expected int", "e.g. num_envs=")),
    ("episode_length_s=nan", ("bad value 'nan' for episode_length_s", "give a finite one")),
    ("physics.gravity_m_s2=0,-9.81", ("expected tuple[float, float, float]", "give 3 values")),
    ("physics.timestep=0.01", ("unknown key 'physics.timestep'", "did you mean 'physics.timestep_s'?")),
    ("physics.timestep_s=-1", ("bad value -1.0 for physics.timestep_s: it must be > 0", "pass seconds")),
    ("physics.gravity_m_s2=0,0,inf", ("for physics.gravity_m_s2", "not inf", "e.g. (0, 0, -9.81)")),
    ("physics.solver_iterations=0", ("bad value 0 for physics.solver_iterations", "pass a whole number >= 1")),
])
def test_env_cfg_overrides_are_checked_against_the_config(pair, parts):
    cfg = envs.spec("cartpole").cfg_fn()
    raises_one_line(lambda: apply_overrides(cfg, [pair]), *parts, kind=OverrideError)
