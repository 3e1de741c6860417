"""How the terrain curriculum treats robots that follow their commands exactly.

    python benchmarks/curriculum_demotions.py [--task humanoid-rough] [--episodes 20000] [--seed 0]

Draws the task's own velocity commands (``envs.commands.VelocityCommand``: resampling, yaw rates,
heading-controlled and standing envs) for ``--episodes`` episodes of the task's length, at the
start-of-training command scale (``curriculum_start_scale``) and at full ranges, and moves a
perfect tracker exactly as commanded (position integrated in the complex plane, independently of
the env's ``commanded_velocity_w``). For each, the share of episodes the curriculum's rules would
move up (farther than ``up_distance_fraction`` of a tile, or, by the command rule, covering
``up_command_fraction`` of an ask of at least ``up_min_command_m``) and down: by the rule in use (closer to
the start than ``down_command_fraction`` of the commanded displacement) and by the path-length rule
used until session 12 (|v| integrated). A perfect tracker should never move down.
Ends with one line ``RESULT {json}``.
"""

from __future__ import annotations

import argparse
import json

import torch

import ambulo.envs as envs
from ambulo.envs.commands import VelocityCommand
from ambulo.envs.humanoid_rough import commanded_velocity_w


def perfect_tracker(env, episodes: int, range_scale: float, seed: int) -> dict[str, torch.Tensor]:
    """(episodes,) tensors: ``distance`` from the start (m), commanded ``displacement`` and ``path`` (m)."""
    dt = env.step_dt_s
    commands = VelocityCommand(env.cfg.commands, episodes, torch.Generator().manual_seed(seed), torch.device("cpu"))
    commands.range_scale.fill_(range_scale)
    commands.resample(None)
    pos = torch.zeros(episodes, dtype=torch.complex128)  # x + iy
    yaw = torch.zeros(episodes, dtype=torch.float64)
    asked, path = torch.zeros(episodes, 2), torch.zeros(episodes)
    for _ in range(round(env.cfg.episode_length_s / dt)):
        commands.update(dt, yaw.float())
        c = commands.command.double()
        asked += commanded_velocity_w(commands.command, yaw.float()) * dt
        path += torch.linalg.vector_norm(commands.command[:, :2], dim=-1) * dt
        pos += torch.exp(1j * yaw) * torch.complex(c[:, 0], c[:, 1]) * dt
        yaw += c[:, 2] * dt
    return {"distance": pos.abs().float(), "displacement": torch.linalg.vector_norm(asked, dim=-1), "path": path}


def shares(env, tracked: dict[str, torch.Tensor]) -> dict[str, float]:
    distance = tracked["distance"]
    # the curriculum's own rules; the commanded displacement less 0.1 mm: the tracker's float64
    # path and the float32 commanded sum agree to rounding, not to the bit
    up, down_now = env.curriculum.moves(distance, tracked["displacement"] - 1e-4)
    _, down_path = env.curriculum.moves(distance, tracked["path"])
    return {"up": round(up.float().mean().item(), 4), "down": round(down_now.float().mean().item(), 4),
            "down_by_path_length": round(down_path.float().mean().item(), 4),
            "mean_distance_m": round(distance.mean().item(), 3), "mean_path_m": round(tracked["path"].mean().item(), 3)}


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--task", default="humanoid-rough")
    p.add_argument("--episodes", type=int, default=20000)
    p.add_argument("--seed", type=int, default=0)
    args = p.parse_args()
    env = envs.make(args.task, num_envs=1, device="cpu")
    result = {"benchmark": "curriculum_demotions", "task": args.task, "episodes": args.episodes,
              "episode_length_s": env.cfg.episode_length_s, "tile_size_m": env.curriculum.tile_size_m}
    for name, scale in (("start_of_training", env.cfg.curriculum_start_scale), ("full_ranges", 1.0)):
        result[name] = {"range_scale": scale, **shares(env, perfect_tracker(env, args.episodes, scale, args.seed))}
        print(f"{name} (command scale {scale}): {result[name]}", flush=True)
    print("RESULT " + json.dumps(result))


if __name__ == "__main__":
    main()
