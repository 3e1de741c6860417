"""evaluate: measure a trained policy over many complete episodes.

Each of ``num_episodes`` envs runs exactly one episode of ``episode_length_s`` of the task's
play variant (no pushes, no observation noise) with the deterministic policy (the action
mean). An episode *fails* when it ends by a termination that is not a success (the task's
``success_terminations``; for humanoid-walk every termination is a fall). The task's
``step_metrics`` (for humanoid-walk the planar velocity and yaw-rate errors) are averaged
over every policy step of every episode until it ends, and each of its ``criteria`` is
reported as a bool. ``run_episodes`` is the measurement itself: ``evaluate`` applies it to a
saved checkpoint, ``ambulo.rl.periodic_eval`` to the policy under training. A task laid out
in blocks (``eval_blocks``: humanoid-walk-robust's nominal + 16 transfer corners) is summarized
block by block, and its criteria hold where they hold in every block. A terrain task's result
also summarizes each tile kind's episodes alone (``by_kind``: reported, not judged; ``eval_kinds``).
"""

from __future__ import annotations

import contextlib
import json
import os
from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass, field
from typing import Any

import torch
from tqdm import tqdm

from ambulo import envs
from ambulo.utils.atomic import atomic_write_json

from . import runs
from .distributed import Rank
from .eval_blocks import blocks_table, eval_layout, judge_blocks
from .eval_kinds import kinds_table, reported, tile_kinds
from .eval_share import eval_share, merge_over_ranks


@dataclass
class EpisodeRecords:
    """What each of N complete episodes did; every tensor is (N,) on the env's device.

    ``metric_means``: per step metric, its mean over the steps of each episode (float64)."""

    failed: torch.Tensor
    succeeded: torch.Tensor
    returns: torch.Tensor
    length_steps: torch.Tensor
    metric_means: dict[str, torch.Tensor]

    def _columns(self) -> list[torch.Tensor]:
        """Each episode's share of ``EpisodeSums``' fields, in ``to_tensor``'s order: (N,) float64 each
        (1 for the episode count)."""
        return [torch.ones_like(self.returns), self.failed.double(), self.succeeded.double(), self.returns,
                self.length_steps, *self.metric_means.values()]

    def sums(self, rows: slice = slice(None)) -> EpisodeSums:
        """The totals of the episodes ``rows`` (one device-to-host read)."""
        totals = torch.stack([column[rows].sum() for column in self._columns()])
        return EpisodeSums.from_values(totals, self.metric_means)

    def sums_by(self, group: torch.Tensor, count: int) -> list[EpisodeSums]:
        """The totals of the episodes of each of ``count`` groups, ``group`` (N,) int64 the group of
        each episode, in [0, count) (one device-to-host read). A masked sum rather than
        ``index_add_``: CUDA's atomic adds would sum in a different order from run to run."""
        columns = torch.stack(self._columns(), dim=1)  # (N, C)
        member = group[None, :] == torch.arange(count, device=group.device)[:, None]  # (count, N)
        totals = torch.where(member[:, :, None], columns[None], 0.0).sum(dim=1).cpu()  # (count, C)
        return [EpisodeSums.from_values(row, self.metric_means) for row in totals]


@dataclass
class EpisodeSums:
    """Totals over a set of complete episodes: what evaluations of disjoint shares of the episodes
    (on several processes, ``eval_share``) add up to before ``summarize`` divides by the count.
    Means are merged as sums and counts, never as averages of averages: shares of unequal size
    weigh by their episodes."""

    episodes: float
    falls: float
    successes: float
    returns: float
    """Sum of the episodes' returns."""
    length_steps: float
    """Sum of the episodes' lengths, policy steps."""
    metric_means: dict[str, float] = field(default_factory=dict)
    """Step metric -> sum over the episodes of its per-episode mean."""

    def to_tensor(self) -> torch.Tensor:
        """(5 + metrics,) float64: the fields in order (metrics in insertion order)."""
        return torch.tensor([self.episodes, self.falls, self.successes, self.returns, self.length_steps,
                             *self.metric_means.values()], dtype=torch.float64)

    @classmethod
    def from_values(cls, values: torch.Tensor, metric_names) -> EpisodeSums:
        """Sums from ``values`` (``to_tensor``'s layout), the metrics named by ``metric_names`` in order."""
        v = values.cpu().tolist()
        return cls(*v[:5], dict(zip(metric_names, v[5:])))

    def like(self, values: torch.Tensor) -> EpisodeSums:
        """Sums with ``values`` (``to_tensor``'s layout) and this one's metric names."""
        return EpisodeSums.from_values(values, self.metric_means)

    def __add__(self, other: EpisodeSums) -> EpisodeSums:
        if list(self.metric_means) != list(other.metric_means):
            raise ValueError(f"cannot merge episodes measuring {list(self.metric_means)} "
                             f"and {list(other.metric_means)}")
        return self.like(self.to_tensor() + other.to_tensor())


