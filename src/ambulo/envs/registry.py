"""The task registry: one dict, one ``register`` call next to each task, copies out.

It feeds ``ambulo.envs.make``, the CLI (``ambulo train <task>``) and the contract test.
"""

from __future__ import annotations

import dataclasses
import difflib
from dataclasses import dataclass
from typing import Any, Callable

from .base import EnvCfg, RLEnv


@dataclass(frozen=True)
class TaskSpec:
    """A registered task: its env class, the function building its default config, a summary."""

    name: str
    env_cls: type[RLEnv]
    cfg_fn: Callable[[], EnvCfg]
    description: str


_REGISTRY: dict[str, TaskSpec] = {}


def register(name: str, env_cls: type[RLEnv], cfg_fn: Callable[[], EnvCfg],
             description: str) -> None:
    """Add a task; names are unique."""
    if name in _REGISTRY:
        raise ValueError(f"task {name!r} is already registered")
    _REGISTRY[name] = TaskSpec(name, env_cls, cfg_fn, description)


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


def make_cfg(name: str, **overrides: Any) -> EnvCfg:
    """A fresh default config of task ``name`` with ``overrides`` (config field names) applied.

    ``None`` values are ignored, so CLI flags that were not given keep the task default.
    """
    cfg = spec(name).cfg_fn()
    overrides = {k: v for k, v in overrides.items() if v is not None}
    known = {f.name for f in dataclasses.fields(cfg)}
    unknown = sorted(set(overrides) - known)
    if unknown:
        raise TypeError(
            f"{type(cfg).__name__} has no field(s) {unknown}; fields: {', '.join(sorted(known))}"
        )
    return dataclasses.replace(cfg, **overrides)


def make(name: str, *, num_envs: int | None = None, device: str | None = None,
         seed: int | None = None, **overrides: Any) -> RLEnv:
    """Build task ``name`` with ``num_envs`` envs on ``device``, seeded with ``seed``.

    Other keyword arguments override fields of the task's config, e.g.
    ``make("humanoid-walk", num_envs=512, episode_length_s=20.0)``.
    """
    cfg = make_cfg(name, num_envs=num_envs, device=device, seed=seed, **overrides)
    return spec(name).env_cls(cfg)


__all__ = ["TaskSpec", "make", "make_cfg", "names", "register", "registry", "spec"]
