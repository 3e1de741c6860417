"""Time-outs bootstrap from the critic's observation before the reset (``FinalCriticObs``)."""

import torch

from ambulo import envs
from ambulo.rl.offpolicy.runner import FinalCriticObs


def test_final_critic_observations_are_those_before_the_reset():
    env = envs.make("humanoid-walk", num_envs=3, seed=0, episode_length_s=0.2)  # time-outs every 10 steps
    env.return_final_obs = True
    final = FinalCriticObs(env)
    ended_seen = 0
    for _ in range(12):
        (_, _, dones, extras), before = final.step(lambda: env.step(torch.zeros(3, env.num_actions)))
        after = extras["observations"]["critic"]
        same = (before == after).all(dim=1)
        # a world that went on shows the same state twice; one that was reset shows its new episode after
        assert torch.equal(same, ~dones), (same, dones)
        ended_seen += int(dones.sum())
    assert ended_seen >= 3
