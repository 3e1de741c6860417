"""play: roll a trained policy out headless and write an MP4 of env 0, or show it live.

Rendering goes through ``ambulo.render.OffscreenRenderer`` (headless EGL or OSMesa, no
shadows or multisampling: ~10x faster on a software rasterizer). With ``watch`` (``ambulo play
--viewer web``) nothing is rendered here: the web viewer draws the env in the browser.
"""

from __future__ import annotations

import os
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

import mujoco
import torch
from tqdm import tqdm

from ..render import OffscreenRenderer
from ..render.video import VideoError, VideoWriter
from . import runs


def _camera(env, distance_m: float = 3.0) -> mujoco.MjvCamera:
    """A camera on the task's robot: tracking a floating robot, else aimed at a fixed one."""
    camera = mujoco.MjvCamera()
    camera.distance, camera.elevation, camera.azimuth = distance_m, -20.0, 135.0
    robot = env.robot
    if robot.is_floating:
        camera.type = mujoco.mjtCamera.mjCAMERA_TRACKING
        camera.trackbodyid = robot.root_body_id
    else:  # a fixed-base robot: look at the middle of its bodies, from further away
        camera.type = mujoco.mjtCamera.mjCAMERA_FREE
        camera.lookat[:] = robot.data.body_pos_w[0].mean(dim=0).cpu().numpy()
        camera.distance, camera.azimuth = 1.5 * distance_m, 90.0
    return camera


def play(run: str | os.PathLike, *, checkpoint: str | os.PathLike | None = None,
         seconds: float = 10.0, out: str | os.PathLike | None = None, width: int = 640,
         height: int = 480, seed: int = 1, num_envs: int = 1,
         log_root: str | os.PathLike = "runs", device: str | None = None,
         watch: Callable[[Any], Any] | None = None) -> Path | None:
    """Run the policy of ``run`` for ``seconds`` and write ``<run>/videos/play.mp4`` (or ``out``).

    The task's play variant runs (no pushes, no observation noise, no time-out); env 0 is
    filmed, and a fall resets it, so falls and restarts are visible. ``device`` defaults to
    the run's.
    ``watch``: called with the env before the first step (``ambulo play --viewer web`` opens the
    web viewer on it, which paces the steps); the rollout is shown there instead of filmed (no
    MP4), and what ``watch`` returned is ``close()``d at the end.
    Returns the video's path (None with ``watch``).
    """
    run_dir, ckpt = runs.resolve_policy(run, checkpoint, log_root)
    path = None if watch is not None else Path(out) if out else run_dir / "videos" / "play.mp4"
    if path is not None:
        path.parent.mkdir(parents=True, exist_ok=True)  # an unwritable place fails before rendering
    info = runs.read_run_info(run_dir)
    env = runs.make_env_for_run(info, num_envs=num_envs, seed=seed, play=True, device=device)
    num_steps = max(1, round(seconds / env.step_dt_s))
    desc = f"play {info['task']}"
    try:
        runner = runs.load_runner(run_dir, env, ckpt)
        policy = runner.get_inference_policy(device=str(env.device))
        if watch is not None:
            watcher = watch(env)
            try:
                total_reward, episodes = 0.0, 0
                for reward, done in _rollout(runner, policy, num_steps, desc):
                    total_reward, episodes = total_reward + reward, episodes + done
            finally:
                watcher.close()
            print(f"played {num_steps} steps from {ckpt.name}; env 0 reward {total_reward:.2f}, "
                  f"{episodes} episode end(s)")
            return None
        total_reward, episodes, fps = _film(env, runner, policy, num_steps, desc, path, width, height)
    finally:
        env.close()
    print(f"{path}: {num_steps} frames at {fps} fps from {ckpt.name}; env 0 reward "
          f"{total_reward:.2f}, {episodes} episode end(s)")
    return path


def _rollout(runner, policy, num_steps: int, desc: str) -> Iterator[tuple[float, int]]:
    """Step the policy ``num_steps`` times; yields env 0's (reward, 1 if its episode ended)."""
    obs = runner.env.get_observations()
    for _ in tqdm(range(num_steps), desc=desc, unit="step"):
        with torch.inference_mode():
            actions = policy(obs)
        obs, rewards, dones, _ = runner.env.step(actions)
        yield float(rewards[0]), int(dones[0])


def _film(env, runner, policy, num_steps: int, desc: str, path: Path, width: int,
          height: int) -> tuple[float, int, int]:
    """The rollout with env 0 rendered into the MP4 ``path``; (env 0's reward, episode ends, fps)."""
    renderer = OffscreenRenderer(env.model, width, height)
    camera = _camera(env)
    fps = round(1.0 / env.step_dt_s)
    data = mujoco.MjData(env.model)
    total_reward, episodes = 0.0, 0
    try:
        with VideoWriter(path, fps=fps, quality=8) as writer:
            for reward, done in _rollout(runner, policy, num_steps, desc):
                total_reward, episodes = total_reward + reward, episodes + done
                env.engine.get_data(0, data)
                renderer.update_view(env.model, data, camera)
                writer.append(renderer.render_rgb())
    except VideoError as err:  # no ffmpeg, or ffmpeg failed without raising: say so rather than print success
        raise runs.RunError(err.problem, err.fix) from None
    finally:
        renderer.close()
    return total_reward, episodes, fps
