"""Velocity commands: ranges, shares of heading and standing envs, steering, resampling times."""

import math

import pytest
import torch

from ambulo.envs.commands import VelocityCommand, VelocityCommandCfg

N = 4000


def commands(**overrides):
    cfg = VelocityCommandCfg(**overrides)
    cmd = VelocityCommand(cfg, N, torch.Generator().manual_seed(0), torch.device("cpu"))
    cmd.resample(None)
    return cfg, cmd


def test_resampled_commands_fill_their_ranges_and_shares():
    cfg, cmd = commands(standing_fraction=0.0)
    for column, (low, high) in enumerate((cfg.lin_vel_x_m_s, cfg.lin_vel_y_m_s, cfg.yaw_rate_rad_s)):
        values = cmd.command[:, column]
        assert low <= values.min() and values.max() < high
        assert values.max() - values.min() > 0.95 * (high - low)  # 4000 draws cover the range
    assert 3.99 <= cmd.time_left_s.min() and cmd.time_left_s.max() < 8.0
    assert abs(cmd.is_heading.float().mean() - cfg.heading_fraction) < 0.03


def test_standing_envs_get_zero_commands_and_heading_envs_steer_within_limits():
    cfg, cmd = commands(standing_fraction=0.25)
    assert abs(cmd.is_standing.float().mean() - 0.25) < 0.03
    heading_w = torch.zeros(N)
    cmd.update(0.02, heading_w)
    assert (cmd.command[cmd.is_standing] == 0).all()
    steering = cmd.is_heading & ~cmd.is_standing
    expected = (cfg.heading_stiffness * cmd.heading_target[steering]).clamp(*cfg.yaw_rate_rad_s)
    torch.testing.assert_close(cmd.command[steering, 2], expected)
    # an env facing its target heading (mod 2 pi) is not turned
    cmd.update(0.02, cmd.heading_target + 2 * math.pi)
    assert cmd.command[steering, 2].abs().max() < 1e-5


def test_commands_are_redrawn_when_their_time_runs_out_and_only_then():
    _, cmd = commands()
    before = cmd.command.clone()
    due = cmd.time_left_s <= 4.5
    cmd.update(4.5, torch.zeros(N))
    changed = (cmd.command != before).any(dim=1)
    heading_or_standing = cmd.is_heading | cmd.is_standing
    # envs that were not due kept their planar command (yaw may steer for heading envs)
    assert torch.equal(cmd.command[~due, :2] * ~cmd.is_standing[~due, None], before[~due, :2]
                       * ~cmd.is_standing[~due, None])
    assert changed[due & ~heading_or_standing].all()
    assert (cmd.time_left_s > 0).all()


def test_curriculum_widens_the_ranges_only_while_tracking_is_good():
    """humanoid-walk's command curriculum: the range share grows by rate * dt per step while
    the running tracking mean is above the threshold, never past 1, and not otherwise."""
    from ambulo import envs

    env = envs.make("humanoid-walk", num_envs=2, device="cpu", seed=0, curriculum_start_scale=0.4,
                    curriculum_rate_per_s=0.5)
    scale = env.commands.range_scale
    assert float(scale) == pytest.approx(0.4)
    for _ in range(10):  # tracking kernel 0: the running mean stays low, the range does not grow
        env._advance_curriculum(torch.zeros(2))
    assert float(scale) == pytest.approx(0.4)
    env._tracking_mean.fill_(1.0)
    env._advance_curriculum(torch.ones(2))
    assert float(scale) == pytest.approx(0.4 + 0.5 * env.step_dt_s)
    for _ in range(200):
        env._advance_curriculum(torch.ones(2))
    assert float(scale) == 1.0
    env.commands.resample(None)  # draws within the full ranges now; play variants never scale
    assert envs.make_cfg("humanoid-walk", play=True).curriculum_start_scale is None
