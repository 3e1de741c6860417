"""An Entity owns its initial state (mjlab's ``init_state``): a robot file's keyframe placed by the
frame the robot was attached at, written into every world once, and restored by every reset."""

import math

import mujoco
import numpy as np
import pytest
import torch

from ambulo.core import Entity, GroundCfg, KeyPose, PhysicsCfg, RobotCfg, Simulation, add_ground, add_robot, new_scene
from ambulo.core.entity import InitState


def started(robot_cfg: RobotCfg, num_worlds: int = 2):
    spec = new_scene()
    add_ground(spec, GroundCfg())
    attached = add_robot(spec, robot_cfg)
    sim = Simulation(spec, PhysicsCfg(timestep_s=0.005), num_worlds=num_worlds, num_threads=1)
    sim.start()
    return sim, attached


def test_a_keyframe_is_placed_by_the_robots_frame():
    yaw = math.pi / 2
    cfg = RobotCfg(file="humanoid", pos_m=(1.0, 2.0, 0.5), quat=(math.cos(yaw / 2), 0.0, 0.0, math.sin(yaw / 2)))
    key = KeyPose(joint_pos={"left_knee": 0.4}, root_pos_m=np.array([0.1, 0.0, 0.9]),
                  root_quat=np.array([1.0, 0.0, 0.0, 0.0]))
    state = InitState.from_keyframe(key, cfg, joint_pos={"right_knee": 0.3})
    # the frame turns the keyframe's 0.1 m along x into 0.1 m along y, then shifts it
    np.testing.assert_allclose(state.root_pos_m, (1.0, 2.1, 1.4), atol=1e-12)
    np.testing.assert_allclose(state.root_quat, cfg.quat, atol=1e-12)
    assert state.joint_pos == {"left_knee": 0.4, "right_knee": 0.3}
    # a fixed base has no root state to set
    fixed = InitState.from_keyframe(key, RobotCfg(file="humanoid", fixed_base=True))
    assert fixed.root_pos_m is None and fixed.root_quat is None and fixed.joint_pos == {"left_knee": 0.4}


def test_the_home_keyframe_becomes_every_worlds_start_and_what_reset_restores():
    sim, attached = started(RobotCfg(file="humanoid", pos_m=(0.5, -1.0, 0.0)))
    engine = sim.engine
    home = attached.keyframes["home"]
    robot = Entity(engine, "/World/robot", init_state=InitState.from_keyframe(home, RobotCfg(
        file="humanoid", pos_m=(0.5, -1.0, 0.0))))
    model = engine.model
    assert model.nkey == 0  # nothing compiled into the model: the state enters through the Entity
    qpos0 = engine.qpos.clone()
    robot.apply_init_state()
    knees = robot.find_joints(["left_knee", "right_knee"])
    torch.testing.assert_close(robot.data.joint_pos[:, knees], torch.full((2, 2), home.joint_pos["left_knee"],
                                                                            dtype=torch.float64))
    torch.testing.assert_close(robot.default_joint_pos, robot.data.joint_pos[0])
    torch.testing.assert_close(robot.data.root_pos_w, torch.tensor(
        [[0.5 + home.root_pos_m[0], -1.0 + home.root_pos_m[1], home.root_pos_m[2]]] * 2, dtype=torch.float64))
    assert not torch.equal(engine.qpos, qpos0)
    # the kinematics were recomputed: the pelvis body sits where the root state says
    torch.testing.assert_close(robot.data.body_pos_w[:, 0], robot.data.root_pos_w)
    # step away from it, then a reset of one world restores that world's initial state only
    robot.set_joint_targets(torch.zeros(2, robot.num_joints, dtype=torch.float64))
    for _ in range(20):
        sim.step()
    moved = engine.qpos.clone()
    sim.reset(torch.tensor([1]))
    torch.testing.assert_close(engine.qpos[0], moved[0])
    torch.testing.assert_close(robot.data.joint_pos[1], robot.default_joint_pos)
    assert float(engine.qvel[1].abs().max()) == 0.0 and float(engine.time[1]) == 0.0


def test_joints_it_does_not_name_keep_qpos0_and_bad_states_are_refused():
    sim, _ = started(RobotCfg(file="humanoid"), num_worlds=1)
    robot = Entity(sim.engine, "/World/robot", init_state=InitState(joint_pos={"left_elbow": 0.3}))
    robot.apply_init_state()
    pos = robot.data.joint_pos[0]
    elbow = robot.find_joints("left_elbow")[0]
    assert pos[elbow].item() == pytest.approx(0.3)
    others = [i for i in range(robot.num_joints) if i != elbow]
    torch.testing.assert_close(pos[others], torch.as_tensor(
        sim.engine.model.qpos0[robot._qpos_adr[others]], dtype=torch.float64))
    with pytest.raises(ValueError, match="unknown joints \\['elbow'\\]"):
        Entity(sim.engine, "/World/robot", init_state=InitState(joint_pos={"elbow": 0.1}))

    fixed, _ = started(RobotCfg(file="humanoid", fixed_base=True), num_worlds=1)
    with pytest.raises(ValueError, match="no free joint"):
        Entity(fixed.engine, "/World/robot", init_state=InitState(root_pos_m=(0.0, 0.0, 1.0)))
    assert mujoco.mjtJoint.mjJNT_FREE not in fixed.engine.model.jnt_type
