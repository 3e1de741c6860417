"""A PPO iteration of humanoid-walk on a GPU waits for the device only where it must: the update.

What is covered: ``AmbuloRunner.learn`` (the runner ``ambulo train`` builds, ``runner_cfg``'s
classes, a TensorBoard writer, ambulo's episode statistics) on humanoid-walk with 64 worlds on
CUDA. After one warm-up iteration (kernel compile, CUDA-graph captures, first resets: each
synchronizes once, by design), two more iterations run under torch's sync debug mode:

- the whole of ``learn`` runs with the mode at ``"warn"`` and then at ``"error"``: policy sampling
  (``alg.act``: actor, critic, log-probabilities), ``env.step`` (action checks and clipping, the
  physics graph, divergence resets, terminations, rewards, resets of finished episodes,
  observations, the env's episode statistics), ``RslRlVecEnv`` (ambulo's episode returns),
  the NaN check's accumulation, rollout storage and the logger's per-step bookkeeping;
- except these, run with the mode off: ``compute_returns`` (reads the NaN flag once),
  ``update`` (rsl-rl's PPO update reads its losses and the adaptive learning rate's KL with
  ``.item()``), ``Logger.log``, ``save`` and ``init_logging_writer``: once an iteration each.

Not covered: the engine's overflow check, one host read every ``overflow_check_steps`` (100)
env steps by design; it is run just before the checked iterations so it does not fall inside.
The warn pass lists every synchronizing line at once (the error pass stops at the first).
"""

from __future__ import annotations

import contextlib
import io
import warnings

import pytest
import torch

pytestmark = pytest.mark.skipif(not torch.cuda.is_available(), reason="needs CUDA")

NUM_ENVS = 64


@contextlib.contextmanager
def sync_debug(mode):
    previous = torch.cuda.get_sync_debug_mode()
    torch.cuda.set_sync_debug_mode(mode)
    try:
        yield
    finally:
        torch.cuda.set_sync_debug_mode(previous)


def _unchecked(fn):
    """``fn`` with torch's sync debug mode off while it runs (a once-per-iteration part)."""
    def call(*args, **kwargs):
        with sync_debug("default"):
            return fn(*args, **kwargs)
    return call


@pytest.fixture(scope="module")
def runner(tmp_path_factory):
    from ambulo import envs
    from ambulo.rl.config import ppo_cfg
    from ambulo.rl.episodes import EpisodeStats
    from ambulo.rl.train import AmbuloRunner, runner_cfg
    from ambulo.rl.vecenv import RslRlVecEnv

    torch.manual_seed(0)
    env = envs.make("humanoid-walk", num_envs=NUM_ENVS, device="cuda", seed=0)
    ppo = ppo_cfg("humanoid-walk", num_envs=NUM_ENVS)
    with contextlib.redirect_stdout(io.StringIO()):
        runner = AmbuloRunner(RslRlVecEnv(env, EpisodeStats(NUM_ENVS, env.device)), runner_cfg(env, ppo),
                              log_dir=str(tmp_path_factory.mktemp("run")), device=str(env.device))
        runner.learn(1, init_at_random_ep_len=True)  # warm-up: compile, captures, first resets
    for name in ("compute_returns", "update"):
        setattr(runner.alg, name, _unchecked(getattr(runner.alg, name)))
    for name in ("log", "init_logging_writer"):
        setattr(runner.logger, name, _unchecked(getattr(runner.logger, name)))
    runner.save = _unchecked(runner.save)
    return runner


def _iteration(runner, mode: str) -> None:
    runner.env.env.engine.check_overflow()  # the engine's periodic read, outside the checked steps
    torch.cuda.synchronize()
    with contextlib.redirect_stdout(io.StringIO()), sync_debug(mode):
        runner.learn(1)


def test_a_ppo_iteration_syncs_nowhere_but_the_update(runner):
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        _iteration(runner, "warn")
    where = sorted({f"{w.filename}:{w.lineno}: {str(w.message).splitlines()[0]}" for w in caught
                    if "synchroniz" in str(w.message).lower()})
    assert where == [], "host syncs in the training step:\n" + "\n".join(where)
    # on a GPU resets are masks, so every step runs the reset path whether or not an episode ended
    _iteration(runner, "error")  # a RuntimeError names the first synchronizing op


def test_cuda_samples_are_torch_normals_value_for_value():
    from rsl_rl.modules.distribution import GaussianDistribution

    from ambulo.rl.sampling import SyncFreeGaussian

    mean = torch.randn(4096, 21, device="cuda")
    ours, theirs = SyncFreeGaussian(21).cuda(), GaussianDistribution(21).cuda()
    ours.update(mean)
    theirs.update(mean)
    torch.manual_seed(3)
    with sync_debug("error"):
        a = ours.sample()
    torch.manual_seed(3)
    b = theirs.sample()
    assert torch.equal(a, b)
