"""Vectorized RL tasks: N envs stepped together as torch tensors, and their registry.

    env = ambulo.envs.make("humanoid-walk", num_envs=1024, device="cpu", seed=0)
    obs = env.reset()                                  # (N, env.num_obs) float32
    obs, rewards, dones, extras = env.step(actions)    # actions (N, env.num_actions)

``ambulo.envs.names()`` lists the tasks; ``GymVectorEnv`` adapts any of them to
``gymnasium.vector.VectorEnv``.
"""

from . import (  # noqa: F401  (each registers its task)
    cartpole,
    g1_rough,
    g1_walk,
    humanoid_footsteps,
    humanoid_footsteps_stairs,
    humanoid_rough,
    humanoid_walk,
    humanoid_walk_robust,
    jetbot_goal,
)
from .base import EnvCfg, RLEnv
from .ppo import PpoCfg
from .registry import Criterion, EvalBlocks, TaskSpec, make, make_cfg, names, register, registry, spec


def __getattr__(name: str):
    # gymnasium is an optional dependency (the "rl" extra): import it only when asked.
    if name == "GymVectorEnv":
        from .gym_vector import GymVectorEnv

        return GymVectorEnv
    raise AttributeError(f"module 'ambulo.envs' has no attribute {name!r}")


__all__ = [
    "Criterion",
    "EnvCfg",
    "EvalBlocks",
    "PpoCfg",
    "GymVectorEnv",
    "RLEnv",
    "TaskSpec",
    "make",
    "make_cfg",
    "names",
    "register",
    "registry",
    "spec",
]
