"""Contract every registered task must meet: shapes, dtypes, finiteness, determinism, resets."""

import numpy as np
import pytest
import torch

import ambulo.envs as envs
from ambulo.utils.checks import InvalidValueError

NUM_ENVS = 8


def make(name, seed=3, **overrides):
    return envs.make(name, num_envs=NUM_ENVS, seed=seed, num_threads=1, **overrides)


def rollout_steps(name, steps: int) -> int:
    """``steps`` for a task on the CPU engine, a third of them on Warp: the suite runs Warp on its CPU
    device, where each physics step costs ~40 ms of kernel launches whatever the world count, so
    200 steps of 10 substeps were ~70 s of the suite. 65 steps still cross the random resets."""
    return steps if envs.make_cfg(name).engine != "warp" else steps // 3


def random_actions(env, generator):
    return torch.rand(env.num_envs, env.num_actions, generator=generator) * 2.0 - 1.0


def test_registry_lists_the_issue_tasks():
    assert {"cartpole", "jetbot-goal", "humanoid-walk"} <= set(envs.names())
    with pytest.raises(KeyError, match="Did you mean 'cartpole'"):
        envs.make("cartpol")


@pytest.mark.parametrize("name", envs.names())
def test_shapes_dtypes_and_no_nan_over_random_steps(name):
    env = make(name)
    obs = env.reset()
    assert obs.shape == (NUM_ENVS, env.num_obs) and obs.dtype == torch.float32
    assert obs.device == env.device
    generator = torch.Generator().manual_seed(0)
    for _ in range(rollout_steps(name, 200)):
        obs, rewards, dones, extras = env.step(random_actions(env, generator))
        assert obs.shape == (NUM_ENVS, env.num_obs) and obs.dtype == torch.float32
        assert rewards.shape == (NUM_ENVS,) and rewards.dtype == torch.float32
        assert dones.shape == (NUM_ENVS,) and dones.dtype == torch.bool
        assert extras["time_outs"].dtype == torch.bool
        assert not (extras["time_outs"] & extras["terminated"]).any()
        assert torch.isfinite(obs).all() and torch.isfinite(rewards).all()
        if "observations" in extras:
            assert extras["observations"]["critic"].shape == (NUM_ENVS, env.num_privileged_obs)
    # a diverged world is reset silently (its state stays finite), so count divergences
    assert env.engine.num_diverged == 0


@pytest.mark.parametrize("name", envs.names())
def test_same_seed_gives_identical_rollouts(name):
    rollouts = []
    for _ in range(2):
        env = make(name, seed=11)
        generator = torch.Generator().manual_seed(5)
        trace = [env.reset()]
        for _ in range(rollout_steps(name, 100)):
            obs, rewards, dones, _ = env.step(random_actions(env, generator))
            trace += [obs, rewards, dones.float()]
        rollouts.append(torch.cat([t.reshape(-1) for t in trace]))
    assert torch.equal(rollouts[0], rollouts[1])
    other = make(name, seed=12)
    assert not torch.equal(other.reset(), make(name, seed=11).reset())


def twins(name, **overrides):
    """Two envs of one seed stepped alike: what one does differently shows against the other."""
    pair = [make(name, **overrides) for _ in range(2)]
    zero = torch.zeros(NUM_ENVS, pair[0].num_actions)
    for env in pair:
        env.reset()
        env.step(zero)
    return pair, zero


@pytest.mark.parametrize("name", envs.names())
def test_step_resets_only_the_envs_that_finished(name):
    (env, twin), zero = twins(name, stats_interval_steps=1)
    env.episode_length_buf[0] = env.max_episode_length - 1  # env 0 times out next step
    _, _, dones, extras = env.step(zero)
    twin.step(zero)
    assert dones.tolist() == [True] + [False] * (NUM_ENVS - 1)
    assert extras["time_outs"][0] and env.episode_length_buf[0] == 0
    # the episode statistics count that one ended episode, which timed out
    assert extras["episode"]["Episode/num_ended"] == 1
    assert extras["episode"]["Episode_Termination/time_out"] == 1.0
    # the other envs went on exactly as the twin's, which reset nothing
    assert torch.equal(env.engine.qpos[1:], twin.engine.qpos[1:])
    assert torch.equal(env.engine.qvel[1:], twin.engine.qvel[1:])
    assert torch.equal(env.episode_length_buf[1:], twin.episode_length_buf[1:])
    # env 0 restarted from the initial state (its randomized reset), not from where it was
    assert not torch.equal(env.engine.qpos[0], twin.engine.qpos[0])
    assert env.engine.time[0] == 0.0 and twin.engine.time[0] > 0.0


