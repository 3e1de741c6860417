"""What the viewer watches: an ``ambulo.sim.World`` or a vectorized ``ambulo.envs.RLEnv``.

Both hold a ``Simulation`` (``.sim``) whose components are updated after every physics step; the
viewer joins it as one, so it sees every step of any loop (a script, ``ambulo play``, a training
run) without that loop's cooperation. What differs is how a world is reset and how the velocity
command reaches the walking policy, and those run on the simulation thread (``apply``), never on
the browser's:

- a World is reset between two physics steps (a one-shot physics callback calling ``reset()``);
  its scripts read the page's command through ``WebViewer.velocity_command``;
- an env is reset through its own path (the watched env is timed out at this step), and a
  task with a ``VelocityCommand`` (``env.commands``) gets the page's command written into its
  command row, its resampling timer pushed out of reach, so the policy sees it as its command.
"""

from __future__ import annotations

import math

import mujoco
import numpy as np
import torch

from .camera import CameraPose, from_mjv_camera

RESET_CALLBACK = "ambulo.viewer.reset"
NEVER_RESAMPLE_S = 1e9
"""s, the resampling timer of a teleoperated env: the task never replaces the page's command."""


class WorldTarget:
    """An ``ambulo.sim.World``."""

    can_reset = True
    has_command = True  # its scripts may read it (the demo's walking humanoid does)

    def __init__(self, world):
        self.world = world
        self.sim = world.sim
        self.follow_default = False
        self.default_speed = 1.0  # a person watching a scene wants it at real time

    @property
    def num_worlds(self) -> int:
        return self.world.num_worlds

    def camera(self, model: mujoco.MjModel) -> CameraPose:
        """The World's viewport camera (``set_camera_view``): the page opens on the video's view."""
        return from_mjv_camera(self.world.viewport_camera, float(model.vis.global_.fovy))

    def extras(self, world: int) -> dict[str, torch.Tensor]:
        return {}

    def reset_world(self, world: int) -> None:
        """Reset the World (every copy: a World resets as one) before its next physics step."""
        target = self.world

        def reset_once(_dt_s: float) -> None:
            target.remove_physics_callback(RESET_CALLBACK)
            target.reset()

        if not target.physics_callback_exists(RESET_CALLBACK):
            target.add_physics_callback(RESET_CALLBACK, reset_once)

    def apply_command(self, world: int, command: np.ndarray) -> None:
        """Nothing to write: a World's scripts pull the command (``WebViewer.velocity_command``)."""


class EnvTarget:
    """A vectorized ``RLEnv`` (``ambulo.envs``)."""

    can_reset = True

    def __init__(self, env):
        self.env = env
        self.sim = env.sim
        self.follow_default = True
        self.default_speed = None  # training and evaluation run as fast as they can
        self._commands = getattr(env, "commands", None)

    @property
    def num_worlds(self) -> int:
        return self.env.num_envs

    def camera(self, model: mujoco.MjModel) -> CameraPose:
        """Behind and above the robot's start, at MuJoCo's default field of view."""
        return CameraPose(eye_w=(-2.5, -2.5, 1.8), target_w=(0.0, 0.0, 0.6),
                          fovy_rad=math.radians(float(model.vis.global_.fovy)))

    def extras(self, world: int) -> dict[str, torch.Tensor]:
        """The watched env's command (vx m/s, vy m/s, yaw rate rad/s) and its episode return so far."""
        rows = {"episode_return": self.env.episode_sums[world].sum().reshape(1)}
        if self._commands is not None:
            rows["command"] = self._commands.command[world]
        return rows

    def reset_world(self, world: int) -> None:
        """Time the env out at this step: the env resets it through its own path (stats, commands)."""
        self.env.episode_length_buf[world] = self.env.max_episode_length

    def apply_command(self, world: int, command: np.ndarray) -> None:
        """Make ``command`` the env's command until the page lets go (on the simulation thread)."""
        cmds = self._commands
        if cmds is None:
            return
        cmds.command[world] = torch.as_tensor(command, dtype=cmds.command.dtype).to(cmds.command.device)
        cmds.time_left_s[world] = NEVER_RESAMPLE_S
        cmds.is_heading[world] = False
        cmds.is_standing[world] = False

    @property
    def has_command(self) -> bool:
        return self._commands is not None


class SimTarget:
    """Any other owner of a ``Simulation`` (``.sim``), e.g. the navigator's ``NavWorld``: watched,
    paused and stepped from the page; its loop owns resets and commands."""

    can_reset = False
    has_command = False

    def __init__(self, owner):
        self.sim = owner.sim
        self.follow_default = True
        self.default_speed = 1.0

    @property
    def num_worlds(self) -> int:
        return self.sim.num_worlds

    camera = EnvTarget.camera

    def extras(self, world: int) -> dict[str, torch.Tensor]:
        return {}

    def reset_world(self, world: int) -> None:
        """Not offered (``can_reset``): the loop that owns the simulation decides when it resets."""

    def apply_command(self, world: int, command: np.ndarray) -> None:
        """Not offered (``has_command``)."""


def target_of(world_or_env):
    """The target for a World, an env or another owner of a ``Simulation``; a clear error otherwise."""
    sim = getattr(world_or_env, "sim", None)
    if sim is None or not hasattr(sim, "components"):
        raise TypeError(f"ambulo.viewer.serve watches an ambulo.sim.World, an ambulo.envs env or another owner of "
                        f"an ambulo.core.Simulation (.sim), not a {type(world_or_env).__name__}; pass world or env")
    if hasattr(world_or_env, "viewport_camera"):
        return WorldTarget(world_or_env)
    if hasattr(world_or_env, "episode_length_buf"):
        return EnvTarget(world_or_env)
    return SimTarget(world_or_env)
