"""The policy walker stands still when told to: the position hold keeps it within a few cm over
10 s (the shipped policy commanded zero creeps ~4 cm/s: 0.41 m in 10 s on this floor)."""

import math

import numpy as np
import pytest

from ambulo.navigation import NavWorld, NavWorldCfg
from ambulo.navigation.stand_hold import PositionHold, StandHoldCfg
from ambulo.navigation.walkers import PolicyWalker

pytest.importorskip("onnxruntime")


def test_the_hold_commands_back_towards_the_held_pose_in_the_heading_frame():
    """Held at (1, 2) facing +y; the robot 0.1 m further along +y (ahead of it) and turned 0.2 rad
    left: P alone (ki = 0) commands 2 /s * -0.1 m = -0.2 m/s forward, 0 sideways, -0.2 rad/s."""
    hold = PositionHold(StandHoldCfg(gain_per_s=2.0, integral_gain_per_s2=0.0, yaw_gain_per_s=1.0))
    assert hold.command((1.0, 2.0, math.pi / 2), 0.02) == pytest.approx((0.0, 0.0, 0.0))
    vx, vy, wz = hold.command((1.0, 2.1, math.pi / 2 + 0.2), 0.02)
    # the heading frame is turned 0.2 rad: the error (0, -0.1) world reads (-0.1 cos 0.2, 0.1 sin 0.2)
    assert (vx, vy) == pytest.approx((-0.2 * math.cos(0.2), 0.2 * math.sin(0.2)))
    assert wz == pytest.approx(-0.2)
    # the integral term grows with a standing error and stops at its bias limit (anti-windup)
    pi = PositionHold(StandHoldCfg(gain_per_s=0.0, integral_gain_per_s2=1.0, max_bias_m_s=0.1))
    pi.command((0.0, 0.0, 0.0), 0.02)
    first = pi.command((-0.05, 0.0, 0.0), 0.02)[0]
    assert first == pytest.approx(0.05 * 0.02)
    for _ in range(500):
        last = pi.command((-0.05, 0.0, 0.0), 0.02)[0]
    assert last == pytest.approx(0.1)


def test_the_policy_walker_stands_still_for_ten_seconds(room):
    world = NavWorld.from_file(room, start_pose=(-1.0, 0.0, 0.0), cfg=NavWorldCfg(record_gyro=False))
    walker = PolicyWalker()
    walker.bind(world)
    walker.reset()
    walker.stand()
    start = world.true_pose()
    drift = []
    for _ in range(int(10.0 / world.dt_s)):
        walker.step(world.dt_s, world.true_pose())
        world.step()
        drift.append(float(np.linalg.norm(world.true_pose()[:2] - start[:2])))
    assert not world.fell
    assert max(drift) < 0.08, max(drift)
    assert drift[-1] < 0.05, drift[-1]
    assert abs(world.true_pose()[2] - start[2]) < 0.05
    world.close()


def test_a_turn_on_the_spot_holds_the_position_and_keeps_its_rate():
    """``turn_command``: the commanded yaw rate as given, the position pulled back to where the turn
    began, and the held heading follows the robot (standing after the turn keeps the new heading)."""
    hold = PositionHold(StandHoldCfg(gain_per_s=2.0, integral_gain_per_s2=0.0))
    assert hold.turn_command((1.0, 2.0, 0.0), 0.02, 0.6) == pytest.approx((0.0, 0.0, 0.6))
    vx, vy, wz = hold.turn_command((1.1, 2.0, 1.0), 0.02, 0.6)  # 0.1 m off along +x, turned 1 rad
    assert wz == 0.6
    assert (vx, vy) == pytest.approx((-0.2 * math.cos(1.0), 0.2 * math.sin(1.0)))
    assert hold.command((1.0, 2.0, 1.0), 0.02)[2] == pytest.approx(0.0)  # no turn back to yaw 0


def test_the_policy_walker_turns_on_the_spot_without_walking_off(room):
    """Told to turn at 0.5 rad/s (``scan``: look turns, the lost robot's sweep) for 5 s, the pelvis
    stays within a few cm of where it began; open loop it wandered 0.19-0.22 m at 0.3-0.6 rad/s
    (``benchmarks/turn_on_the_spot.py``)."""
    world = NavWorld.from_file(room, start_pose=(-1.0, 0.0, 0.0), cfg=NavWorldCfg(record_gyro=False))
    walker = PolicyWalker()
    walker.bind(world)
    walker.reset()
    walker.scan(0.5)
    start = world.true_pose()
    wander, turned, last = 0.0, 0.0, start[2]
    for _ in range(int(5.0 / world.dt_s)):
        walker.step(world.dt_s, world.true_pose())
        world.step()
        pose = world.true_pose()
        wander = max(wander, float(np.linalg.norm(pose[:2] - start[:2])))
        turned += math.atan2(math.sin(pose[2] - last), math.cos(pose[2] - last))
        last = pose[2]
    world.close()
    assert not world.fell
    assert turned > 1.5, turned  # it did turn (0.5 rad/s for 5 s, less the start)
    assert wander < 0.1, wander
