"""Leg-inertial odometry's kinematics, checked by hand: a planted sole and a known joint motion give
the pelvis displacement that geometry says; the free joint (the true base pose) is never read."""

import math

import mujoco
import numpy as np
import pytest

from ambulo.navigation import NavWorld, NavWorldCfg
from ambulo.navigation.leg_odometry import LegOdometry
from ambulo.robots import humanoid


@pytest.fixture(scope="module")
def world(room):
    w = NavWorld.from_file(room, start_pose=(0.0, 0.0, 0.0), cfg=NavWorldCfg(camera_width=64, camera_height=48))
    yield w
    w.close()


def _walk_joints(legs, world, start, end, steps, t0_s, dt_s=0.005):
    """Move the encoders linearly from ``start`` to ``end`` over ``steps`` updates (no gyro: the
    attitude stays); returns the time after."""
    for k in range(1, steps + 1):
        legs.step(start + (end - start) * k / steps, t0_s + k * dt_s)
    return t0_s + steps * dt_s


def test_a_hip_swing_on_a_planted_sole_moves_the_pelvis_by_the_leg_times_sin(world):
    names = world.robot.joint_names
    q0 = world.robot.data.joint_pos[0].cpu().numpy().copy()
    legs = LegOdometry()
    legs.reset(world)
    start_xy = legs.xyyaw[:2].copy()
    # lift the right foot (bent knee, hip forward): the left sole is the planted one
    lifted = q0.copy()
    lifted[names.index("right_hip_pitch")] -= 0.4
    lifted[names.index("right_knee")] += 0.8
    t = _walk_joints(legs, world, q0, lifted, 100, world.time_s)
    assert legs.stance == 0
    np.testing.assert_allclose(legs.xyyaw[:2], start_xy, atol=1e-9)  # the planted leg did not move
    # the hand figure: the hip-to-sole distance L of the planted leg, swung by delta about the hip's
    # pitch axis (+y, right-handed: a leg hanging down swings back, to -x), carries the pelvis forward
    # by L sin(delta) along its heading
    data = mujoco.MjData(world.model)
    data.qpos[:] = world.model.qpos0
    mujoco.mj_kinematics(world.model, data)
    hip = data.xpos[world.model.body(humanoid.PRIM_PATH + "/left_thigh").id]
    sole = data.site_xpos[world.model.site(humanoid.PRIM_PATH + "/left_sole").id]
    leg_m = float(np.linalg.norm(hip - sole))
    delta = 0.1
    swung = lifted.copy()
    swung[names.index("left_hip_pitch")] += delta
    _walk_joints(legs, world, lifted, swung, 200, t)
    moved = legs.xyyaw[:2] - start_xy
    heading = np.array([math.cos(legs.xyyaw[2]), math.sin(legs.xyyaw[2])])
    assert moved @ heading == pytest.approx(leg_m * math.sin(delta), abs=0.01)
    assert abs(moved @ np.array([-heading[1], heading[0]])) < 0.01
    assert legs.coasted_steps == 0


def test_the_swing_sole_takes_over_when_it_lands_and_the_free_joint_is_never_read(world):
    names = world.robot.joint_names
    q0 = world.robot.data.joint_pos[0].cpu().numpy().copy()
    legs = LegOdometry()
    legs.reset(world)
    lift_right, lift_left = q0.copy(), q0.copy()
    lift_right[names.index("right_knee")] += 0.8
    lift_right[names.index("right_hip_pitch")] -= 0.4
    lift_left[names.index("left_knee")] += 0.8
    lift_left[names.index("left_hip_pitch")] -= 0.4
    free = world.robot.names.free_qpos_adr
    saved = world.engine.qpos[0, free:free + 7].clone()
    world.engine.qpos[0, free:free + 3] += 5.0  # a moved base would show if it were read
    try:
        t = _walk_joints(legs, world, q0, lift_right, 100, world.time_s)
        assert legs.stance == 0
        t = _walk_joints(legs, world, lift_right, q0, 100, t)  # both down: no reason to switch
        t = _walk_joints(legs, world, q0, lift_left, 100, t)
        assert legs.stance == 1 and legs.switches == 1
        np.testing.assert_allclose(legs.xyyaw[:2], np.zeros(2), atol=0.02)
    finally:
        world.engine.qpos[0, free:free + 7] = saved
