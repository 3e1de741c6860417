"""Contract every registered task must meet: shapes, dtypes, finiteness, determinism, resets."""

import pytest
import torch

import ambulo.envs as envs

NUM_ENVS = 8


def make(name, seed=3):
    return envs.make(name, num_envs=NUM_ENVS, seed=seed, num_threads=1)


def random_actions(env, generator):
    return torch.rand(env.num_envs, env.num_actions, generator=generator) * 2.0 - 1.0


def test_registry_lists_the_issue_tasks():
    assert {"cartpole", "jetbot-goal", "humanoid-walk"} <= set(envs.names())
    with pytest.raises(KeyError, match="Did you mean 'cartpole'"):
        envs.make("cartpol")


@pytest.mark.parametrize("name", envs.names())
def test_shapes_dtypes_and_no_nan_over_200_random_steps(name):
    env = make(name)
    obs = env.reset()
    assert obs.shape == (NUM_ENVS, env.num_obs) and obs.dtype == torch.float32
    assert obs.device == env.device
    generator = torch.Generator().manual_seed(0)
    for _ in range(200):
        obs, rewards, dones, extras = env.step(random_actions(env, generator))
        assert obs.shape == (NUM_ENVS, env.num_obs) and obs.dtype == torch.float32
        assert rewards.shape == (NUM_ENVS,) and rewards.dtype == torch.float32
        assert dones.shape == (NUM_ENVS,) and dones.dtype == torch.bool
        assert extras["time_outs"].dtype == torch.bool
        assert not (extras["time_outs"] & extras["terminated"]).any()
        assert torch.isfinite(obs).all() and torch.isfinite(rewards).all()
        if "observations" in extras:
            assert extras["observations"]["critic"].shape == (NUM_ENVS, env.num_privileged_obs)


@pytest.mark.parametrize("name", envs.names())
def test_same_seed_gives_identical_rollouts(name):
    rollouts = []
    for _ in range(2):
        env = make(name, seed=11)
        generator = torch.Generator().manual_seed(5)
        trace = [env.reset()]
        for _ in range(100):
            obs, rewards, dones, _ = env.step(random_actions(env, generator))
            trace += [obs, rewards, dones.float()]
        rollouts.append(torch.cat([t.reshape(-1) for t in trace]))
    assert torch.equal(rollouts[0], rollouts[1])
    other = make(name, seed=12)
    assert not torch.equal(other.reset(), make(name, seed=11).reset())


@pytest.mark.parametrize("name", envs.names())
def test_step_resets_only_the_envs_that_finished(name):
    env = make(name)
    env.reset()
    zero = torch.zeros(NUM_ENVS, env.num_actions)
    env.step(zero)
    env.episode_length_buf[0] = env.max_episode_length - 1  # env 0 times out next step
    before = env.episode_length_buf.clone()
    qpos_before = env.engine.qpos.clone()
    _, _, dones, extras = env.step(zero)
    assert dones[0] and extras["time_outs"][0] and "episode" in extras
    assert env.episode_length_buf[0] == 0
    kept = ~dones
    assert kept.sum() > 0
    assert torch.equal(env.episode_length_buf[kept], before[kept] + 1)
    # the envs that went on continued from their own state: not back at the initial state
    assert not torch.equal(env.engine.qpos[kept], qpos_before[kept])


@pytest.mark.parametrize("name", envs.names())
def test_reset_subset_reports_all_observations(name):
    env = make(name)
    env.reset()
    env.step(torch.full((NUM_ENVS, env.num_actions), 0.3))
    env.episode_length_buf[:] = 5
    obs = env.reset(torch.tensor([1, 3]))
    assert obs.shape == (NUM_ENVS, env.num_obs)
    assert env.episode_length_buf.tolist() == [5, 0, 5, 0, 5, 5, 5, 5]


def test_bad_actions_are_rejected_with_the_fix():
    env = make("cartpole")
    with pytest.raises(ValueError, match=r"shape \(8, 2\), expected \(8, 1\)"):
        env.step(torch.zeros(NUM_ENVS, 2))
    bad = torch.zeros(NUM_ENVS, 1)
    bad[2, 0] = float("nan")
    with pytest.raises(ValueError, match="NaN or Inf in 1 envs \\(first: env 2\\)"):
        env.step(bad)


def test_unknown_reward_term_is_named():
    with pytest.raises(ValueError, match="unknown reward terms \\['speed'\\]"):
        envs.make("cartpole", num_envs=2, reward_weights={"speed": 1.0})
