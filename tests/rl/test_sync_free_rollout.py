"""The training step without host reads, checked on the CPU (tests/rl/test_sync_free_gpu.py
checks it on a GPU with torch's sync debug mode).

On the CPU nothing waits for a device, so these tests look for the ops that would: a
``TorchDispatchMode`` records every op that reads a tensor back to the host on a GPU (``.item()``,
``bool(t)``, ``nonzero``, boolean-mask indexing, ``torch.normal`` with a tensor std, which checks
``std >= 0`` on the host) while ``AmbuloRunner.learn`` runs a real iteration, except inside the
env's own step (its CPU path reads on purpose, where it is free; the GPU test covers the GPU
path) and the once-per-iteration parts (returns, update, logging, saving).
"""

from __future__ import annotations

import contextlib
import io

import pytest
import torch
from rsl_rl.modules.distribution import GaussianDistribution
from torch.utils._python_dispatch import TorchDispatchMode

from ambulo import envs
from ambulo.rl.config import ppo_cfg
from ambulo.rl.episodes import EpisodeStats
from ambulo.rl.sampling import SyncFreeGaussian
from ambulo.rl.train import AmbuloRunner, runner_cfg
from ambulo.rl.vecenv import RslRlVecEnv

aten = torch.ops.aten
READS_BACK = {aten._local_scalar_dense.default, aten.nonzero.default, aten.masked_select.default,
              aten.is_nonzero.default, aten.equal.default, aten.normal.Tensor_Tensor}
"""Ops that copy from the device to the host (or, for ``normal(Tensor, Tensor)``, check their
argument there) before they return."""


class HostReads(TorchDispatchMode):
    """Records the ops of ``READS_BACK`` and indexing with a bool mask while ``active``."""

    def __init__(self):
        super().__init__()
        self.active, self.seen = True, []

    def __torch_dispatch__(self, func, types, args=(), kwargs=None):
        kwargs = kwargs or {}
        if self.active:
            masks = func in (aten.index.Tensor, aten.index_put.default, aten.index_put_.default) and any(
                isinstance(i, torch.Tensor) and i.dtype == torch.bool for i in (args[1] or ()))
            if func in READS_BACK or masks:
                self.seen.append(str(func))
        return func(*args, **kwargs)

    @contextlib.contextmanager
    def paused(self):
        active, self.active = self.active, False
        try:
            yield
        finally:
            self.active = active


def _pausing(reads: HostReads, fn):
    def call(*args, **kwargs):
        with reads.paused():
            return fn(*args, **kwargs)
    return call


def make_runner(log_dir=None, num_envs=16):
    env = envs.make("cartpole", num_envs=num_envs, seed=0)
    ppo = ppo_cfg("cartpole", num_envs=num_envs, num_steps_per_env=8)
    with contextlib.redirect_stdout(io.StringIO()):  # rsl-rl prints the networks
        runner = AmbuloRunner(RslRlVecEnv(env, EpisodeStats(num_envs, env.device)), runner_cfg(env, ppo),
                              log_dir=None if log_dir is None else str(log_dir), device="cpu")
    return runner


def test_sampling_is_rsl_rls_gaussian_value_for_value():
    """mean + std * randn is what torch.normal computes after its std check: the same actions
    from the same seed, so CPU training runs are unchanged by the sync-free head."""
    mean = torch.randn(64, 7, generator=torch.Generator().manual_seed(1))
    ours, theirs = SyncFreeGaussian(7, init_std=0.8), GaussianDistribution(7, init_std=0.8)
    with torch.no_grad():
        ours.std_param.copy_(torch.linspace(0.1, 2.0, 7))
        theirs.std_param.copy_(torch.linspace(0.1, 2.0, 7))
    ours.update(mean)
    theirs.update(mean)
    torch.manual_seed(5)
    a = ours.sample()
    torch.manual_seed(5)
    b = theirs.sample()
    torch.manual_seed(5)
    assert torch.equal(a, b)
    assert torch.equal(ours.sample(), a)  # same seed, same actions
    assert not torch.equal(ours.sample(), a)  # and the stream moves on
    assert torch.equal(ours.log_prob(a), theirs.log_prob(a))


def test_samples_have_the_policys_mean_and_std():
    n = 200_000
    head = SyncFreeGaussian(3, init_std=1.0)
    with torch.no_grad():
        head.std_param.copy_(torch.tensor([0.05, 0.5, 3.0]))
    mean = torch.tensor([[-1.0, 0.0, 2.5]]).expand(n, 3)
    head.update(mean)
    torch.manual_seed(0)
    x = head.sample()
    std = torch.tensor([0.05, 0.5, 3.0])
    # 5 standard errors of the sample mean (std / sqrt(n)) and of the sample std (std / sqrt(2n))
    assert torch.all((x.mean(0) - mean[0]).abs() < 5 * std / n**0.5)
    assert torch.all((x.std(0) - std).abs() < 5 * std / (2 * n) ** 0.5)
    assert not x.requires_grad


def test_training_builds_the_sync_free_head_and_check():
    runner = make_runner()
    assert type(runner.alg.actor.distribution) is SyncFreeGaussian
    assert runner.cfg["check_for_nan"] is False  # rsl-rl's per-step check: the algorithm's instead
    assert type(runner.logger).__name__ == "EpisodeLogger"


def test_a_training_iteration_reads_nothing_back_outside_the_env_and_the_update(tmp_path):
    runner = make_runner(log_dir=tmp_path)
    reads = HostReads()
    env = runner.env.env
    env.step = _pausing(reads, env.step)
    alg = runner.alg
    for name in ("compute_returns", "update"):
        setattr(alg, name, _pausing(reads, getattr(alg, name)))
    runner.logger.log = _pausing(reads, runner.logger.log)
    runner.save = _pausing(reads, runner.save)
    runner.logger.init_logging_writer = _pausing(reads, runner.logger.init_logging_writer)
    with contextlib.redirect_stdout(io.StringIO()), reads:
        runner.learn(2, init_at_random_ep_len=True)
    assert reads.seen == [], sorted(set(reads.seen))
    # the logger still reports rsl-rl's episode means, from ambulo's statistics
    assert len(runner.logger.rewbuffer) > 0
    assert list(runner.logger.rewbuffer) == runner.env.episodes.returns()


def test_a_nan_from_the_env_stops_the_iteration_before_the_update():
    runner = make_runner()
    alg = runner.alg
    obs = runner.env.get_observations()
    with torch.inference_mode():
        for step in range(3):
            alg.act(obs)
            rewards = torch.zeros(runner.env.num_envs)
            if step == 1:
                rewards[3] = float("nan")
            alg.process_env_step(obs, rewards, torch.zeros(runner.env.num_envs, dtype=torch.long), {})
        with pytest.raises(ValueError, match="NaN in rewards"):
            alg.compute_returns(obs)
        alg.storage.clear()
        alg.act(obs)
        alg.process_env_step(obs, torch.zeros(runner.env.num_envs),
                             torch.zeros(runner.env.num_envs, dtype=torch.long), {})
        alg.compute_returns(obs)  # the flag was read and cleared: a clean rollout passes
        bad = obs.clone()
        bad["policy"][0, 0] = float("nan")
        alg.storage.clear()
        alg.act(obs)
        alg.process_env_step(bad, torch.zeros(runner.env.num_envs),
                             torch.zeros(runner.env.num_envs, dtype=torch.long), {})
        with pytest.raises(ValueError, match="NaN in policy"):
            alg.raise_on_nan()
