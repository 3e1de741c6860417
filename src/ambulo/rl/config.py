"""The PPO settings of a task: its ``TaskSpec.ppo_cfg_fn`` with overrides."""

from __future__ import annotations

import dataclasses
from typing import Any

from ambulo import envs
from ambulo.envs.ppo import PpoCfg


def ppo_cfg(task: str, **overrides: Any) -> PpoCfg:
    """PPO settings of ``task`` (from its registry entry) with ``overrides`` (None: keep)."""
    cfg = envs.spec(task).ppo_cfg_fn()
    known = {f.name for f in dataclasses.fields(cfg)}
    unknown = sorted(set(overrides) - known)
    if unknown:
        raise TypeError(f"PpoCfg has no field(s) {unknown}; fields: {', '.join(sorted(known))}")
    return dataclasses.replace(cfg, **{k: v for k, v in overrides.items() if v is not None})


__all__ = ["PpoCfg", "ppo_cfg"]
