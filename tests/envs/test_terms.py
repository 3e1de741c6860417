"""Observation and reward terms against hand-computed values on constructed states."""

import math

import pytest
import torch

import ambulo.envs as envs
from ambulo.envs import observations as obs_terms
from ambulo.envs import rewards
from ambulo.utils.math import (
    projected_gravity,
    quat_from_axis_angle,
    quat_from_yaw,
    quat_mul,
    quat_rotate,
    quat_rotate_inverse,
)

X, Z = torch.tensor([[1.0, 0.0, 0.0]], dtype=torch.float64), torch.tensor([[0.0, 0.0, 1.0]],
                                                                       dtype=torch.float64)


def tilt_x(angle):
    return quat_from_axis_angle(X, torch.tensor([angle], dtype=torch.float64))


def test_projected_gravity_of_a_known_tilt():
    theta = math.radians(30.0)
    g = projected_gravity(tilt_x(theta))
    # R_x(theta)^T (0, 0, -1) = (0, -sin theta, -cos theta)
    torch.testing.assert_close(g, torch.tensor([[0.0, -math.sin(theta), -math.cos(theta)]],
                                               dtype=torch.float64))
    assert rewards.upright(g).item() == pytest.approx(math.cos(theta))


def test_quat_from_yaw_is_the_rotation_about_world_z():
    yaw = torch.tensor([0.3, -2.0, math.pi], dtype=torch.float64)
    torch.testing.assert_close(quat_from_yaw(yaw), quat_from_axis_angle(Z.expand(3, 3), yaw))
    # a quarter turn maps x to y
    q = quat_from_yaw(torch.tensor([math.pi / 2], dtype=torch.float64))
    torch.testing.assert_close(quat_rotate(q, X), torch.tensor([[0.0, 1.0, 0.0]], dtype=torch.float64))


def test_base_velocity_frames():
    yaw90 = quat_from_axis_angle(Z, torch.tensor([math.pi / 2], dtype=torch.float64))
    v_w = torch.tensor([[1.0, 0.0, 0.0]], dtype=torch.float64)
    torch.testing.assert_close(quat_rotate_inverse(yaw90, v_w),
                               torch.tensor([[0.0, -1.0, 0.0]], dtype=torch.float64))
    # heading frame ignores pitch/roll: a base pitched 40 deg and yawed 90 deg moving +y
    # in the world moves straight forward in its heading frame
    pitched = quat_from_axis_angle(torch.tensor([[0.0, 1.0, 0.0]], dtype=torch.float64),
                                   torch.tensor([math.radians(40)], dtype=torch.float64))
    quat = quat_mul(yaw90, pitched)
    v = obs_terms.base_lin_vel_yaw(quat, torch.tensor([[0.0, 0.7, 0.0]], dtype=torch.float64))
    torch.testing.assert_close(v, torch.tensor([[0.7, 0.0]], dtype=torch.float64))


def test_quat_rotate_inverse_undoes_rotate():
    q = quat_from_axis_angle(torch.tensor([[0.6, 0.0, 0.8]], dtype=torch.float64),
                             torch.tensor([1.1], dtype=torch.float64))
    v = torch.tensor([[0.3, -2.0, 0.5]], dtype=torch.float64)
    torch.testing.assert_close(quat_rotate_inverse(q, quat_rotate(q, v)), v)


def test_velocity_tracking_at_a_known_error():
    cmd = torch.tensor([[1.0, 0.0]], dtype=torch.float64)
    vel = torch.tensor([[0.5, 0.0]], dtype=torch.float64)
    # exp(-0.5^2 / 0.5^2) = e^-1
    assert rewards.track_lin_vel_xy_exp(cmd, vel, 0.5).item() == pytest.approx(math.exp(-1.0))
    yaw = rewards.track_ang_vel_z_exp(torch.tensor([0.5]), torch.tensor([-0.5]), 0.5)
    assert yaw.item() == pytest.approx(math.exp(-4.0))


