"""rl_games' ``RLGPU`` and ``ISAACGYM`` vecenv types for Isaac Gym env classes, during a run only.

IsaacGymEnvs registers ``RLGPU`` (``RLGPUEnv``) with rl_games so ``Runner().load(cfg);
runner.run({"train": True})`` trains an env registered in ``env_configurations`` with
``'vecenv_type': 'RLGPU'``; tutorials also write ``'ISAACGYM'``. Both names answer this adapter
while ``ambulo run`` runs a script (and are removed after, as nothing of Isaac's stays installed).

The adapter also serves env classes written for these tutorials that lack IsaacGymEnvs'
``observation_space``/``action_space``: the observation size is read from the first ``reset()``
and the action size from ``num_actions``, ``action_dim``, ``num_dof`` or ``num_dofs``, each a
float box of [-1, 1] (IsaacGymEnvs' own ``VecTask`` spaces are boxes of [-inf, inf] and [-1, 1]).
"""

from __future__ import annotations

import contextlib
import importlib.abc
import importlib.machinery
import sys
from collections.abc import Iterator

import numpy as np
import torch

VECENV_TYPES = ("RLGPU", "ISAACGYM")
_ACTION_COUNT_NAMES = ("num_actions", "action_dim", "num_dof", "num_dofs")


class RLGPUEnv:
    """An Isaac Gym env class as an rl_games vecenv (IsaacGymEnvs' ``RLGPUEnv`` contract)."""

    def __init__(self, config_name: str, num_actors: int, **kwargs):
        from rl_games.common import env_configurations

        self.env = env_configurations.configurations[config_name]["env_creator"](**kwargs)
        self._first_obs = None

    def step(self, actions):
        return self.env.step(actions)

    def reset(self):
        if self._first_obs is not None:  # get_env_info reset already: hand that episode start over
            obs, self._first_obs = self._first_obs, None
            return obs
        return self.env.reset()

    def reset_done(self):
        return self.env.reset_done()

    def get_number_of_agents(self) -> int:
        count = getattr(self.env, "get_number_of_agents", None)
        return count() if callable(count) else 1

    def has_action_masks(self) -> bool:
        return False

    def seed(self, seed) -> None:
        """Isaac Gym envs seed themselves (torch's global generator)."""

    def set_train_info(self, env_frames, *args, **kwargs) -> None:
        hook = getattr(self.env, "set_train_info", None)
        if callable(hook):
            hook(env_frames, *args, **kwargs)

    def get_env_state(self):
        return None

    def set_env_state(self, env_state) -> None:
        pass

    def get_env_info(self) -> dict:
        from rl_games.common.gym_compat import gym

        info = {}
        action_space = getattr(self.env, "action_space", None)
        if action_space is None:
            count = next((getattr(self.env, n) for n in _ACTION_COUNT_NAMES if isinstance(getattr(self.env, n, None), int)),
                         None)
            if count is None:
                raise AttributeError(f"rl_games: the env has no action_space nor any of {', '.join(_ACTION_COUNT_NAMES)}; "
                                     "give it action_space (a gym Box) or num_actions")
            action_space = gym.spaces.Box(np.full(count, -1.0, np.float32), np.full(count, 1.0, np.float32))
        observation_space = getattr(self.env, "observation_space", None)
        if observation_space is None:
            self._first_obs = self.env.reset()
            obs = self._first_obs["obs"] if isinstance(self._first_obs, dict) else self._first_obs
            size = int(torch.as_tensor(obs).shape[-1])
            observation_space = gym.spaces.Box(np.full(size, -np.inf, np.float32), np.full(size, np.inf, np.float32))
        info["action_space"] = action_space
        info["observation_space"] = observation_space
        if getattr(self.env, "num_states", 0) > 0:
            info["state_space"] = self.env.state_space
        return info


def _register(vecenv) -> dict:
    """Register the vecenv types on rl_games' ``vecenv`` module; return what they replaced."""
    saved = {name: vecenv.vecenv_config.get(name) for name in VECENV_TYPES}
    for name in VECENV_TYPES:
        vecenv.register(name, lambda config_name, num_actors, **kwargs: RLGPUEnv(config_name, num_actors, **kwargs))
    return saved


class _RegisterOnImport(importlib.abc.MetaPathFinder, importlib.abc.Loader):
    """Registers the vecenvs right after a script imports ``rl_games.common.vecenv`` (importing
    rl_games costs seconds, which a run whose script never uses it should not pay)."""

    def __init__(self):
        self.saved: dict | None = None
        self._loader = None

    def find_spec(self, fullname, path=None, target=None):
        if fullname != _VECENV_MODULE:
            return None
        spec = importlib.machinery.PathFinder.find_spec(fullname, path)
        if spec is None:
            return None
        self._loader, spec.loader = spec.loader, self
        return spec

    def create_module(self, spec):
        return self._loader.create_module(spec)

    def exec_module(self, module) -> None:
        self._loader.exec_module(module)
        self.saved = _register(module)


_VECENV_MODULE = "rl_games.common.vecenv"


@contextlib.contextmanager
def registered_vecenvs() -> Iterator[None]:
    """Inside the block, rl_games (once imported) knows the ``RLGPU`` and ``ISAACGYM`` vecenvs."""
    hook = _RegisterOnImport()
    if _VECENV_MODULE in sys.modules:
        hook.saved = _register(sys.modules[_VECENV_MODULE])
    else:
        sys.meta_path.insert(0, hook)
    try:
        yield
    finally:
        if hook in sys.meta_path:
            sys.meta_path.remove(hook)
        if hook.saved is not None and _VECENV_MODULE in sys.modules:
            config = sys.modules[_VECENV_MODULE].vecenv_config
            for name, previous in hook.saved.items():
                if previous is None:
                    config.pop(name, None)
                else:
                    config[name] = previous


__all__ = ["RLGPUEnv", "VECENV_TYPES", "registered_vecenvs"]
