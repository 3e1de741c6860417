"""Mirror-symmetry data augmentation for rsl-rl-lib's PPO (``--ppo-cfg symmetry=true``).

rsl-rl's ``Symmetry`` extension calls ``data_augmentation_func(env=, obs=, actions=)`` on every
mini-batch and trains on the originals and their mirror images together (the batch doubles). This
is that function for ambulo's walking tasks: the maps come from ``envs.symmetry.task_mirror`` of the
wrapped env, built once and kept on the wrapper.
"""

from __future__ import annotations

import torch
from tensordict import TensorDict

from ambulo.envs.symmetry import TaskMirror, task_mirror


def env_mirror(env) -> TaskMirror:
    """The ``TaskMirror`` of an ``RLEnv`` (or of the one an ``RslRlVecEnv`` wraps), built on first
    use and kept on the env."""
    task_env = getattr(env, "env", env)
    mirror = getattr(task_env, "_task_mirror", None)
    if mirror is None:
        mirror = task_mirror(task_env)
        task_env._task_mirror = mirror
    return mirror


def mirrored_obs(obs: TensorDict, mirror: TaskMirror) -> TensorDict:
    """``obs``'s groups reflected: ``policy`` by the actor's map, ``critic`` (the task's privileged
    observations) by the critic's; another group has no map and is refused."""
    groups = {}
    for key, value in obs.items():
        if key == "policy":
            reflect = mirror.policy
        elif key == "critic" and mirror.critic is not None:
            reflect = mirror.critic
        else:
            raise ValueError(f"symmetry: no mirror map for the observation group {key!r}")
        groups[key] = reflect(value)
    return TensorDict(groups, batch_size=obs.batch_size, device=obs.device)


def mirror_augmentation(env, obs: TensorDict | None = None, actions: torch.Tensor | None = None
                        ) -> tuple[TensorDict | None, torch.Tensor | None]:
    """``obs`` (B groups: ``policy``, and ``critic`` when the task has privileged observations)
    and ``actions`` (B, A), each followed by its mirror image: (2B, ...). Either may be None."""
    mirror = env_mirror(env)
    doubled = None if obs is None else torch.cat([obs, mirrored_obs(obs, mirror)])
    mirrored_actions = None if actions is None else torch.cat([actions, mirror.actions(actions)])
    return doubled, mirrored_actions


__all__ = ["env_mirror", "mirror_augmentation", "mirrored_obs"]