def test_penalties_and_air_time():
    rate = rewards.action_rate_l2(torch.tensor([[1.0, 2.0]]), torch.tensor([[0.0, 4.0]]))
    assert rate.item() == 5.0
    pos = torch.tensor([[0.95, -1.2, 0.0]])
    lower, upper = torch.tensor([-0.9, -0.9, -0.9]), torch.tensor([0.9, 0.9, 0.9])
    assert rewards.joint_pos_limits(pos, lower, upper).item() == pytest.approx(0.05 + 0.3)
    air = torch.tensor([[0.6, 0.2]])
    first = torch.tensor([[True, False]])
    moving, standing = torch.tensor([[0.5, 0.0]]), torch.tensor([[0.05, 0.0]])
    assert rewards.feet_air_time(air, first, 0.4, moving).item() == pytest.approx(0.2)
    assert rewards.feet_air_time(air, first, 0.4, standing).item() == 0.0


def test_single_stance_air_time_by_hand():
    # env 0: left on the ground 0.3 s, right swinging 0.2 s -> 0.2; env 1: double support -> 0;
    # env 2: 0.7 s / 0.5 s -> 0.5, capped at 0.4; env 3: as env 0 but told to stand -> 0
    in_contact = torch.tensor([[True, False], [True, True], [False, True], [True, False]])
    contact_time = torch.tensor([[0.3, 0.0], [0.3, 0.1], [0.0, 0.7], [0.3, 0.0]])
    air_time = torch.tensor([[0.0, 0.2], [0.0, 0.0], [0.5, 0.0], [0.0, 0.2]])
    command = torch.tensor([[0.5, 0.0], [0.5, 0.0], [0.0, -0.3], [0.05, 0.0]])
    got = rewards.feet_air_time_single_stance(air_time, contact_time, in_contact, 0.4, command)
    assert got.tolist() == pytest.approx([0.2, 0.0, 0.4, 0.0])


def test_a_slow_walks_quick_steps_lose_reward_by_touchdown_and_earn_it_by_single_stance():
    """Why the single-stance term exists: a slow walk of 0.25 s swings (each foot: 0.25 s in the air,
    0.35 s on the ground, so 0.05 s of double support at each change) earns a negative touchdown term,
    less than standing still (0), and a positive single-stance term. The contact timers advance as
    the contact sensor's do, at the policy step of 0.02 s."""
    dt, swing_steps, period_steps = 0.02, 12, 30  # 0.24 s swing, 0.6 s a stride
    air = torch.zeros(1, 2)
    contact = torch.zeros(1, 2)
    was_in = torch.ones(1, 2, dtype=torch.bool)
    last_air = torch.zeros(1, 2)
    command = torch.tensor([[0.25, 0.0]])
    touchdown = single = 0.0
    for step in range(10 * period_steps):
        phase = step % period_steps
        in_contact = torch.tensor([[not (0 <= phase < swing_steps), not (15 <= phase < 15 + swing_steps)]])
        first = in_contact & ~was_in
        last_air = torch.where(first, air, last_air)  # the flight just ended: 12 steps of 0.02 s
        air = torch.where(in_contact, 0.0, air + dt)
        contact = torch.where(in_contact, contact + dt, 0.0)
        was_in = in_contact
        touchdown += rewards.feet_air_time(last_air, first, 0.4, command).item()
        single += rewards.feet_air_time_single_stance(air, contact, in_contact, 0.4, command).item()
    assert touchdown == pytest.approx(20 * (0.24 - 0.4), abs=1e-4)  # 20 touchdowns of 0.24 s flights
    assert single > 0.5


def test_walk_env_takes_the_air_time_term_the_cfg_names(monkeypatch):
    calls = []
    for name in ("feet_air_time", "feet_air_time_single_stance"):
        real = getattr(rewards, name)
        monkeypatch.setattr(rewards, name, lambda *a, _real=real, _name=name, **k: calls.append(_name) or _real(*a, **k))
    for choice in ("single_stance", "touchdown"):
        env = envs.make("humanoid-walk", num_envs=2, seed=0, num_threads=1, play=True, air_time_reward=choice)
        calls.clear()
        env.step(torch.zeros(env.num_envs, env.num_actions))
        assert set(calls) == {"feet_air_time_single_stance" if choice == "single_stance" else "feet_air_time"}
        env.close()
    with pytest.raises(ValueError, match="air_time_reward"):
        envs.make("humanoid-walk", num_envs=1, seed=0, num_threads=1, air_time_reward="stance")


