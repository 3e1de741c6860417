"""Episode metrics as embodied-navigation benchmarks define them (Anderson et al. 2018, *On
Evaluation of Embodied Navigation Agents*, arXiv:1807.06757), and ``run_episode``.

- **success**: the episode ended with the robot stopped (the navigator declared arrival after
  standing still) within ``goal_tolerance_m`` (0.3 m) of the goal by the *true* pose, not fallen,
  within the time limit;
- **SPL**: success x geodesic / max(path walked, geodesic), the geodesic being the shortest path
  that keeps the robot's clearance (``scenes.apartment``'s exact geodesic);
- **stuck**: some ``window_s`` (20 s) stretch in which the robot moved less than ``progress_m``
  (0.5 m) from where the stretch began, the goal not reached;
- **collisions**: contact events (``NavWorld``), **fell**: the pelvis dropped below its threshold;
- **ATE**: root-mean-square of |estimated - true| base position over the tracked frames (VO
  fixes; the VO starts at the true pose, so no alignment), m; the bridged frames' (leg odometry
  while the VO is lost) are scored apart (``bridged_ate_m``), and frames are counted per source;
- replan wall times (each replan's route + subgoal + footsteps) and their 95th percentile.
"""

from __future__ import annotations

import json
import math
import time
from dataclasses import asdict, dataclass, field

import numpy as np

from ..robots import humanoid
from ..scenes.apartment import apartment
from ..scenes.apartment_paths import path_length_m
from ..utils.validate import Checked
from .navigator import Navigator, NavigatorCfg
from .world import NavWorld, NavWorldCfg


def spl(success: bool, geodesic_m: float, walked_m: float) -> float:
    """Success weighted by (normalized inverse) path length."""
    if not success or not math.isfinite(geodesic_m):
        return 0.0
    return float(geodesic_m / max(walked_m, geodesic_m))


def is_stuck(times_s: np.ndarray, xy: np.ndarray, *, window_s: float = 20.0, progress_m: float = 0.5) -> bool:
    """Whether, in some stretch of ``window_s`` of the log (times (K,), positions (K, 2)), the
    robot never got ``progress_m`` away from where the stretch began."""
    t, p = np.asarray(times_s, float), np.asarray(xy, float).reshape(-1, 2)
    if len(t) == 0 or t[-1] - t[0] < window_s:
        return False
    for i in range(len(t)):
        j = int(np.searchsorted(t, t[i] + window_s, side="left"))
        if j >= len(t):
            break
        if np.linalg.norm(p[i:j + 1] - p[i], axis=1).max() < progress_m:
            return True
    return False


def succeeded(status: str, final_xy_m, goal_xy_m, *, fell: bool, tolerance_m: float = 0.3) -> bool:
    """The success rule: arrived (stopped), by the true pose within ``tolerance_m``, not fallen."""
    return (status == "arrived" and not fell
            and float(np.linalg.norm(np.asarray(final_xy_m, float) - np.asarray(goal_xy_m, float))) <= tolerance_m)


def p95(values) -> float:
    return float(np.percentile(values, 95)) if len(values) else 0.0


@dataclass
class EpisodeResult:
    """One episode's outcome (module docstring); ``to_json()`` writes it."""

    apartment_seed: int | None
    episode_seed: int | None
    mode: str
    walker: str
    randomized: bool
    start_pose: list[float]
    goal_xy_m: list[float]
    geodesic_m: float
    status: str
    """The navigator's ending: arrived, fell, stuck, timeout, lost_timeout, no_route."""
    success: bool
    spl: float
    distance_to_goal_m: float
    path_length_m: float
    fell: bool
    collisions: int
    collision_bodies: list[str]
    stuck: bool
    time_s: float
    """Simulated time of the episode, s."""
    wall_s: float
    sim_to_wall: float
    """Simulated seconds per wall-clock second."""
    replan_wall_s: list[float]
    replan_p95_s: float
    num_replans: int
    ate_m: float
    frames: int
    untracked_frames: int
    fused_while_untracked: int
    extras: dict = field(default_factory=dict)
    frames_by_source: dict = field(default_factory=dict)
    """Frames per pose source: "vo", "oracle", "legs" (a leg-odometry bridge), "none" (untracked)."""
    bridged_ate_m: float = 0.0
    """Root-mean-square |estimated - true| base position over the bridged frames, m (0: none)."""
    rejected_vo_frames: int = 0
    """VO fixes refused as outliers by the leg odometry's gate."""

    def to_json(self, indent: int | None = None) -> str:
        return json.dumps(asdict(self), indent=indent, default=float)


