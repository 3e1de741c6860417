"""AmbuloPPO: rsl-rl-lib's PPO, named in ``train_cfg["algorithm"]["class_name"]`` (its extension point).

Two additions, both for data-parallel training (``ambulo.rl.distributed``):

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

from rsl_rl.algorithms import PPO

from . import distributed


class AmbuloPPO(PPO):
    """rsl-rl-lib's ``PPO`` plus the CPU process group and a per-update hook (see the module doc)."""

    def __init__(self, *args, multi_gpu_cfg: dict | None = None, **kwargs):
        super().__init__(*args, multi_gpu_cfg=multi_gpu_cfg or distributed.cpu_group_cfg(), **kwargs)
        self.after_update: Callable[[], None] | None = None

    def update(self) -> dict[str, float]:
        losses = super().update()
        if self.after_update is not None:
            self.after_update()
        return losses


__all__ = ["AmbuloPPO"]
