"""play: roll a trained policy out headless and write an MP4 of env 0.

Rendering goes through ``ambulo.render.OffscreenRenderer`` (headless EGL or OSMesa, no
shadows or multisampling: ~10x faster on a software rasterizer).
"""

from __future__ import annotations

import os
from pathlib import Path

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
         log_root: str | os.PathLike = "runs", device: str | None = None) -> Path:
    """Run the policy of ``run`` for ``seconds`` and write ``<run>/videos/play.mp4`` (or ``out``).

    The task's play variant runs (no pushes, no observation noise, no time-out); env 0 is
    filmed, and a fall resets it, so falls and restarts are visible. ``device`` defaults to
    the run's.
    Returns the video's path.
    """
    run_dir, ckpt = runs.resolve_policy(run, checkpoint, log_root)
    path = Path(out) if out else run_dir / "videos" / "play.mp4"
    path.parent.mkdir(parents=True, exist_ok=True)  # an unwritable place fails before rendering
    info = runs.read_run_info(run_dir)
    env = runs.make_env_for_run(info, num_envs=num_envs, seed=seed, play=True, device=device)
    runner = runs.load_runner(run_dir, env, ckpt)
    policy = runner.get_inference_policy(device=str(env.device))
    renderer = OffscreenRenderer(env.model, width, height)
    camera = _camera(env)
    fps = round(1.0 / env.step_dt_s)
    num_steps = max(1, round(seconds / env.step_dt_s))
    data = mujoco.MjData(env.model)
    obs = runner.env.get_observations()
    total_reward, episodes = 0.0, 0
    try:
        with VideoWriter(path, fps=fps, quality=8) as writer:
            for _ in tqdm(range(num_steps), desc=f"play {info['task']}", unit="step"):
                with torch.inference_mode():
                    actions = policy(obs)
                obs, rewards, dones, _ = runner.env.step(actions)
                total_reward += float(rewards[0])
                episodes += int(dones[0])
                env.engine.get_data(0, data)
                renderer.update_view(env.model, data, camera)
                writer.append(renderer.render_rgb())
    except VideoError as err:  # no ffmpeg, or ffmpeg failed without raising: say so rather than print success
        raise runs.RunError(err.problem, err.fix) from None
    finally:
        renderer.close()
        env.close()
    print(f"{path}: {num_steps} frames at {fps} fps from {ckpt.name}; env 0 reward "
          f"{total_reward:.2f}, {episodes} episode end(s)")
    return path
