"""The PPO settings of a task: its ``TaskSpec.ppo_cfg_fn`` with checked overrides."""

from __future__ import annotations

from typing import Any

from ambulo import envs
from ambulo.envs.ppo import PpoCfg
from ambulo.utils.overrides import replace_dotted


def ppo_cfg(task: str, *, num_envs: int | None = None, max_iterations: int | None = None,
            **overrides: Any) -> PpoCfg:
    """PPO settings of ``task`` (its registry entry) with ``num_envs``/``max_iterations`` (None:
    the task's) and ``overrides`` (field names, checked against ``PpoCfg``'s types)."""
    given = {k: v for k, v in dict(num_envs=num_envs, max_iterations=max_iterations).items() if v is not None}
    return replace_dotted(envs.spec(task).ppo_cfg_fn(), {**given, **overrides}, check_types=True)


__all__ = ["PpoCfg", "ppo_cfg"]
