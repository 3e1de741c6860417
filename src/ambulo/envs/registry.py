"""The task registry: one ``TaskSpec`` per task, registered next to the task.

A ``TaskSpec`` is everything the rest of ambulo knows about a task: the env class, its
config factory and play variant, its PPO settings, the metrics evaluation measures and the
criteria that say the task is solved. ``envs.make``, ``ambulo.rl`` (train, play, eval), the
CLI, the docs and the contract test read it; nothing asks an env what it can do.
"""

from __future__ import annotations

import difflib
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import torch

from ..utils.overrides import replace_dotted
from .base import EnvCfg, RLEnv
from .ppo import PpoCfg

StepMetrics = Callable[[RLEnv], dict[str, torch.Tensor]]


@dataclass(frozen=True)
class Criterion:
    """A named pass/fail bar over evaluation metrics (keys of ``ambulo eval``'s result)."""

    name: str
    """E.g. ``"walks"``; evaluation reports it as a bool."""
    max_values: dict[str, float] = field(default_factory=dict)
    """Metric -> largest passing value."""
    min_values: dict[str, float] = field(default_factory=dict)
    """Metric -> smallest passing value."""

    def holds(self, result: dict[str, float]) -> bool:
        return (all(result[k] <= v for k, v in self.max_values.items())
                and all(result[k] >= v for k, v in self.min_values.items()))

    def load(self, result: dict[str, float]) -> float:
        """How close ``result`` is to failing: the largest ratio of a metric to its bar (a
        ``min_values`` bar to its metric); above 1 fails, for bars above 0. Ranks the blocks of
        an evaluation laid out in blocks (its worst block: the largest load)."""
        def ratio(value: float, bar: float) -> float:
            return value / bar if bar > 0 else (0.0 if value <= bar else float("inf"))

        loads = [ratio(result[k], v) for k, v in self.max_values.items()]
        loads += [ratio(v, result[k]) for k, v in self.min_values.items()]
        return max(loads, default=0.0)


@dataclass(frozen=True)
class EvalBlocks:
    """An evaluation laid out in named blocks of worlds, each under its own condition.

    The evaluation env's worlds split into ``len(names)`` contiguous equal blocks, block b
    under condition ``names[b]`` (humanoid-walk-robust: nominal and the 16 corners of the
    transfer ranges); each block is summarized on its own and every criterion of the task
    holds when it holds in every block (``rl.eval_blocks``)."""

    names: tuple[str, ...]
    env_overrides: dict[str, Any]
    """Overrides of the play variant's config that lay its worlds out in these blocks (for
    humanoid-walk: ``transfer_blocks``); they need a number of worlds divisible by the blocks."""
    episodes_per_block: int
    """The default evaluation's episodes per block (``ambulo eval``, ``--eval-every``)."""


@dataclass(frozen=True)
class TaskSpec:
    """A registered task."""

    name: str
    env_cls: type[RLEnv]
    cfg_fn: Callable[[], EnvCfg]
    """Default training config."""
    description: str
    play_cfg_fn: Callable[[], EnvCfg] | None = None
    """Config for ``play``/``eval`` of a policy (no pushes or noise); None: ``cfg_fn``."""
    ppo_cfg_fn: Callable[[], PpoCfg] = PpoCfg
    """PPO settings for ``ambulo train``."""
    step_metrics: StepMetrics | None = None
    """Per-step (N,) values evaluation averages over every step of every episode, reported as
    ``mean_<name>`` (e.g. the velocity tracking error)."""
    success_terminations: tuple[str, ...] = ()
    """Termination names that mean success (a goal reached), not failure."""
    criteria: tuple[Criterion, ...] = field(default=())
    """What "solved" means, checked by ``ambulo eval``."""
    eval_blocks_fn: Callable[[], EvalBlocks] | None = None
    """The evaluation's layout in blocks, where the criteria must hold in each (None: one
    block, the play variant as it is)."""

    def play_cfg(self) -> EnvCfg:
        return (self.play_cfg_fn or self.cfg_fn)()

    def eval_blocks(self) -> EvalBlocks | None:
        return None if self.eval_blocks_fn is None else self.eval_blocks_fn()


_REGISTRY: dict[str, TaskSpec] = {}


def register(spec_: TaskSpec) -> TaskSpec:
    """Add a task; names are unique."""
    if spec_.name in _REGISTRY:
        raise ValueError(f"task {spec_.name!r} is already registered")
    _REGISTRY[spec_.name] = spec_
    return spec_


def registry() -> dict[str, TaskSpec]:
    """A copy of the registry: task name -> ``TaskSpec``."""
    return dict(_REGISTRY)


def names() -> list[str]:
    """Registered task names, sorted."""
    return sorted(_REGISTRY)


def spec(name: str) -> TaskSpec:
    """The ``TaskSpec`` of ``name``; a helpful ``KeyError`` for unknown names."""
    try:
        return _REGISTRY[name]
    except KeyError:
        close = difflib.get_close_matches(name, _REGISTRY, n=3)
        hint = f" Did you mean {', '.join(map(repr, close))}?" if close else ""
        raise KeyError(
            f"no task named {name!r}.{hint} Registered: {', '.join(names())}."
        ) from None


def make_cfg(name: str, *, play: bool = False, **overrides: Any) -> EnvCfg:
    """A fresh config of task ``name`` (its play variant if ``play``) with ``overrides`` applied.

    Keys are field names, or dotted paths into nested configs and dict fields
    (``**{"physics.timestep_s": 0.002, "reward_weights.upright": 1.0}``); each value is checked
    against the field's type (``OverrideError`` names the key, the type and close matches).
    """
    task = spec(name)
    cfg = task.play_cfg() if play else task.cfg_fn()
    return replace_dotted(cfg, overrides, check_types=True)


def make(name: str, *, num_envs: int | None = None, device: str | None = None,
         seed: int | None = None, play: bool = False, **overrides: Any) -> RLEnv:
    """Build task ``name`` with ``num_envs`` envs on ``device``, seeded with ``seed`` (None
    keeps the task default).

    Other keyword arguments override fields of the task's config (see ``make_cfg``), e.g.
    ``make("humanoid-walk", num_envs=512, episode_length_s=20.0)``; ``play=True`` starts from
    the task's play variant.
    """
    given = {k: v for k, v in dict(num_envs=num_envs, device=device, seed=seed).items() if v is not None}
    cfg = make_cfg(name, play=play, **given, **overrides)
    return spec(name).env_cls(cfg)


__all__ = ["Criterion", "EvalBlocks", "TaskSpec", "make", "make_cfg", "names", "register", "registry", "spec"]