@pytest.mark.parametrize("name", envs.names())
def test_reset_subset_changes_only_those_envs(name):
    (env, twin), _ = twins(name)
    env.episode_length_buf[:] = 5
    obs = env.reset(torch.tensor([1, 3]))
    assert obs.shape == (NUM_ENVS, env.num_obs)
    assert env.episode_length_buf.tolist() == [5, 0, 5, 0, 5, 5, 5, 5]
    reset = torch.zeros(NUM_ENVS, dtype=torch.bool)
    reset[[1, 3]] = True
    assert torch.equal(env.engine.qpos[~reset], twin.engine.qpos[~reset])
    assert torch.equal(env.engine.time[reset], torch.zeros(2, dtype=torch.float64))
    assert (twin.engine.time[reset] > 0).all()


@pytest.mark.parametrize("name", envs.names())
def test_play_variant_builds_and_steps(name):
    env = make(name, play=True)
    obs, rewards, _, _ = env.step(torch.zeros(NUM_ENVS, env.num_actions))
    assert torch.isfinite(obs).all() and torch.isfinite(rewards).all()


def test_bad_actions_are_rejected_with_the_fix():
    env = make("cartpole")
    with pytest.raises(ValueError, match=r"shape \(8, 2\), expected \(8, 1\)"):
        env.step(torch.zeros(NUM_ENVS, 2))
    bad = torch.zeros(NUM_ENVS, 1)
    bad[2, 0] = float("nan")
    with pytest.raises(ValueError, match="NaN or Inf in 1 envs \\(first: env 2\\)"):
        env.step(bad)


@pytest.mark.parametrize("actions, shown", [
    (torch.zeros(NUM_ENVS, 1, dtype=torch.complex64), "a torch.complex64 tensor"),
    (np.full((NUM_ENVS, 1), 0.5 + 0.5j), "a complex128 array"),
    ([[0.5 + 0.5j]] * NUM_ENVS, "a torch.complex64 tensor"),
    (torch.zeros(NUM_ENVS, 1, dtype=torch.bool), "a torch.bool tensor"),
    (np.zeros((NUM_ENVS, 1), dtype=bool), "a bool array"),
    (np.full((NUM_ENVS, 1), "0.5"), "a <U3 array"),
])
def test_complex_bool_or_text_actions_are_refused_not_cast(actions, shown):
    # a cast to float32 would drop the imaginary part (torch only warns) or read a mask as 0/1
    env = make("cartpole")
    with pytest.raises(InvalidValueError) as info:
        env.step(actions)
    message = str(info.value)
    assert "\n" not in message and f"actions is {shown}: expected real numbers" in message
    assert "pass real numbers of shape (8, 1) (num_envs, num_actions)" in message
    env.step(np.zeros((NUM_ENVS, 1), dtype=np.int64))  # whole numbers are real numbers


def test_a_config_edited_after_it_was_built_is_checked_by_the_env():
    cfg = envs.make_cfg("cartpole", num_envs=2)
    cfg.episode_length_s = -5.0
    with pytest.raises(InvalidValueError, match=r"CartpoleCfg.episode_length_s is -5.0: a duration must be > 0"):
        envs.spec("cartpole").env_cls(cfg)


def test_unknown_reward_term_is_named():
    with pytest.raises(ValueError, match="unknown reward terms \\['speed'\\]"):
        envs.make("cartpole", num_envs=2, reward_weights={"speed": 1.0})
