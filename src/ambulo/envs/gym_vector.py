"""GymVectorEnv: any ambulo task as a ``gymnasium.vector.VectorEnv`` (for SB3, skrl, CleanRL).

Observations, rewards and flags are numpy arrays. Finished envs reset in the same step
(``AutoresetMode.SAME_STEP``): the returned observation already starts the new episode and
``infos["final_obs"]`` holds the last observation of the one that ended, masked by
``infos["_final_obs"]``.
"""

from __future__ import annotations

from typing import Any

import gymnasium as gym
import numpy as np
import torch
from gymnasium.vector import AutoresetMode

from .base import RLEnv
from .registry import make


class GymVectorEnv(gym.vector.VectorEnv):
    """Adapter of an ``RLEnv`` (or a task name plus ``make`` arguments) to gymnasium.

    Args:
      env: an env, or a registered task name.
      **make_kwargs: passed to ``ambulo.envs.make`` when ``env`` is a name.
    """

    metadata = {"autoreset_mode": AutoresetMode.SAME_STEP, "render_modes": []}

    def __init__(self, env: RLEnv | str, **make_kwargs: Any):
        self.env = make(env, **make_kwargs) if isinstance(env, str) else env
        self.env.return_final_obs = True
        self.num_envs = self.env.num_envs
        bound = float(self.env.cfg.action_clip)
        self.single_observation_space = gym.spaces.Box(-np.inf, np.inf, (self.env.num_obs,),
                                                       np.float32)
        self.single_action_space = gym.spaces.Box(-bound, bound, (self.env.num_actions,),
                                                  np.float32)
        self.observation_space = gym.vector.utils.batch_space(self.single_observation_space,
                                                              self.num_envs)
        self.action_space = gym.vector.utils.batch_space(self.single_action_space, self.num_envs)

    def reset(self, *, seed: int | None = None,
              options: dict[str, Any] | None = None) -> tuple[np.ndarray, dict[str, Any]]:
        if seed is not None:
            self.env.generator.manual_seed(seed)
            self.action_space.seed(seed)
        obs = self.env.reset()
        return obs.cpu().numpy(), {}

    def step(self, actions: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray,
                                                 dict[str, Any]]:
        obs, rewards, dones, extras = self.env.step(torch.as_tensor(np.asarray(actions)))
        time_outs = extras["time_outs"].cpu().numpy()
        terminated = extras["terminated"].cpu().numpy()
        done = dones.cpu().numpy()
        infos: dict[str, Any] = {}
        if done.any():
            infos["final_obs"] = extras["final_obs"].cpu().numpy()
            infos["_final_obs"] = done
        return obs.cpu().numpy(), rewards.cpu().numpy(), terminated, time_outs, infos

    def close_extras(self, **kwargs: Any) -> None:
        self.env.close()


__all__ = ["GymVectorEnv"]
