"""Physical outcomes of the core: drops, pendulum period, wheeled driving, PD behaviour."""

import math

import numpy as np
import pytest

from ambulo import assets
from ambulo.sim import (
    ArticulationAction,
    DifferentialController,
    DynamicCuboid,
    RigidPrim,
    Robot,
    WheeledRobot,
    World,
    add_reference_to_stage,
)
from ambulo.utils.rotations import quat_to_mat

PENDULUM_MJCF = """
<mujoco>
  <worldbody>
    <body name="pivot" pos="0 0 2">
      <body name="bob">
        <joint name="hinge" type="hinge" axis="0 1 0"/>
        <geom type="capsule" fromto="0 0 0 0 0 -{L}" size="0.002" mass="1e-6"/>
        <geom type="sphere" pos="0 0 -{L}" size="0.01" mass="1"/>
      </body>
    </body>
  </worldbody>
</mujoco>
"""


def _jetbot_world():
    world = World(physics_dt=0.005)
    world.scene.add_default_ground_plane()
    jetbot = world.scene.add(WheeledRobot(
        prim_path="/World/Fancy_Robot", name="fancy_robot", create_robot=True,
        usd_path=assets.path("jetbot"), wheel_dof_names=["left_wheel_joint", "right_wheel_joint"]))
    world.reset()
    return world, jetbot


def _drive(world, jetbot, command, seconds):
    controller = DifferentialController(wheel_radius=0.03, wheel_base=0.1125)
    for _ in range(int(round(seconds / world.get_physics_dt()))):
        jetbot.apply_wheel_actions(controller.forward(command))
        world.step()


def _yaw(quat):
    w, x, y, z = quat
    return math.atan2(2 * (w * z + x * y), 1 - 2 * (y * y + z * z))


def test_jetbot_drives_straight_0p6_m_in_2_s():
    world, jetbot = _jetbot_world()
    start = jetbot.get_world_pose()[0]
    _drive(world, jetbot, [0.3, 0.0], 2.0)
    moved = jetbot.get_world_pose()[0] - start
    assert moved[0] == pytest.approx(0.6, rel=0.15)
    assert abs(moved[1]) < 0.02  # straight
    assert abs(_yaw(jetbot.get_world_pose()[1])) < 0.05


def test_jetbot_turns_2_rad_in_2_s_at_1_rad_per_s():
    world, jetbot = _jetbot_world()
    _drive(world, jetbot, [0.0, 1.0], 2.0)
    assert _yaw(jetbot.get_world_pose()[1]) == pytest.approx(2.0, rel=0.15)
    assert np.linalg.norm(jetbot.get_world_pose()[0][:2]) < 0.05  # turned in place


def test_box_dropped_from_1_m_rests_at_half_height():
    world = World()
    world.scene.add_default_ground_plane()
    box = world.scene.add(DynamicCuboid(prim_path="/World/box", position=[0, 0, 1.0], size=0.2, mass=2.0))
    world.reset()
    assert box.get_mass() == pytest.approx(2.0)
    heights = []
    for _ in range(600):
        world.step()
        heights.append(box.get_world_pose()[0][2])
    assert min(heights[:80]) < 0.5  # it fell
    assert heights[-1] == pytest.approx(0.1, abs=0.002)
    assert np.linalg.norm(box.get_linear_velocity()) < 1e-3


@pytest.mark.parametrize("length_m", [0.5, 1.0])
def test_pendulum_period_matches_small_angle_formula(tmp_path, length_m):
    file = tmp_path / "pendulum.xml"
    file.write_text(PENDULUM_MJCF.format(L=length_m))
    world = World(physics_dt=0.001, integrator="rk4")
    add_reference_to_stage(usd_path=str(file), prim_path="/World/Pendulum")
    pendulum = world.scene.add(Robot(prim_path="/World/Pendulum"))
    world.reset()
    pendulum.get_articulation_controller().switch_control_mode("effort")
    pendulum.set_joint_positions([0.05])
    angles, times = [], []
    for _ in range(int(4.0 / 0.001)):
        world.step()
        angles.append(pendulum.get_joint_positions()[0])
        times.append(world.current_time)
    angles, times = np.array(angles), np.array(times)
    # downward zero crossings, linearly interpolated
    idx = np.flatnonzero((angles[:-1] > 0) & (angles[1:] <= 0))
    crossings = times[idx] + angles[idx] / (angles[idx] - angles[idx + 1]) * 0.001
    period = np.diff(crossings).mean()
    assert period == pytest.approx(2 * math.pi * math.sqrt(length_m / 9.81), rel=0.02)


