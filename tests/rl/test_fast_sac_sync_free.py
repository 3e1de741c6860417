"""The off-policy step path (act, step, store, sample, update) reads nothing back to the host,
checked on the CPU with the op recorder of test_sync_free_rollout (the env's own CPU step, which
reads on purpose where it is free, is left out)."""

import torch
from test_sync_free_rollout import HostReads

from ambulo import envs
from ambulo.rl.episodes import EpisodeStats
from ambulo.rl.offpolicy import OffPolicyRunner, offpolicy_cfg


def _steps_and_updates(algo: str, task: str) -> list[str]:
    cfg = offpolicy_cfg(task, algo, num_envs=4, batch_size=32, actor_hidden_dims=(16,), critic_hidden_dims=(16,),
                        random_steps=0, learning_starts=3)
    env = envs.make(task, num_envs=4, seed=0)
    runner = OffPolicyRunner(env, cfg, episodes=EpisodeStats(4, env.device))
    for _ in range(4):  # fill the ring past learning_starts, episodes end (time-outs and falls)
        runner._collect()
    reads = HostReads()
    step = env.step

    def step_unrecorded(actions):
        with reads.paused():
            return step(actions)

    env.step = step_unrecorded
    with reads:
        for _ in range(3):
            runner._collect()
            runner.alg.update_from(runner.ring, runner.generator)
    return reads.seen


def test_fast_sac_steps_and_updates_without_host_reads():
    assert _steps_and_updates("fast-sac", "cartpole") == []


def test_fast_td3_steps_and_updates_without_host_reads():
    assert _steps_and_updates("fast-td3", "cartpole") == []


def test_the_recorder_sees_a_host_read():
    reads = HostReads()
    with reads:
        float(torch.ones(2).sum())
    assert reads.seen
