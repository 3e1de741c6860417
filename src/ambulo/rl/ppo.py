"""AmbuloPPO: rsl-rl-lib's PPO, named in ``train_cfg["algorithm"]["class_name"]`` (its extension point).

The NaN check without a host sync per step. rsl-rl's runner, with ``check_for_nan``, asks
``torch.isnan(x).any()`` in a Python ``if`` for every observation group and the rewards after
every env step: a device-to-host read each, the GPU idle while the host waits. ambulo's runner
config turns that off (``train.runner_cfg``) and this class runs the same test on the device:
``process_env_step`` ORs each step's finding into one flag tensor and ``compute_returns``,
once an iteration and before any of that data trains the networks, reads it and raises rsl-rl's
``ValueError`` naming the group. A NaN stops training at the end of the rollout instead of at
its step; nothing is learnt from it.

Two additions for data-parallel training (``ambulo.rl.distributed``):

- CPU ranks over gloo. rsl-rl-lib's runner sets up data-parallel training on CUDA with NCCL only,
  from ``WORLD_SIZE``. For CPU ranks ambulo opens the gloo group itself and builds the runner as
  one process (``distributed.single_process_view``); this class then takes the group's ranks as
  its ``multi_gpu_cfg``, so the algorithm averages gradients, the KL and the adaptive learning rate
  over the ranks exactly as rsl-rl does for GPUs (``AmbuloRunner.learn`` starts the ranks from rank
  0's weights, as rsl-rl's does when it knows it is distributed).
- ``after_update``: called after every update on the ranks other than 0, which have no logger,
  so they share rank 0's end-of-iteration decisions (``progress.TrainingProgress.follow``).
"""

from __future__ import annotations

from collections.abc import Callable

import torch
from rsl_rl.algorithms import PPO
from tensordict import TensorDict

from . import distributed


class AmbuloPPO(PPO):
    """rsl-rl-lib's ``PPO`` plus the CPU process group and a per-update hook (see the module doc)."""

    def __init__(self, *args, multi_gpu_cfg: dict | None = None, **kwargs):
        super().__init__(*args, multi_gpu_cfg=multi_gpu_cfg or distributed.cpu_group_cfg(), **kwargs)
        self.after_update: Callable[[], None] | None = None
        self._nan_seen: torch.Tensor | None = None
        """(groups + 1,) bool on the device: a NaN in each observation group, then the rewards,
        since the last ``compute_returns``."""
        self._nan_names: list[str] = []

    def process_env_step(self, obs: TensorDict, rewards: torch.Tensor, dones: torch.Tensor,
                         extras: dict) -> None:
        found = torch.stack([torch.isnan(t).any() for t in (*obs.values(), rewards)])
        if self._nan_seen is None:
            self._nan_names = [*obs.keys(), "rewards"]
        # out of place: the flag may be an inference tensor from the rollout's inference mode
        self._nan_seen = found if self._nan_seen is None else self._nan_seen | found
        super().process_env_step(obs, rewards, dones, extras)

    def compute_returns(self, obs: TensorDict) -> None:
        self.raise_on_nan()
        super().compute_returns(obs)

    def raise_on_nan(self) -> None:
        """Raise ``ValueError`` if a step since the last call returned NaN (one read of the device)."""
        seen, self._nan_seen = self._nan_seen, None
        if seen is None:
            return
        bad = [name for name, hit in zip(self._nan_names, seen.tolist()) if hit]
        if bad:
            raise ValueError(
                f"the environment returned NaN in {' and '.join(bad)} during the last rollout (observation "
                "groups or rewards); the engine resets worlds whose state diverges, so the NaN comes from the "
                "task's own observation or reward terms: step the env and look for the first non-finite term")

    def update(self) -> dict[str, float]:
        losses = super().update()
        if self.after_update is not None:
            self.after_update()
        return losses


__all__ = ["AmbuloPPO"]
