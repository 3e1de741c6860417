"""Entity/EntityData against hand-computed states, masked writes, air time, divergence dumps."""

import math

import mujoco
import numpy as np
import pytest
import torch

from ambulo.core import Entity, GroundCfg, PhysicsCfg, RobotCfg, Simulation, add_ground, add_robot, new_scene
from ambulo.core.entity import InitState
from ambulo.engine import CpuEngine
from ambulo.sensors import ContactSensor, ContactSensorCfg
from ambulo.utils.math import quat_from_axis_angle


def humanoid_sim(num_worlds=3, components=()):
    spec = new_scene()
    add_ground(spec, GroundCfg())
    add_robot(spec, RobotCfg(file="humanoid", prim_path="/World/robot", pos_m=(0.0, 0.0, 0.0)))
    sim = Simulation(spec, PhysicsCfg(timestep_s=0.005), num_worlds=num_worlds, num_threads=1)
    for c in components:
        sim.add(c)
    sim.start()
    return sim


def test_root_state_in_world_and_body_frames():
    sim = humanoid_sim()
    robot = Entity(sim.engine, "/World/robot")
    assert robot.is_floating and robot.num_joints == 21 and robot.body_names[0] == "pelvis"
    yaw = math.radians(90.0)
    quat = quat_from_axis_angle(torch.tensor([[0.0, 0.0, 1.0]], dtype=torch.float64),
                                torch.tensor([yaw], dtype=torch.float64))
    robot.write_root_pose(pos_w=torch.tensor([[1.0, 2.0, 3.0]], dtype=torch.float64).expand(3, 3),
                          quat_w=quat.expand(3, 4))
    # moving along world +x while facing +y is moving to the robot's right (-y in its frame)
    robot.write_root_velocity(lin_vel_w=torch.tensor([[1.0, 0.0, 0.0]], dtype=torch.float64).expand(3, 3),
                              ang_vel_w=torch.tensor([[0.0, 0.0, 0.5]], dtype=torch.float64).expand(3, 3))
    sim.engine.forward()
    data = robot.data
    torch.testing.assert_close(data.root_pos_w[0], torch.tensor([1.0, 2.0, 3.0], dtype=torch.float64))
    torch.testing.assert_close(data.root_lin_vel_b[0], torch.tensor([0.0, -1.0, 0.0], dtype=torch.float64))
    torch.testing.assert_close(data.root_ang_vel_b[0], torch.tensor([0.0, 0.0, 0.5], dtype=torch.float64))
    torch.testing.assert_close(data.root_ang_vel_w[0], torch.tensor([0.0, 0.0, 0.5], dtype=torch.float64))
    assert data.heading_w[0].item() == pytest.approx(yaw)
    torch.testing.assert_close(data.projected_gravity_b[0], torch.tensor([0.0, 0.0, -1.0], dtype=torch.float64))
    # derived body fields agree with the state after the kinematics pass
    torch.testing.assert_close(data.body_pos_w[:, 0], data.root_pos_w)
    torch.testing.assert_close(data.body_lin_vel_w[:, 0], data.root_lin_vel_w)


def test_masked_writes_change_only_the_masked_worlds():
    sim = humanoid_sim()
    robot = Entity(sim.engine, "/World/robot")
    before = sim.engine.qpos.clone()
    mask = torch.tensor([False, True, False])
    target = torch.full((3, robot.num_joints), 0.1, dtype=torch.float64)
    robot.write_joint_state(pos=target, env_ids=mask)
    robot.write_root_pose(pos_w=torch.zeros(3, 3, dtype=torch.float64), env_ids=mask)
    after = sim.engine.qpos
    assert torch.equal(after[[0, 2]], before[[0, 2]])
    torch.testing.assert_close(robot.data.joint_pos[1], target[1])
    assert torch.equal(robot.data.root_pos_w[1], torch.zeros(3, dtype=torch.float64))
    # index writes take one row per index
    robot.write_joint_state(pos=torch.zeros(1, robot.num_joints, dtype=torch.float64), env_ids=torch.tensor([2]))
    assert torch.equal(robot.data.joint_pos[2], torch.zeros(robot.num_joints, dtype=torch.float64))


