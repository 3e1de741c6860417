"""The ceiling of an episode's speed: the same robot in the same scene, stepped with physics and the
walker only (no camera, no localization, no mapping, no planning) for the same simulated time.

A navigation episode's simulated/wall ratio (``EpisodeResult.sim_to_wall``) divided by this
ceiling's, measured in the same process right after it, is the share of the wall time the loop
leaves to the walking itself: 1 would mean perception and planning cost nothing.

- **The same world**: ``NavWorld.from_apartment`` with the episode's start pose and world config
  (randomization included), but without the gyro recording (a sensor: the VO's input).
- **Walking without a plan**: the policy walker turns on the spot (``PolicyWalker.scan``), so the
  policy runs its stepping gait every control period and the feet make and break contact, as when
  it walks, without walking into a wall; a walker without ``scan`` (the ZMP walker) stands.
- **Timed as an episode is** (``metrics.run_episode``): from building the world to the last step.
"""

from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np

from ..robots import humanoid
from ..scenes.apartment import apartment
from .metrics import EpisodeCfg
from .walkers import PolicyWalker
from .world import NavWorld, NavWorldCfg


@dataclass
class CeilingResult:
    """One ceiling run."""

    time_s: float
    """Simulated time, s."""
    wall_s: float
    """Wall time from building the world to the last step, s."""
    turned_rad: float
    """Yaw change of the base from the first step to the last, wrapped to [-pi, pi], rad."""
    fell: bool

    @property
    def sim_to_wall(self) -> float:
        """Simulated seconds per wall-clock second."""
        return self.time_s / max(self.wall_s, 1e-9)


def physics_policy_ceiling(apartment_seed: int, episode_seed: int, sim_s: float, cfg: EpisodeCfg | None = None, *,
                           walker=None, scan_rate_rad_s: float = 0.4) -> CeilingResult:
    """Step ``apartment(apartment_seed)`` with the robot at the start of episode ``episode_seed``
    (``Apartment.sample_start_goal`` as ``run_episode`` draws it) for ``sim_s`` of simulated time,
    physics and walker only (module docstring). ``walker``: default a new ``PolicyWalker``."""
    cfg = cfg or EpisodeCfg()
    apt = apartment(apartment_seed)
    ep = apt.sample_start_goal(episode_seed, cfg.min_geodesic_m, cfg.max_geodesic_m, humanoid.BODY_RADIUS_M)
    t0 = time.perf_counter()
    world = NavWorld.from_apartment(apt, ep.start_pose, NavWorldCfg(**{**cfg.world.__dict__, "record_gyro": False}))
    try:
        walker = walker or PolicyWalker()
        walker.bind(world)
        walker.reset()
        world.engine.forward()
        world.reset_monitors()
        if hasattr(walker, "scan"):
            walker.scan(scan_rate_rad_s)
        else:
            walker.stand()
        pose = world.true_pose()  # a turn on the spot (or standing) steers on no pose
        t_start = world.time_s
        for _ in range(max(0, round(sim_s / world.dt_s))):
            walker.step(world.dt_s, pose)
            world.step()
        sim = world.time_s - t_start
        turned = float(np.angle(np.exp(1j * (world.true_pose()[2] - pose[2]))))
        fell = world.fell
    finally:
        world.close()
    return CeilingResult(time_s=sim, wall_s=time.perf_counter() - t0, turned_rad=turned, fell=fell)


__all__ = ["CeilingResult", "physics_policy_ceiling"]
