"""RslRlVecEnv: an ambulo ``RLEnv`` seen through rsl-rl-lib's ``VecEnv`` interface.

rsl-rl-lib 5.x wants observations as a ``TensorDict`` of groups: ``policy`` feeds the
actor, and the critic reads ``policy`` plus ``critic`` (the task's privileged
observations) when the task has them.
"""

from __future__ import annotations

import torch
from rsl_rl.env import VecEnv
from tensordict import TensorDict

from ambulo.envs import RLEnv

from .episodes import EpisodeStats


class RslRlVecEnv(VecEnv):
    """Wraps ``env`` for ``rsl_rl.runners.OnPolicyRunner``; ``env`` stays the source of truth."""

    def __init__(self, env: RLEnv, episodes: EpisodeStats | None = None):
        self.env = env
        self.episodes = episodes
        """Fed every step's rewards and dones when given (training's metrics; see ``rl.episodes``)."""
        self.num_envs = env.num_envs
        self.num_actions = env.num_actions
        self.max_episode_length = env.max_episode_length
        self.device = env.device
        self.cfg = env.cfg
        self._critic_obs = env.get_privileged_observations()

    @property
    def episode_length_buf(self) -> torch.Tensor:
        return self.env.episode_length_buf

    @episode_length_buf.setter
    def episode_length_buf(self, value: torch.Tensor) -> None:
        # the runner randomizes episode phases by assigning a new buffer; keep the env's own
        self.env.episode_length_buf.copy_(value)

    def _obs(self, policy: torch.Tensor) -> TensorDict:
        groups = {"policy": policy}
        if self._critic_obs is not None:
            groups["critic"] = self._critic_obs
        return TensorDict(groups, batch_size=[self.num_envs], device=self.device)

    def get_observations(self) -> TensorDict:
        return self._obs(self.env.get_observations())

    def reset(self) -> TensorDict:
        policy = self.env.reset()
        self._critic_obs = self.env.get_privileged_observations()
        return self._obs(policy)

    def step(self, actions: torch.Tensor) -> tuple[TensorDict, torch.Tensor, torch.Tensor, dict]:
        obs, rewards, dones, extras = self.env.step(actions)
        if "observations" in extras:
            self._critic_obs = extras["observations"]["critic"]
        if self.episodes is not None:
            self.episodes.step(rewards, dones)
        return self._obs(obs), rewards, dones.long(), extras
