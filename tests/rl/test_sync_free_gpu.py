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
- except these, run with the mode off (their syncs are counted in the warn pass and printed): ``compute_returns`` (reads the NaN flag once),
  ``update`` (rsl-rl's PPO update reads its losses and the adaptive learning rate's KL with
  ``.item()``), ``Logger.log``, ``save`` and ``init_logging_writer``: once an iteration each.

Both with the eager env step and with ``cuda_graph=True`` (the step's device work replayed as
one CUDA graph, captured in the warm-up iteration).

Not covered: the engine's overflow check, one host read every ``overflow_check_steps`` (100)
env steps by design; it is run just before the checked iterations so it does not fall inside.
The warn pass lists every synchronizing line at once (the error pass stops at the first).
"""

from __future__ import annotations

import collections
import contextlib
import io
import warnings

import pytest
import torch

from cuda_sync import sync_debug

pytestmark = pytest.mark.skipif(not torch.cuda.is_available(), reason="needs CUDA")

NUM_ENVS = 64


class AllowedSyncs:
    """Syncs of the once-per-iteration parts, by part, taken out of the warn pass's record."""

    caught: list | None = None
    by_part: collections.Counter = collections.Counter()


def _is_sync(warning) -> bool:
    # torch announces the mode itself once ("Synchronization debug mode is a prototype feature ..."):
    # that notice names no op, and the first device run counted it as the step's one sync
    message = str(warning.message).lower()
    return "synchroniz" in message and "prototype feature" not in message


def _unchecked(fn, part: str):
    """``fn``, a once-per-iteration part: under ``"error"`` it runs with the mode off; under
    ``"warn"`` its sync warnings are counted in ``AllowedSyncs.by_part`` and removed from the
    step path's record."""
    def call(*args, **kwargs):
        if torch.cuda.get_sync_debug_mode() == 2:  # error
            with sync_debug("default"):
                return fn(*args, **kwargs)
        record = AllowedSyncs.caught
        before = len(record) if record is not None else 0
        try:
            return fn(*args, **kwargs)
        finally:
            if record is not None:
                AllowedSyncs.by_part[part] += sum(map(_is_sync, record[before:]))
                del record[before:]
    return call


@pytest.fixture(scope="module", params=[False, True], ids=["eager", "cuda_graph"])
def runner(request, tmp_path_factory):
    from ambulo import envs
    from ambulo.rl.config import ppo_cfg
    from ambulo.rl.episodes import EpisodeStats
    from ambulo.rl.train import AmbuloRunner, runner_cfg
    from ambulo.rl.vecenv import RslRlVecEnv

    torch.manual_seed(0)
    # cuda_graph: the env step replayed as one CUDA graph (envs.graph_step), captured in the warm-up
    env = envs.make("humanoid-walk", num_envs=NUM_ENVS, device="cuda", seed=0, cuda_graph=request.param)
    ppo = ppo_cfg("humanoid-walk", num_envs=NUM_ENVS)
    with contextlib.redirect_stdout(io.StringIO()):
        runner = AmbuloRunner(RslRlVecEnv(env, EpisodeStats(NUM_ENVS, env.device)), runner_cfg(env, ppo),
                              log_dir=str(tmp_path_factory.mktemp("run")), device=str(env.device))
        runner.learn(1, init_at_random_ep_len=True)  # warm-up: compile, captures, first resets
    assert (env._graph is not None and env._graph.graph is not None) == request.param
    for name in ("compute_returns", "update"):
        setattr(runner.alg, name, _unchecked(getattr(runner.alg, name), name))
    for name in ("log", "init_logging_writer"):
        setattr(runner.logger, name, _unchecked(getattr(runner.logger, name), f"logger.{name}"))
    runner.save = _unchecked(runner.save, "save")
    return runner


def _iteration(runner, mode: str) -> None:
    runner.env.env.engine.check_overflow()  # the engine's periodic read, outside the checked steps
    torch.cuda.synchronize()
    with contextlib.redirect_stdout(io.StringIO()), sync_debug(mode):
        runner.learn(1)


def test_a_ppo_iteration_syncs_nowhere_but_the_update(runner):
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        AllowedSyncs.caught = caught
        try:
            _iteration(runner, "warn")
        finally:
            AllowedSyncs.caught = None
    # the figure for the record (pytest -rA prints it): what the update and logging read per iteration
    print(f"syncs per iteration outside the step path: {dict(AllowedSyncs.by_part)}")
    where = sorted({f"{w.filename}:{w.lineno}: {str(w.message).splitlines()[0]}" for w in caught if _is_sync(w)})
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
