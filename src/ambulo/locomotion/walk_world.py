"""The walk arena started on the core: one ``core.Simulation`` of ``scenes.walk_arena`` and the
humanoid's ``core.Entity``, whose initial state is the robot file's ``home`` keyframe.

The keyframe enters once, through the Entity (``InitState.from_keyframe``, ``apply_init_state``):
it is what the engine's reset restores, and its configuration (``home_qpos``) seeds the walk's
inverse kinematics and holds the torso and arms. Physics advances only in the engine.
"""

from __future__ import annotations

from dataclasses import dataclass

import mujoco
import numpy as np

from ..core import Entity, Simulation
from ..core.entity import InitState
from ..engine import Engine
from ..robots import humanoid
from ..scenes.walk_arena import walk_arena, walk_physics

HOME_KEYFRAME = "home"
"""The humanoid file's standing pose (knees bent, soles on the floor): the walk's initial state."""


@dataclass
class WalkWorld:
    """A started walk arena."""

    sim: Simulation
    robot: Entity
    """The humanoid at ``robots.humanoid.PRIM_PATH``, started in its ``home`` keyframe."""
    home_qpos: np.ndarray
    """(nq,) the initial state's configuration (world 0): the keyframe as the robot stands in the arena."""

    @property
    def engine(self) -> Engine:
        return self.sim.engine

    @property
    def model(self) -> mujoco.MjModel:
        return self.sim.engine.model


def start_walk_world(*, friction: float = 1.0, timestep_s: float = 0.005, obstacles=(),
                     num_worlds: int = 1) -> WalkWorld:
    """``scenes.walk_arena(friction, obstacles)`` on the CPU engine with ``walk_physics(timestep_s)``,
    every world in the humanoid's ``home`` keyframe (the state ``sim.reset`` restores)."""
    spec, attached = walk_arena(friction=friction, obstacles=obstacles)
    sim = Simulation(spec, walk_physics(timestep_s), num_worlds=num_worlds, num_threads=1)
    engine = sim.start()
    robot = Entity(engine, humanoid.PRIM_PATH, init_state=InitState.from_keyframe(attached.keyframes[HOME_KEYFRAME]))
    robot.apply_init_state()
    return WalkWorld(sim=sim, robot=robot, home_qpos=engine.qpos[0].cpu().numpy().copy())


__all__ = ["HOME_KEYFRAME", "WalkWorld", "start_walk_world"]