def _held_arm(kp):
    """A 1 kg point mass on a 0.5 m arm held horizontal by the drive against gravity."""
    world = World(physics_dt=0.002)
    xml = PENDULUM_MJCF.format(L=0.5).replace('axis="0 1 0"', 'axis="0 1 0" ref="0"')
    import tempfile
    from pathlib import Path

    file = Path(tempfile.mkdtemp()) / "arm.xml"
    file.write_text(xml)
    add_reference_to_stage(usd_path=str(file), prim_path="/World/Arm")
    arm = world.scene.add(Robot(prim_path="/World/Arm"))
    world.reset()
    arm.get_articulation_controller().set_gains(kps=[kp], kds=[0.2 * math.sqrt(kp)])
    # horizontal: rotate the arm (hanging along -z) by -90 deg about +y so it points +x
    target = -math.pi / 2
    arm.set_joint_positions([target])
    arm.apply_action(ArticulationAction(joint_positions=[target]))
    for _ in range(3000):
        world.step()
    return arm.get_joint_positions()[0] - target, arm


def test_higher_stiffness_gives_smaller_steady_state_error():
    # steady state: kp * error = gravity torque m g L (hand-computed: 1 * 9.81 * 0.5 N*m)
    gravity_torque = 1.0 * 9.81 * 0.5
    err_soft, _ = _held_arm(100.0)
    err_stiff, arm = _held_arm(400.0)
    assert abs(err_soft) == pytest.approx(gravity_torque / 100.0, rel=0.05)
    assert abs(err_stiff) == pytest.approx(gravity_torque / 400.0, rel=0.05)
    assert abs(arm.get_measured_joint_efforts()[0]) == pytest.approx(gravity_torque, rel=0.02)


def test_humanoid_stands_10_s_under_pd_hold():
    world = World(physics_dt=0.005)
    world.scene.add_default_ground_plane()
    add_reference_to_stage(usd_path=assets.path("humanoid"), prim_path="/World/Humanoid")
    humanoid = world.scene.add(Robot(prim_path="/World/Humanoid"))
    world.reset()
    assert humanoid.num_dof == 21
    start = humanoid.get_world_pose()[0][2]
    lowest = start
    for _ in range(int(10.0 / 0.005)):
        world.step()
        lowest = min(lowest, humanoid.get_world_pose()[0][2])
    w, x, y, z = humanoid.get_world_pose()[1]
    tilt = math.degrees(math.acos(np.clip(1 - 2 * (x * x + y * y), -1, 1)))
    assert lowest > 0.9 * start
    assert tilt < 10.0


def test_rigid_prim_velocities_are_world_frame_at_the_body_origin():
    world = World(gravity=(0.0, 0.0, 0.0))
    rod = world.scene.add(DynamicCuboid(prim_path="/World/rod", position=[0, 0, 2.0], size=1.0,
                                        scale=[0.4, 0.1, 0.1], orientation=[np.cos(0.4), 0, 0, np.sin(0.4)]))
    world.reset()
    rod.set_linear_velocity([0.5, -0.2, 0.1])
    rod.set_angular_velocity([0.0, 0.0, 2.0])
    np.testing.assert_allclose(rod.get_linear_velocity(), [0.5, -0.2, 0.1], atol=1e-9)
    np.testing.assert_allclose(rod.get_angular_velocity(), [0.0, 0.0, 2.0], atol=1e-9)
    start_yaw = _yaw(rod.get_world_pose()[1])
    for _ in range(30):  # 0.5 s of free flight without gravity (Isaac's 1/60 s steps)
        world.step()
    assert _yaw(rod.get_world_pose()[1]) - start_yaw == pytest.approx(1.0, abs=1e-3)
    np.testing.assert_allclose(rod.get_world_pose()[0], [0.25, -0.1, 2.05], atol=1e-6)