def humanoid(num_envs=2, play=True):
    return envs.make("humanoid-walk", num_envs=num_envs, seed=0, num_threads=1, play=play)


def test_humanoid_observes_a_constructed_tilt_and_command():
    env = humanoid()
    theta = math.radians(30.0)
    env.robot.write_root_pose(quat_w=tilt_x(theta).expand(2, 4))
    env.engine.forward()
    env.commands.command[:] = torch.tensor([0.5, -0.25, 1.0])
    obs = env._compute_observations()
    torch.testing.assert_close(obs[:, 0:3], torch.tensor(
        [[0.0, -math.sin(theta), -math.cos(theta)]] * 2))
    torch.testing.assert_close(obs[:, 3:6], torch.tensor([[1.0, -0.5, 0.25]] * 2))


def test_observation_noise_reaches_the_actor_only_within_its_bounds():
    env = humanoid(num_envs=64, play=False)
    obs, critic = env.get_observations(), env.get_privileged_observations()
    clean = critic[:, :env.num_obs]
    noise = obs - clean
    # term order: gravity 3, command 3, joint pos 21, joint vel 21, ang vel 3, actions 21
    bounds = [(0, 3, 0.05), (3, 6, 0.0), (6, 27, 0.01), (27, 48, 0.075), (48, 51, 0.05), (51, 72, 0.0)]
    for start, stop, half_width in bounds:
        part = noise[:, start:stop].abs()
        assert part.max() <= half_width + 1e-6
        if half_width:
            assert part.max() > 0.5 * half_width  # 64 envs x k draws: the bound is approached
    play = humanoid(num_envs=4)
    torch.testing.assert_close(play.get_observations(), play.get_privileged_observations()[:, :play.num_obs])


def test_humanoid_tracking_reward_and_terminations_on_constructed_states():
    env = humanoid()
    engine, robot = env.engine, env.robot
    robot.write_root_pose(quat_w=torch.tensor([[1.0, 0, 0, 0]], dtype=torch.float64).expand(2, 4))
    engine.qvel[:] = 0.0
    robot.write_root_velocity(lin_vel_w=torch.tensor([[0.6, 0.0, 0.0]], dtype=torch.float64).expand(2, 3))
    env.commands.command[:] = torch.tensor([1.0, 0.0, 0.0])
    pos = robot.data.root_pos_w.clone()
    pos[1, 2] = 0.4     # env 1 below 0.5 m
    robot.write_root_pose(pos_w=pos)
    engine.forward()
    terms = env._get_terminations()
    assert terms["base_height"].tolist() == [False, True]
    assert not terms["tilt"].any()
    reward = env._get_rewards()["track_lin_vel_xy_exp"]
    torch.testing.assert_close(reward, torch.full((2,), math.exp(-0.4**2 / 0.5**2),
                                                  dtype=torch.float64))
    robot.write_root_pose(quat_w=tilt_x(math.radians(70.0)).expand(2, 4))
    assert env._get_terminations()["tilt"].all()


def test_humanoid_yaw_rate_reward_uses_the_world_z_rate_of_a_tilted_base():
    env = humanoid()
    robot = env.robot
    tilt = tilt_x(math.radians(25.0)).expand(2, 4)
    omega_w = torch.tensor([[0.3, -0.2, 0.8]], dtype=torch.float64).expand(2, 3)
    robot.write_root_pose(quat_w=tilt)
    robot.write_root_velocity(ang_vel_w=omega_w)
    env.engine.forward()
    env.commands.command[:] = torch.tensor([0.0, 0.0, 0.5])
    env._get_terminations()  # computes the projected gravity the rewards reuse
    reward = env._get_rewards()["track_ang_vel_z_exp"]
    # the base spins at 0.8 rad/s about world z whatever its tilt: error 0.3 rad/s
    torch.testing.assert_close(reward, torch.full((2,), math.exp(-0.3**2 / 0.5**2), dtype=torch.float64))
    # and evaluation's metric measures the same error
    torch.testing.assert_close(env.velocity_tracking_error()[1], torch.full((2,), 0.3, dtype=torch.float64))
