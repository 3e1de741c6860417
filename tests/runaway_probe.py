"""The runaway probe of the terrain tasks' Warp tests: unit Gaussian actions, the fastest speed seen."""

import torch


def fastest_speed_under_noise(env, steps: int, seed: int = 0) -> float:
    """Step ``env`` ``steps`` times with unit Gaussian actions (PPO's first exploration, from a
    generator seeded ``seed``); the largest |qvel| (rad/s or m/s) any world reached."""
    generator = torch.Generator().manual_seed(seed)
    fastest = 0.0
    for _ in range(steps):
        env.step(torch.randn(env.num_envs, env.num_actions, generator=generator))
        fastest = max(fastest, env.engine.field("qvel").abs().max().item())
    return fastest
