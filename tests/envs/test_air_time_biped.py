"""The biped air-time reward (``air_time_reward="biped"``): single stance, capped, never negative."""

import pytest
import torch

import ambulo.envs as envs
from ambulo.envs import rewards

MOVING = torch.tensor([[0.5, 0.0]])


def biped(air, contact, touching, command=MOVING, threshold=0.4):
    return rewards.feet_air_time_biped(torch.tensor([air]), torch.tensor([contact]), torch.tensor([touching]),
                                       threshold, command).item()


def test_hand_computed_values():
    # left foot on the ground 0.30 s, right foot in the air 0.20 s: the shorter, 0.20
    assert biped([0.0, 0.2], [0.3, 0.0], [True, False]) == pytest.approx(0.2)
    # both long past the threshold: capped at 0.4
    assert biped([0.0, 0.7], [0.9, 0.0], [True, False]) == pytest.approx(0.4)
    assert biped([0.0, 0.0], [0.5, 0.5], [True, True]) == 0.0  # double stance
    assert biped([0.3, 0.3], [0.0, 0.0], [False, False]) == 0.0  # flight
    assert biped([0.0, 0.2], [0.3, 0.0], [True, False], command=torch.tensor([[0.05, 0.0]])) == 0.0  # standing
    # a quick step: legged_gym's term punishes it (0.15 - 0.4 per touchdown), this one does not
    quick = rewards.feet_air_time(torch.tensor([[0.15, 0.0]]), torch.tensor([[True, False]]), 0.4, MOVING).item()
    assert quick == pytest.approx(-0.25) and biped([0.0, 0.15], [0.05, 0.0], [True, False]) >= 0.0


def test_the_env_counts_its_feet_air_time_term_the_biped_way():
    # the shipped walker walking forward: single stance comes every step cycle
    from ambulo.policies.shipped import load_policy

    walker = load_policy("humanoid-walk")
    fixed = {"commands.lin_vel_x_m_s": (0.6, 0.6), "commands.lin_vel_y_m_s": (0.0, 0.0),
             "commands.yaw_rate_rad_s": (0.0, 0.0), "commands.standing_fraction": 0.0,
             "commands.heading_fraction": 0.0}
    env = envs.make("humanoid-walk", num_envs=2, device="cpu", seed=0, play=True, air_time_reward="biped", **fixed)
    obs, rewarded = env.reset(), 0
    for _ in range(60):
        obs = env.step(walker(obs))[0]
        feet = env.feet.data
        expected = rewards.feet_air_time_biped(feet.current_air_time_s, feet.current_contact_time_s,
                                               feet.in_contact, env.cfg.air_time_threshold_s,
                                               env.commands.command[:, :2])
        assert torch.equal(env._get_rewards()["feet_air_time"], expected)
        rewarded += int((expected > 0).sum())
    assert rewarded > 20  # it did walk in single stance
    env.close()


def test_an_unknown_air_time_reward_is_refused():
    with pytest.raises(Exception, match="air_time_reward"):
        envs.make_cfg("humanoid-rough", air_time_reward="bogus")
