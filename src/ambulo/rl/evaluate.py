"""evaluate: measure a trained policy over many complete episodes.

Each of ``num_episodes`` envs runs exactly one episode of ``episode_length_s`` of the task's
play variant (no pushes, no observation noise) with the deterministic policy (the action
mean). An episode *fails* when it ends by a termination that is not a success (the task's
``success_terminations``; for humanoid-walk every termination is a fall). The task's
``step_metrics`` (for humanoid-walk the planar velocity and yaw-rate errors) are averaged
over every policy step of every episode until it ends, and each of its ``criteria`` is
reported as a bool. ``run_episodes`` is the measurement itself: ``evaluate`` applies it to a
saved checkpoint, ``ambulo.rl.periodic_eval`` to the policy under training.
"""

from __future__ import annotations

import contextlib
import json
import os
from collections.abc import Callable, Iterator
from typing import Any

import torch
from tqdm import tqdm

from ambulo import envs
from ambulo.utils.atomic import atomic_write_json

from . import runs


def run_episodes(env: envs.RLEnv, vec_env, policy: Callable, task: envs.TaskSpec, *,
                 desc: str = "eval", quiet: bool = True, blocks: int = 1) -> dict:
    """Run one episode in each env of ``env`` (wrapped by ``vec_env``, an ``RslRlVecEnv``)
    with ``policy`` (TensorDict observations -> (N, num_actions) actions) from a full reset;
    return the metrics and criteria (see the module docstring). ``blocks`` > 1: the envs are
    that many contiguous equal blocks evaluated side by side (humanoid-walk's
    ``transfer_blocks``: one condition each), and ``result["blocks"]`` holds each one's result
    (the same keys) beside the whole's."""
    if blocks < 1 or env.num_envs % blocks:
        raise ValueError(f"blocks={blocks} does not split {env.num_envs} envs evenly")
    n, dev = env.num_envs, env.device
    running = torch.ones(n, dtype=torch.bool, device=dev)
    failed = torch.zeros(n, dtype=torch.bool, device=dev)
    succeeded = torch.zeros(n, dtype=torch.bool, device=dev)
    returns = torch.zeros(n, dtype=torch.float64, device=dev)
    lengths = torch.zeros(n, dtype=torch.float64, device=dev)
    metric_sums: dict[str, torch.Tensor] = {}
    obs = vec_env.reset()
    # the loop never reads a device value back: an early end when every episode is over would
    # cost a host sync per step, more than the few steps it saves
    for _ in tqdm(range(env.max_episode_length), desc=desc, unit="step", disable=quiet):
        with torch.inference_mode():
            actions = policy(obs)
        if task.step_metrics is not None:  # of the state the policy acted on, for running envs
            for name, value in task.step_metrics(env).items():
                total = value.double() * running
                metric_sums[name] = metric_sums[name] + total if name in metric_sums else total
        obs, rewards, dones, extras = vec_env.step(actions)
        returns += rewards.double() * running
        lengths += running.double()
        ended = running & dones.bool()
        for name, mask in extras["terminations"].items():
            target = succeeded if name in task.success_terminations else failed
            target |= ended & mask
        failed |= ended & extras["terminated"] & ~succeeded
        running &= ~dones.bool()

    def summary(rows: slice) -> dict:
        steps = lengths[rows].clamp(min=1.0)
        result = {
            "task": task.name,
            "episodes": int(lengths[rows].numel()),
            "episode_length_s": env.max_episode_length * env.step_dt_s,
            "fall_rate": float(failed[rows].double().mean()),
            "success_rate": float(succeeded[rows].double().mean()),
            "mean_return": float(returns[rows].mean()),
            "mean_episode_length_s": float(lengths[rows].mean() * env.step_dt_s),
        }
        for name, total in metric_sums.items():
            result[f"mean_{name}"] = float((total[rows] / steps).mean())
        result["criteria"] = [c.name for c in task.criteria]
        for criterion in task.criteria:
            result[criterion.name] = criterion.holds(result)
        return result

    result = summary(slice(None))
    if blocks > 1:
        per = n // blocks
        result["blocks"] = [summary(slice(b * per, (b + 1) * per)) for b in range(blocks)]
    return result