def test_joint_targets_compose_kp_kd_and_effort_per_world():
    sim = humanoid_sim(num_worlds=2)
    robot = Entity(sim.engine, "/World/robot")
    kp = torch.tensor([[10.0], [20.0]], dtype=torch.float64).expand(2, robot.num_joints)
    robot.write_gains(kp=kp, kd=torch.full_like(kp, 2.0))
    pos, vel = torch.full_like(kp, 0.5), torch.full_like(kp, -1.0)
    robot.set_joint_targets(pos, vel, effort=torch.full_like(kp, 3.0))
    # ctrl = kp q* + kd qd* + tau = (5 - 2 + 3, 10 - 2 + 3)
    ctrl = sim.engine.ctrl[:, robot.actuator_idx]
    torch.testing.assert_close(ctrl[:, 0], torch.tensor([6.0, 11.0], dtype=torch.float64))
    torch.testing.assert_close(robot.data.joint_stiffness, kp)


def test_unknown_names_and_missing_drives_are_explained():
    sim = humanoid_sim(num_worlds=1)
    robot = Entity(sim.engine, "/World/robot")
    with pytest.raises(KeyError, match="unknown joint 'knee'"):
        robot.find_joints("knee")
    with pytest.raises(ValueError, match="unknown joints \\['elbow'\\]"):
        Entity(sim.engine, "/World/robot", init_state=InitState(joint_pos={"elbow": 0.1}))


def test_a_model_without_actuators_gives_an_entity_without_drives():
    model = mujoco.MjModel.from_xml_string("""<mujoco><worldbody><body name="/World/arm">
      <joint name="/World/arm/hinge" type="hinge" range="-1 1"/><geom size="0.1"/>
    </body></worldbody></mujoco>""")
    robot = Entity(CpuEngine(model, num_worlds=2), "/World/arm", require_drives=False)
    assert robot.joint_names == ["hinge"] and not robot.has_drives
    assert torch.isinf(robot.joint_effort_limits).all()  # no drive limits effort


def test_contact_air_time_of_a_dropped_foot_matches_free_fall():
    feet = ContactSensor(ContactSensorCfg(name="feet", prim_paths=("/World/robot/left_foot",),
                                          include_subtree=True, against="/World/defaultGroundPlane/geom"))
    sim = humanoid_sim(num_worlds=1, components=[feet])
    robot = Entity(sim.engine, "/World/robot")
    height = 0.5  # lift the whole robot 0.5 m: the foot falls freely until it lands
    robot.write_root_pose(pos_w=robot.data.root_pos_w + torch.tensor([0.0, 0.0, height], dtype=torch.float64))
    sim.engine.forward()
    sim.engine.capture_initial_state()
    sim.reset()
    dt, landed_at = 0.005, None
    for step in range(200):
        sim.step(1)
        frame = feet.get_current_frame()
        if frame.first_contact[0, 0]:
            landed_at = (step + 1) * dt
            break
        assert frame.current_air_time_s[0, 0] == pytest.approx((step + 1) * dt)
    fall_s = math.sqrt(2 * height / 9.81)  # 0.319 s
    assert landed_at == pytest.approx(fall_s, abs=3 * dt)
    assert frame.last_air_time_s[0, 0].item() == pytest.approx(landed_at)
    assert frame.current_air_time_s[0, 0] == 0.0
    sim.step(1)
    assert not feet.get_current_frame().first_contact[0, 0]  # touchdown is reported once
    sim.reset()
    assert feet.get_current_frame().last_air_time_s[0, 0] == 0.0


def test_a_diverged_world_is_dumped_before_it_is_reset(tmp_path):
    model = mujoco.MjModel.from_xml_string(
        "<mujoco><worldbody><body><freejoint/><geom size='0.1'/></body></worldbody></mujoco>")
    engine = CpuEngine(model, 3, num_threads=1, divergence_dump_dir=tmp_path)
    engine.qvel[1, 0] = float("nan")
    diverged = engine.step(1)
    assert diverged.tolist() == [False, True, False] and engine.num_diverged == 1
    dump = np.load(tmp_path / "diverged_000001.npz")
    assert dump["world_ids"].tolist() == [1]
    assert np.isnan(dump["state"]).any()  # the state that diverged, not the reset one
    assert mujoco.MjModel.from_binary_path(str(tmp_path / "model.mjb")).nq == 7
