"""EpisodeLogger: rsl-rl-lib's ``Logger`` with nothing read back from the GPU per env step.

rsl-rl's ``Logger.process_env_step`` runs after every env step of a rollout. It finds the
episodes that ended with ``(dones > 0).nonzero()`` and copies their returns and lengths to the
host (``.cpu().numpy().tolist()``) for its 100-episode buffers: host syncs in every training
step on a GPU. ambulo keeps those returns and lengths on the device already
(``episodes.EpisodeStats``, fed by ``vecenv.RslRlVecEnv``), so this logger keeps only the env's
per-step ``extras`` (device tensors, averaged by rsl-rl once per iteration) and, once an
iteration, fills rsl-rl's buffers from ``EpisodeStats`` before rsl-rl's own ``log`` prints and
writes them: the report reads as before, from one read of the device per iteration.
"""

from __future__ import annotations

from collections import deque

import torch
from rsl_rl.utils.logger import Logger

from .episodes import EpisodeStats


class EpisodeLogger(Logger):
    """``Logger`` whose per-step bookkeeping stays on the device (see the module doc).

    ``episodes``: the run's ``EpisodeStats`` (None on ranks that log nothing).
    """

    episodes: EpisodeStats | None = None

    @classmethod
    def adopt(cls, logger: Logger, episodes: EpisodeStats | None) -> EpisodeLogger:
        """Turn ``logger`` (the one ``OnPolicyRunner.__init__`` builds, before its writer exists)
        into an ``EpisodeLogger`` in place: its settings and buffers stay, without restating the
        runner's constructor call; step and log become this class's."""
        logger.__class__ = cls
        logger.episodes = episodes
        return logger

    def process_env_step(self, rewards: torch.Tensor, dones: torch.Tensor, extras: dict,
                         intrinsic_rewards: torch.Tensor | None = None) -> None:
        if intrinsic_rewards is not None or self.episodes is None:
            # RND's extrinsic/intrinsic split is rsl-rl's alone (ambulo configures no RND)
            super().process_env_step(rewards, dones, extras, intrinsic_rewards)
            return
        if self.writer is None:
            return
        if "episode" in extras:
            self.ep_extras.append(extras["episode"])
        elif "log" in extras:
            self.ep_extras.append(extras["log"])

    def log(self, *args, **kwargs) -> None:
        if self.episodes is not None and self.writer is not None:
            self.rewbuffer = deque(self.episodes.returns(), maxlen=100)
            self.lenbuffer = deque(self.episodes.lengths(), maxlen=100)
        super().log(*args, **kwargs)


__all__ = ["EpisodeLogger"]