def summarize(sums: EpisodeSums, task: envs.TaskSpec, *, step_dt_s: float, max_episode_length: int,
              blocks: list[dict] | None = None) -> dict:
    """``run_episodes``' result from the totals of its episodes: the one place metrics are computed,
    for one process's episodes or the merged shares of several. ``blocks``: the summaries of the
    blocks these episodes were laid out in (``eval_blocks``): the criteria hold where they hold
    in every block."""
    n = sums.episodes
    result = {
        "task": task.name,
        "episodes": int(n),
        "episode_length_s": max_episode_length * step_dt_s,
        "fall_rate": sums.falls / n,
        "success_rate": sums.successes / n,
        "mean_return": sums.returns / n,
        "mean_episode_length_s": sums.length_steps / n * step_dt_s,
    }
    for name, total in sums.metric_means.items():
        result[f"mean_{name}"] = total / n
    result["criteria"] = [c.name for c in task.criteria]
    for criterion in task.criteria:
        result[criterion.name] = criterion.holds(result)
    if blocks is not None:
        judge_blocks(result, blocks, task)
    return result


def run_episodes(env: envs.RLEnv, vec_env, policy: Callable, task: envs.TaskSpec, *,
                 desc: str = "eval", quiet: bool = True, blocks: int | Sequence[str] = 1,
                 merge: Callable[[EpisodeSums], EpisodeSums] | None = None) -> dict:
    """Run one episode in each env of ``env`` (wrapped by ``vec_env``, an ``RslRlVecEnv``)
    with ``policy`` (TensorDict observations -> (N, num_actions) actions) from a full reset;
    return the metrics and criteria (see the module docstring). ``blocks``: the envs are that
    many contiguous equal blocks evaluated side by side (humanoid-walk's ``transfer_blocks``: one
    condition each), named ``blocks`` when a sequence of names: ``result["blocks"]`` holds each
    one's result (the same keys and its ``name``) beside the whole's, whose criteria hold where
    they hold in every block (``eval_blocks``). ``merge``: these episodes are one share of an
    evaluation split over processes (``eval_share``); it returns the totals of every share (of
    each block's, block by block), which the result describes."""
    if isinstance(blocks, int) and blocks < 1:
        raise ValueError(f"blocks={blocks}: give 1 or more")
    names = tuple(blocks) if not isinstance(blocks, int) else (
        () if blocks == 1 else tuple(f"block {b}" for b in range(blocks)))
    count = len(names) or 1
    if env.num_envs % count:
        raise ValueError(f"blocks={blocks} does not split {env.num_envs} envs evenly")
    records = episode_records(env, vec_env, policy, task, desc=desc, quiet=quiet)
    merged = merge if merge is not None else (lambda sums: sums)
    shape = {"step_dt_s": env.step_dt_s, "max_episode_length": env.max_episode_length}
    if not names:
        result = summarize(merged(records.sums()), task, **shape)
    else:
        per = env.num_envs // count
        # every rank merges the same blocks in the same order (each merge is one collective)
        parts = [{"name": name, **summarize(merged(records.sums(slice(b * per, (b + 1) * per))), task, **shape)}
                 for b, name in enumerate(names)]
        result = summarize(merged(records.sums()), task, **shape, blocks=parts)
    kinds = tile_kinds(env)
    if kinds is not None:
        result["by_kind"] = summarize_kinds(records, *kinds, task, merged, **shape)
    return result


def summarize_kinds(records: EpisodeRecords, names: Sequence[str], kind: torch.Tensor, task: envs.TaskSpec,
                    merge: Callable[[EpisodeSums], EpisodeSums], **shape) -> dict[str, dict[str, Any]]:
    """Each tile kind's episodes summarized alone (``eval_kinds``): kind name -> ``summarize``'s numbers
    without the criteria (reported, not judged), in the terrain's column order; a kind no episode
    of any process ran on is left out. ``kind``: (N,) int64 index into ``names`` of each episode's."""
    # every rank merges every kind in the same order, even one it ran no episode of (one collective each)
    totals = [merge(sums) for sums in records.sums_by(kind, len(names))]
    return {name: reported(summarize(sums, task, **shape), task)
            for name, sums in zip(names, totals) if sums.episodes > 0}