@contextlib.contextmanager
def watched(env: envs.RLEnv, watch: Callable[[envs.RLEnv], Any] | None) -> Iterator[None]:
    """Inside the block ``env`` is watched by what ``watch(env)`` returns (``ambulo eval --viewer
    web``: the web viewer, an app this package may not import), ``close()``d on the way out."""
    watcher = None if watch is None else watch(env)
    try:
        yield
    finally:
        if watcher is not None:
            watcher.close()


def eval_episode_length_s(task: envs.TaskSpec, episode_length_s: float | None) -> float:
    """The play variant has no time-out: episodes last the training episode length."""
    return task.cfg_fn().episode_length_s if episode_length_s is None else episode_length_s


def evaluate(run: str | os.PathLike, *, checkpoint: str | os.PathLike | None = None,
             num_episodes: int = 100, episode_length_s: float | None = None, seed: int = 12345,
             log_root: str | os.PathLike = "runs", quiet: bool = False, device: str | None = None,
             watch: Callable[[envs.RLEnv], Any] | None = None) -> dict:
    """Evaluate ``run`` and return (and print) a dict of metrics; also written to
    ``<run>/eval.json``. ``device`` (default: the run's) evaluates on another engine: a policy
    trained on a GPU, evaluated with ``device="cpu"``, is a sim-to-sim check. ``watch``: see
    ``watched`` (the episodes are shown as they run)."""
    run_dir, ckpt = runs.resolve_policy(run, checkpoint, log_root)
    info = runs.read_run_info(run_dir)
    task = envs.spec(info["task"])
    env = runs.make_env_for_run(info, num_envs=num_episodes, seed=seed, play=True, device=device,
                                episode_length_s=eval_episode_length_s(task, episode_length_s))
    env.use_cuda_graph()  # on a GPU: 100 worlds are launch-bound, a replayed step is not
    runner = runs.load_runner(run_dir, env, ckpt)
    policy = runner.get_inference_policy(device=str(env.device))
    with watched(env, watch):
        measured = run_episodes(env, runner.env, policy, task, desc=f"eval {info['task']}", quiet=quiet)
    result = {"task": info["task"], "run": str(run_dir), "checkpoint": ckpt.name,
              "device": str(env.device), **measured}
    atomic_write_json(run_dir / "eval.json", result, indent=2, sort_keys=False, fsync=True)
    if not quiet:
        print(json.dumps(result, indent=2))
    env.close()
    return result


def evaluate_shipped(task: str, *, num_episodes: int = 100, episode_length_s: float | None = None,
                     seed: int = 12345, device: str = "cpu", quiet: bool = False,
                     watch: Callable[[envs.RLEnv], Any] | None = None) -> dict:
    """Evaluate the policy that ships with ambulo for ``task`` (``ambulo.policies``) as
    ``evaluate`` measures a run: the same episodes, metrics and criteria; no run folder needed.
    ``watch``: as ``evaluate``'s."""
    from ambulo.policies.shipped import load_policy

    from .vecenv import RslRlVecEnv

    shipped = load_policy(task)
    spec = envs.spec(task)
    env = envs.make(task, num_envs=num_episodes, device=device, seed=seed, play=True,
                    episode_length_s=eval_episode_length_s(spec, episode_length_s))
    env.use_cuda_graph()
    with watched(env, watch):
        measured = run_episodes(env, RslRlVecEnv(env), lambda obs: shipped(obs["policy"]), spec,
                                desc=f"eval shipped {task}", quiet=quiet)
    result = {"task": task, "policy": str(shipped.folder), "checkpoint": shipped.contract["trained"]["checkpoint"],
              "device": str(env.device), **measured}
    if not quiet:
        print(json.dumps(result, indent=2))
    env.close()
    return result
