"""evaluate: measure a trained policy over many complete episodes.

Each of ``num_episodes`` envs runs exactly one episode of ``episode_length_s`` with the
deterministic policy (the action mean). An episode *fails* when it ends by a termination
that is not a success (for humanoid-walk: a fall). For tasks with velocity commands the
mean absolute planar velocity error |v_cmd - v| (heading frame) and yaw rate error are
averaged over every policy step of every episode until it ends.
"""

from __future__ import annotations

import json
import os

import torch
from tqdm import tqdm

from . import runs

WALK_MAX_FALL_RATE = 0.05
WALK_MAX_VEL_ERROR_M_S = 0.2
"""Issue #4's bar for "walks": fall rate <= 5 % and velocity error <= 0.2 m/s."""


def evaluate(run: str | os.PathLike, *, checkpoint: str | os.PathLike | None = None,
             num_episodes: int = 100, episode_length_s: float | None = 20.0, seed: int = 12345,
             log_root: str | os.PathLike = "runs", quiet: bool = False) -> dict:
    """Evaluate ``run`` and return (and print) a dict of metrics; also written to
    ``<run>/eval.json``."""
    run_dir = runs.resolve_run(run, log_root)
    info = runs.read_run_info(run_dir)
    env = runs.make_env_for_run(info, num_envs=num_episodes, seed=seed,
                                episode_length_s=episode_length_s)
    runner, ckpt = runs.load_runner(run_dir, env, checkpoint)
    policy = runner.get_inference_policy(device=str(env.device))
    n, dev = env.num_envs, env.device
    running = torch.ones(n, dtype=torch.bool, device=dev)
    failed = torch.zeros(n, dtype=torch.bool, device=dev)
    succeeded = torch.zeros(n, dtype=torch.bool, device=dev)
    returns = torch.zeros(n, dtype=torch.float64, device=dev)
    lengths = torch.zeros(n, dtype=torch.float64, device=dev)
    tracks = hasattr(env, "velocity_tracking_error")
    lin_err_sum = torch.zeros(n, dtype=torch.float64, device=dev)
    yaw_err_sum = torch.zeros_like(lin_err_sum)
    obs = runner.env.reset()
    for _ in tqdm(range(env.max_episode_length), desc=f"eval {info['task']}", unit="step",
                  disable=quiet):
        with torch.inference_mode():
            actions = policy(obs)
        if tracks:  # error of the state the policy acted on, for envs still in their episode
            lin_err, yaw_err = env.velocity_tracking_error()
            lin_err_sum += lin_err * running
            yaw_err_sum += yaw_err * running
        obs, rewards, dones, extras = runner.env.step(actions)
        returns += rewards.double() * running
        lengths += running.double()
        ended = running & dones.bool()
        for name, mask in extras["terminations"].items():
            target = succeeded if name in env.success_terminations else failed
            target |= ended & mask
        failed |= ended & extras["terminated"] & ~succeeded
        running &= ~dones.bool()
        if not running.any():
            break

    steps = lengths.clamp(min=1.0)
    result = {
        "task": info["task"],
        "run": str(run_dir),
        "checkpoint": ckpt.name,
        "episodes": n,
        "episode_length_s": env.max_episode_length * env.step_dt_s,
        "fall_rate": float(failed.double().mean()),
        "success_rate": float(succeeded.double().mean()),
        "mean_return": float(returns.mean()),
        "mean_episode_length_s": float(lengths.mean() * env.step_dt_s),
    }
    if tracks:
        result["mean_abs_vel_error_m_s"] = float((lin_err_sum / steps).mean())
        result["mean_abs_yaw_rate_error_rad_s"] = float((yaw_err_sum / steps).mean())
        result["walks"] = (result["fall_rate"] <= WALK_MAX_FALL_RATE
                           and result["mean_abs_vel_error_m_s"] <= WALK_MAX_VEL_ERROR_M_S)
    runs.atomic_write_bytes(run_dir / "eval.json", json.dumps(result, indent=2).encode())
    if not quiet:
        print(json.dumps(result, indent=2))
    env.close()
    return result