def episode_records(env: envs.RLEnv, vec_env, policy: Callable, task: envs.TaskSpec, *,
                    desc: str = "eval", quiet: bool = True,
                    on_step: Callable[[torch.Tensor], None] | None = None) -> EpisodeRecords:
    """Run one episode in each env of ``env`` (see ``run_episodes``); what each one did.
    ``on_step(running)``, if given, sees each step's state before the policy acts on it, with the
    (N,) bool of the envs whose episode is still running (``scripts/plot_falls.py``: the paths)."""
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
        if on_step is not None:
            on_step(running)
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
    steps = lengths.clamp(min=1.0)
    return EpisodeRecords(failed, succeeded, returns, lengths,
                          {name: total / steps for name, total in metric_sums.items()})


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
             num_episodes: int | None = None, episode_length_s: float | None = None, seed: int = 12345,
             log_root: str | os.PathLike = "runs", quiet: bool = False, device: str | None = None,
             watch: Callable[[envs.RLEnv], Any] | None = None, rank: Rank | None = None,
             env_overrides: dict[str, Any] | None = None) -> dict:
    """Evaluate ``run`` and return (and print) a dict of metrics; also written to
    ``<run>/eval.json``. ``num_episodes``: default 100, or the task's blocks' default
    (``eval_blocks``). ``device`` (default: the run's) evaluates on another engine: a policy
    trained on a GPU, evaluated with ``device="cpu"``, is a sim-to-sim check. ``watch``: see
    ``watched`` (the episodes are shown as they run). ``rank``: this process runs its share of
    the episodes in a group of processes (``eval_gpus``; ``device`` is then its own) and gets
    the merged result; rank 0 alone prints and writes eval.json. ``env_overrides``: task config
    fields set on top of the run's (``ambulo eval --env-cfg``, e.g. a friction or terrain variant);
    the result names them."""
    rank = rank if rank is not None else Rank()
    run_dir, ckpt = runs.resolve_policy(run, checkpoint, log_root)
    info = runs.read_run_info(run_dir)
    task = envs.spec(info["task"])
    layout = eval_layout(task, num_episodes)
    share = eval_share(layout.num_episodes, seed, rank, blocks=layout.blocks)
    env = runs.make_env_for_run(info, num_envs=share.episodes, seed=share.seed, play=True, device=device,
                                episode_length_s=eval_episode_length_s(task, episode_length_s),
                                user_overrides=env_overrides, **layout.env_overrides)
    env.use_cuda_graph()  # on a GPU: 100 worlds are launch-bound, a replayed step is not
    runner = runs.load_runner(run_dir, env, ckpt)
    policy = runner.get_inference_policy(device=str(env.device))
    with watched(env, watch):
        merge = {} if not rank.distributed else {"merge": lambda sums: merge_over_ranks(sums, rank, env.device)}
        measured = run_episodes(env, runner.env, policy, task, desc=f"eval {info['task']}",
                                quiet=quiet or not rank.is_main, blocks=layout.run_blocks, **merge)
    result = {"task": info["task"], "run": str(run_dir), "checkpoint": ckpt.name,
              "device": str(env.device) if not rank.distributed else f"{env.device.type} x {rank.world_size}",
              **({"env_overrides": env_overrides} if env_overrides else {}), **measured}
    if not rank.is_main:
        env.close()
        return result
    atomic_write_json(run_dir / "eval.json", result, indent=2, sort_keys=False, fsync=True)
    if not quiet:
        print_result(result)
    env.close()
    return result


def print_result(result: dict) -> None:
    """The result as JSON, a blocked evaluation's blocks and a terrain task's tile kinds as tables
    after it (eval.json keeps them whole)."""
    print(json.dumps({k: v for k, v in result.items() if k not in ("blocks", "blocks_failed", "by_kind")},
                     indent=2))
    if "blocks" in result:
        print(blocks_table(result))
    if "by_kind" in result:
        print(kinds_table(result["by_kind"]))


def evaluate_shipped(task: str, *, num_episodes: int | None = None, episode_length_s: float | None = None,
                     seed: int = 12345, device: str = "cpu", quiet: bool = False,
                     watch: Callable[[envs.RLEnv], Any] | None = None,
                     env_overrides: dict[str, Any] | None = None) -> dict:
    """Evaluate the policy that ships with ambulo for ``task`` (``ambulo.policies``) as
    ``evaluate`` measures a run: the same episodes, metrics and criteria; no run folder needed.
    ``watch``, ``env_overrides``: as ``evaluate``'s."""
    from ambulo.policies.shipped import load_policy

    from .vecenv import RslRlVecEnv

    shipped = load_policy(task)
    spec = envs.spec(task)
    layout = eval_layout(spec, num_episodes)
    overrides = {**layout.env_overrides, **(env_overrides or {})}
    env = envs.make(task, num_envs=layout.num_episodes, device=device, seed=seed, play=True,
                    episode_length_s=eval_episode_length_s(spec, episode_length_s), **overrides)
    env.use_cuda_graph()
    with watched(env, watch):
        measured = run_episodes(env, RslRlVecEnv(env), lambda obs: shipped(obs["policy"]), spec,
                                desc=f"eval shipped {task}", quiet=quiet, blocks=layout.run_blocks)
    result = {"task": task, "policy": str(shipped.folder), "checkpoint": shipped.contract["trained"]["checkpoint"],
              "device": str(env.device), **({"env_overrides": env_overrides} if env_overrides else {}), **measured}
    if not quiet:
        print_result(result)
    env.close()
    return result