def result_of(nav: Navigator, *, geodesic_m: float, wall_s: float, apartment_seed=None, episode_seed=None) -> EpisodeResult:
    """Score a navigator's finished episode."""
    w = nav.world
    final = w.true_pose()[:2]
    walked = np.array(nav.walked_path_xy_m + [final]).reshape(-1, 2)
    times = np.array(nav.times_s + [w.time_s])
    ok = succeeded(nav.status, final, nav.goal_xy_m, fell=w.fell, tolerance_m=nav.cfg.goal_tolerance_m)
    length = path_length_m(walked)
    errors = np.asarray(nav.frame_errors_m)
    replans = [r.wall_s for r in nav.replans]
    sim_s = w.time_s - nav._start_time_s
    extras = {"replan_reasons": [r.reason for r in nav.replans],
              "footstep_statuses": [r.footstep_status for r in nav.replans],
              "refusals": [r.refused for r in nav.replans if r.refused],
              "replan_times_s": [round(r.time_s - nav._start_time_s, 3) for r in nav.replans],
              "collision_events": [{"time_s": round(t - nav._start_time_s, 3), "body": body, "robot": part}
                                   for (t, body), part in zip(w.collisions, w.collision_parts)],
              "pushes": len(w.randomizer.pushes),
              "frame_wall_s_median": float(np.median(nav.frame_wall_s)) if nav.frame_wall_s else 0.0}
    tilts = np.asarray(nav.floor_tilts_rad)
    if tilts.size:
        extras["floor_levelled_fraction"] = float(np.isfinite(tilts).mean())
        extras["floor_tilt_deg_median"] = float(np.degrees(np.nanmedian(tilts))) if np.isfinite(tilts).any() else 0.0
        extras["floor_tilt_deg_max"] = float(np.degrees(np.nanmax(tilts))) if np.isfinite(tilts).any() else 0.0
    refresh = getattr(nav.mapper, "refresh_wall_s", None)
    if refresh:
        extras["map_refresh_wall_s_median"] = float(np.median(refresh))
        extras["map_refresh_wall_s_max"] = float(np.max(refresh))
    return EpisodeResult(
        apartment_seed=apartment_seed, episode_seed=episode_seed, mode=nav.cfg.mode, walker=nav.walker.name,
        randomized=w.cfg.randomization.enabled, start_pose=list(w.start_pose),
        goal_xy_m=[float(v) for v in nav.goal_xy_m], geodesic_m=float(geodesic_m), status=nav.status, success=ok,
        spl=spl(ok, geodesic_m, length), distance_to_goal_m=float(np.linalg.norm(final - nav.goal_xy_m)),
        path_length_m=length, fell=w.fell, collisions=len(w.collisions), collision_bodies=[b for _, b in w.collisions],
        stuck=nav.status == "stuck" or (not ok and is_stuck(times, walked, window_s=nav.cfg.stuck_window_s,
                                                             progress_m=nav.cfg.stuck_progress_m)),
        time_s=sim_s, wall_s=wall_s, sim_to_wall=sim_s / max(wall_s, 1e-9), replan_wall_s=replans,
        replan_p95_s=p95(replans), num_replans=len(replans),
        ate_m=float(np.sqrt(np.mean(errors ** 2))) if errors.size else 0.0, frames=nav.frames,
        untracked_frames=nav.untracked_frames, fused_while_untracked=nav.fused_while_untracked, extras=extras,
        frames_by_source=dict(nav.frames_by_source),
        bridged_ate_m=float(np.sqrt(np.mean(np.square(nav.bridged_errors_m)))) if nav.bridged_errors_m else 0.0,
        rejected_vo_frames=int(getattr(nav.localizer, "rejected", 0)))


@dataclass(kw_only=True)
class EpisodeCfg(Checked):
    """One benchmark episode: the navigator, the world and how start and goal are drawn."""

    navigator: NavigatorCfg = field(default_factory=NavigatorCfg)
    world: NavWorldCfg = field(default_factory=NavWorldCfg)
    min_geodesic_m: float = 3.0
    max_geodesic_m: float = 8.0
    time_limit_base_s: float = 30.0
    time_limit_per_m_s: float = 6.0
    """The episode's time limit: base + this per metre of geodesic, s (0.5 m/s walking needs 2 s/m)."""


def episode_world_cfg(world: NavWorldCfg, mode: str) -> NavWorldCfg:
    """``world`` for an episode in ``mode``: the gyro is recorded only in full mode (the legs' and the
    VO's odometry read it; the other modes know the pose)."""
    if mode == "full" or not world.record_gyro:
        return world
    return NavWorldCfg(**{**world.__dict__, "record_gyro": False})


def run_episode(apartment_seed: int, episode_seed: int, cfg: EpisodeCfg | None = None, *, walker=None,
                observer=None) -> EpisodeResult:
    """Navigate in ``apartment(apartment_seed)`` from a start to a goal drawn with ``episode_seed``
    (``Apartment.sample_start_goal``, geodesic in [min, max] with the robot's clearance)."""
    cfg = cfg or EpisodeCfg()
    apt = apartment(apartment_seed)
    ep = apt.sample_start_goal(episode_seed, cfg.min_geodesic_m, cfg.max_geodesic_m, humanoid.BODY_RADIUS_M)
    t0 = time.perf_counter()
    world = NavWorld.from_apartment(apt, ep.start_pose, episode_world_cfg(cfg.world, cfg.navigator.mode))
    limit = cfg.time_limit_base_s + cfg.time_limit_per_m_s * ep.geodesic_m
    nav_cfg = NavigatorCfg(**{**cfg.navigator.__dict__, "time_limit_s": limit})
    nav = Navigator(world, nav_cfg, walker=walker)
    if observer is not None:
        nav.add_observer(observer)
    nav.set_goal(ep.goal_xy_m)
    try:
        nav.run()
    finally:
        world.close()
    return result_of(nav, geodesic_m=ep.geodesic_m, wall_s=time.perf_counter() - t0,
                     apartment_seed=apartment_seed, episode_seed=episode_seed)


__all__ = ["EpisodeCfg", "EpisodeResult", "episode_world_cfg", "is_stuck", "p95", "path_length_m", "result_of", "run_episode", "spl",
           "succeeded"]