# A free body whose frame origin is 0.3 m from its centre of mass: all its mass is a
# sphere centred at (0.3, 0, 0) in the body frame, so its inertia about the CoM is
# isotropic and, without gravity, both the CoM velocity and the angular velocity stay
# constant in the world frame.
OFFSET_ROTOR_MJCF = """
<mujoco>
  <worldbody>
    <body name="rotor" pos="0 0 2">
      <freejoint/>
      <geom type="sphere" pos="0.3 0 0" size="0.05" mass="1"/>
    </body>
  </worldbody>
</mujoco>
"""


def test_rigid_prim_linear_velocity_is_the_body_origin_not_the_com(tmp_path):
    com_b = np.array([0.3, 0.0, 0.0])  # centre of mass in the body frame (the sphere's centre)
    file = tmp_path / "rotor.xml"
    file.write_text(OFFSET_ROTOR_MJCF)
    world = World(physics_dt=0.001, gravity=(0.0, 0.0, 0.0))
    add_reference_to_stage(usd_path=str(file), prim_path="/World/Rotor")
    rotor = world.scene.add(RigidPrim(prim_path="/World/Rotor/rotor"))
    world.reset()
    v_origin0, omega = np.array([0.4, -0.1, 0.2]), np.array([0.5, -1.0, 2.0])
    rotor.set_linear_velocity(v_origin0)  # MuJoCo's free joint: velocity of the frame origin
    rotor.set_angular_velocity(omega)
    np.testing.assert_allclose(rotor.get_angular_velocity(), omega, atol=1e-9)
    np.testing.assert_allclose(rotor.get_linear_velocity(), v_origin0, atol=1e-9)

    # by hand: v_com = v_origin + w x (p_com - p_origin), constant in free flight
    p0, q0 = rotor.get_world_pose()
    r0 = quat_to_mat(q0) @ com_b  # p_com - p_origin at the start (identity rotation: (0.3, 0, 0))
    v_com = v_origin0 + np.cross(omega, r0)
    np.testing.assert_allclose(v_com, [0.4, 0.5, 0.5], atol=1e-12)  # w x (0.3, 0, 0) = (0, 0.6, 0.3)
    # nor is it the CoM's velocity: the two differ by |w x r| = 0.67 m/s
    assert np.linalg.norm(rotor.get_linear_velocity() - v_com) > 0.6

    for _ in range(300):  # 0.3 s: the body turns by |w| t = 0.69 rad about w
        world.step()
    p, q = rotor.get_world_pose()
    r = quat_to_mat(q) @ com_b
    assert np.linalg.norm(r - r0) > 0.1  # the offset has rotated
    np.testing.assert_allclose(rotor.get_angular_velocity(), omega, atol=1e-6)
    np.testing.assert_allclose(p + r, p0 + r0 + 0.3 * v_com, atol=2e-3)  # straight on (integrator drift ~4e-4)
    # v_origin = v_com + w x (p_origin - p_com)
    np.testing.assert_allclose(rotor.get_linear_velocity(), v_com + np.cross(omega, -r), atol=2e-3)


# A rod swinging about a hinge at its body origin: the origin is on the axis, so it does
# not move, while the centre of mass (0.5 m out) moves at w * 0.5 m.
HINGED_ROD_MJCF = """
<mujoco>
  <worldbody>
    <body name="rod" pos="0 0 1">
      <joint name="hinge" type="hinge" axis="0 1 0"/>
      <geom type="sphere" pos="0.5 0 0" size="0.05" mass="1"/>
    </body>
  </worldbody>
</mujoco>
"""


def test_rigid_prim_on_a_hinge_axis_has_zero_linear_velocity(tmp_path):
    file = tmp_path / "rod.xml"
    file.write_text(HINGED_ROD_MJCF)
    world = World(physics_dt=0.001, gravity=(0.0, 0.0, 0.0))
    add_reference_to_stage(usd_path=str(file), prim_path="/World/Rod")
    robot = world.scene.add(Robot(prim_path="/World/Rod"))
    rod = world.scene.add(RigidPrim(prim_path="/World/Rod/rod", name="rod_body"))
    world.reset()
    robot.set_joint_positions([0.7])
    robot.set_joint_velocities([3.0])
    # w = 3 rad/s about +y; the CoM, 0.5 m out, moves at 1.5 m/s, the origin not at all
    np.testing.assert_allclose(rod.get_angular_velocity(), [0.0, 3.0, 0.0], atol=1e-9)
    np.testing.assert_allclose(rod.get_linear_velocity(), [0.0, 0.0, 0.0], atol=1e-9)
