"""Mirror-symmetry augmentation in training: PPO (rsl-rl's Symmetry extension with
``rl.symmetry.mirror_augmentation``, ``--ppo-cfg symmetry=true``) and FastSAC/FastTD3 (the second
half of each sampled batch mirrored, ``--algo-cfg symmetry=true``); refusals in one line."""

import importlib
import json

import pytest
import torch

from ambulo import envs
from ambulo.cli import main
from ambulo.envs.symmetry import task_mirror
from ambulo.rl import symmetry as rl_symmetry
from ambulo.rl import train
from ambulo.rl.offpolicy import offpolicy_cfg
from ambulo.rl.offpolicy.learner import FastOffPolicy
from ambulo.rl.offpolicy.replay import Batch
from ambulo.rl.vecenv import RslRlVecEnv

train_module = importlib.import_module("ambulo.rl.train")  # the module (ambulo.rl.train is also the function)

PPO_FAST = {"num_steps_per_env": 4, "num_mini_batches": 2, "num_learning_epochs": 1}


@pytest.fixture(scope="module")
def walk():
    env = envs.make("humanoid-walk", num_envs=4, device="cpu", seed=0)
    env.reset()
    for _ in range(3):  # states off the default pose
        env.step(torch.randn(4, env.num_actions))
    return env


def test_augmentation_appends_each_groups_mirror_image(walk):
    vec = RslRlVecEnv(walk)
    obs = vec.get_observations()
    actions = torch.randn(4, walk.num_actions)
    doubled, both = rl_symmetry.mirror_augmentation(vec, obs=obs, actions=actions)
    m = task_mirror(walk)
    assert doubled.batch_size[0] == 8 and set(doubled.keys()) == {"policy", "critic"}
    torch.testing.assert_close(doubled["policy"], torch.cat([obs["policy"], m.policy(obs["policy"])]))
    torch.testing.assert_close(doubled["critic"], torch.cat([obs["critic"], m.critic(obs["critic"])]))
    torch.testing.assert_close(both, torch.cat([actions, m.actions(actions)]))
    assert rl_symmetry.mirror_augmentation(vec, obs=None, actions=actions)[0] is None
    # the maps are built once and kept on the task's env
    assert rl_symmetry.env_mirror(vec) is rl_symmetry.env_mirror(walk)


def _actor_weights(run):
    saved = torch.load(sorted(run.glob("model_*.pt"))[-1], weights_only=False)
    return saved["actor_state_dict"]


def test_ppo_learns_from_the_mirrored_minibatches(tmp_path, monkeypatch):
    calls = []
    augment = rl_symmetry.mirror_augmentation

    def counting(env, obs=None, actions=None):
        out = augment(env, obs=obs, actions=actions)
        calls.append((None if obs is None else obs.batch_size[0], None if out[0] is None else out[0].batch_size[0]))
        return out

    monkeypatch.setattr(train_module, "mirror_augmentation", counting)
    common = dict(num_envs=8, max_iterations=1, seed=0, log_root=tmp_path)
    plain = train("humanoid-walk", ppo_overrides=PPO_FAST, **common)
    assert not calls
    mirrored = train("humanoid-walk", ppo_overrides={**PPO_FAST, "symmetry": True}, **common)
    # every mini-batch of 8 x 4 / 2 transitions was trained with its mirror image appended
    batches = [c for c in calls if c[0] is not None]
    assert batches and all(c == (16, 32) for c in batches)
    # same seed, same rollout: only the augmentation differs, and it changed what was learnt
    a, b = _actor_weights(plain), _actor_weights(mirrored)
    assert any(not torch.equal(a[k], b[k]) for k in a)


def test_offpolicy_mirrors_the_second_half_of_each_batch(walk):
    m = task_mirror(walk)
    cfg = offpolicy_cfg("humanoid-walk", "fast-sac", symmetry=True, batch_size=6)
    learner = FastOffPolicy(cfg, walk.num_obs, walk.num_privileged_obs, walk.num_actions, "cpu", mirror=m)
    gen = torch.Generator().manual_seed(0)

    def rand(*shape):
        return torch.randn(*shape, generator=gen)

    batch = Batch(obs=rand(6, walk.num_obs), critic_obs=rand(6, walk.num_privileged_obs),
                  actions=rand(6, walk.num_actions), returns=rand(6), discount=rand(6),
                  next_obs=rand(6, walk.num_obs), next_critic_obs=rand(6, walk.num_privileged_obs))
    out = learner._mirror_half(batch)
    for name, reflect in (("obs", m.policy), ("critic_obs", m.critic), ("actions", m.actions),
                          ("next_obs", m.policy), ("next_critic_obs", m.critic)):
        x, y = getattr(batch, name), getattr(out, name)
        torch.testing.assert_close(y[:3], x[:3])
        torch.testing.assert_close(y[3:], reflect(x[3:]))
    assert out.returns is batch.returns and out.discount is batch.discount
    # the update runs on the mirrored batch
    seen = []
    learner._critic_step = lambda b: seen.append(b)
    learner._actor_step = lambda b: None
    learner._update(batch, with_actor=True)
    torch.testing.assert_close(seen[0].actions[3:], m.actions(batch.actions[3:]))
    with pytest.raises(ValueError, match="needs the task's mirror maps"):
        FastOffPolicy(cfg, walk.num_obs, walk.num_privileged_obs, walk.num_actions, "cpu")


def test_fast_sac_trains_with_symmetry(tmp_path):
    """humanoid-walk's FastSAC recipe mirrors by default (and its CUDA graphs are ignored on the CPU)."""
    run = train("humanoid-walk", algo="fast-sac", num_envs=8, max_iterations=2, log_root=tmp_path,
                algo_overrides={"batch_size": 32, "updates_per_step": 1})
    assert sorted(run.glob("model_*.pt"))
    assert json.loads((run / "run.json").read_text())["offpolicy"]["symmetry"] is True


@pytest.mark.parametrize("flags", [["--ppo-cfg", "symmetry=true"], ["--algo", "fast-sac", "--algo-cfg", "symmetry=true"]])
def test_a_task_that_cannot_be_mirrored_is_refused_in_one_line(tmp_path, capsys, flags):
    assert main(["train", "cartpole", "--max-iterations", "1", "--num-envs", "4", "--log-root", str(tmp_path),
                 *flags]) != 0
    err = capsys.readouterr().err.strip()
    assert err.count("\n") == 0 and "symmetry" in err and "without symmetry" in err
    assert not (tmp_path / "cartpole").exists()  # no run folder left
