"""A VO whose world frame slips, with and without the map as witness (``navigation.relocalize``).

    python benchmarks/vo_slip.py [--seeds 201,203] [--slip 0.6,-0.4,5] [--at-s 5] [--map both|on|off]

Each episode: ``apartment(seed)`` with the benchmark's start and goal (episode seed 0, the
benchmark's world seed), full mode, the policy walker. From ``--at-s`` of simulated time on, every
pose the VO reports is moved by the planar motion ``--slip`` (dx m, dy m, dyaw deg about the world
origin): a VO that relocalised wrongly or restarted its map at a coasted pose, still TRACKING. The
legs disagree with it; without the map the gate refuses it until the bridge (3 m / 10 s) runs out
and the slipped pose is then taken (what apartments 26, 30 and 84 showed on 2026-11-28: 157-198
refused fixes, then 1.2-2.5 m of ATE); with the map (``LegVoLocalizer.bind_map``) the frame is
matched against the occupancy map built so far and the fix taken where the map puts it. Per
episode: status, success, ATE, the largest pose error after the slip, refused fixes and the map
checks' outcomes. The ceiling is the same episode without a slip (its ATE): ``--no-slip-too``.
"""

from __future__ import annotations

import argparse
import collections
import json
import math

import numpy as np

from ambulo.navigation.benchmark import EpisodeSpec, episode_cfg
from ambulo.navigation.localization import LegVoLocalizer
from ambulo.navigation.metrics import result_of
from ambulo.navigation.navigator import Navigator, NavigatorCfg
from ambulo.navigation.world import NavWorld
from ambulo.perception.vo.odometry import RgbdOdometry
from ambulo.robots import humanoid
from ambulo.scenes.apartment import apartment


class SlippingOdometry:
    """``RgbdOdometry`` whose reported poses are moved by ``slip`` (4, 4) from ``at_s`` on."""

    def __init__(self, world: NavWorld, vo_cfg, slip: np.ndarray | None, at_s: float):
        self.world, self.slip, self.at_s = world, slip, at_s
        self.vo = RgbdOdometry(world.camera.cfg.intrinsics_matrix(), vo_cfg, initial_pose_wc=world.camera_pose_wc(),
                               pose_cam_imu=world.pose_cam_imu())

    @property
    def gyro(self):
        """The odometry's gyro model (its bias estimate goes to the legs)."""
        return getattr(self.vo, "gyro", None)

    def track(self, rgb, depth, gyro=None, motion_cam=None):
        result = self.vo.track(rgb, depth, gyro=gyro, motion_cam=motion_cam)
        if self.slip is not None and self.world.time_s >= self.at_s:
            result.pose_wc = self.slip @ np.asarray(result.pose_wc, float)
        return result


def episode(seed: int, slip: np.ndarray | None, at_s: float, with_map: bool) -> dict:
    cfg = episode_cfg(EpisodeSpec(apartment_seed=seed, episode_seed=0, mode="full"))
    apt = apartment(seed)
    ep = apt.sample_start_goal(0, cfg.min_geodesic_m, cfg.max_geodesic_m, humanoid.BODY_RADIUS_M)
    world = NavWorld.from_apartment(apt, ep.start_pose, cfg.world)
    nav_cfg = NavigatorCfg(**{**cfg.navigator.__dict__,
                              "time_limit_s": cfg.time_limit_base_s + cfg.time_limit_per_m_s * ep.geodesic_m})
    odometry = SlippingOdometry(world, nav_cfg.vo.vo, slip, at_s)
    loc = LegVoLocalizer(nav_cfg.legs, nav_cfg.vo, odometry, bridge_max_m=nav_cfg.bridge_max_m,
                         bridge_max_s=nav_cfg.bridge_max_s)
    nav = Navigator(world, nav_cfg, localizer=loc)
    if with_map:
        loc.bind_map(lambda: nav.mapper.grid)
    errors = []
    nav.add_observer(lambda s: errors.append((s.time_s, float(np.linalg.norm(s.estimate.xyyaw[:2] - s.true_pose[:2])))),
                     images=False)
    nav.set_goal(ep.goal_xy_m)
    try:
        nav.run()
    finally:
        world.close()
    res = result_of(nav, geodesic_m=ep.geodesic_m, wall_s=0.0, apartment_seed=seed, episode_seed=0)
    after = [e for t, e in errors if t >= at_s]
    checks = collections.Counter(f"{why}:{outcome}" for _, why, outcome in loc.map_checks)
    return dict(seed=seed, slip=slip is not None, map=with_map, status=res.status, success=res.success, ate_m=res.ate_m,
                distance_to_goal_m=res.distance_to_goal_m, max_error_after_slip_m=max(after, default=0.0),
                rejected=loc.rejected, unverified=loc.unverified, map_checks=dict(checks))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--seeds", default="201,203")
    ap.add_argument("--slip", default="0.6,-0.4,5", help="dx m, dy m, dyaw deg")
    ap.add_argument("--at-s", type=float, default=5.0)
    ap.add_argument("--map", choices=("both", "on", "off"), default="both")
    ap.add_argument("--no-slip-too", action="store_true", help="also each episode without a slip (the ceiling)")
    a = ap.parse_args()
    dx, dy, dyaw = (float(v) for v in a.slip.split(","))
    slip = np.eye(4)
    c, s = math.cos(math.radians(dyaw)), math.sin(math.radians(dyaw))
    slip[:2, :2], slip[:2, 3] = [[c, -s], [s, c]], (dx, dy)
    maps = {"both": (False, True), "on": (True,), "off": (False,)}[a.map]
    rows = []
    for seed in (int(v) for v in a.seeds.split(",")):
        for with_map in maps:
            for sl in ((None, slip) if a.no_slip_too else (slip,)):
                rows.append(episode(seed, sl, a.at_s, with_map))
                print(json.dumps(rows[-1]), flush=True)
    summary = {}
    for with_map in maps:
        group = [r for r in rows if r["map"] == with_map and r["slip"]]
        summary["map" if with_map else "no_map"] = dict(
            episodes=len(group), success=float(np.mean([r["success"] for r in group])),
            median_max_error_after_slip_m=float(np.median([r["max_error_after_slip_m"] for r in group])))
    ceiling = [r["ate_m"] for r in rows if not r["slip"]]
    summary["ceiling_no_slip_median_ate_m"] = float(np.median(ceiling)) if ceiling else None
    print("RESULT " + json.dumps(dict(seeds=a.seeds, slip=a.slip, at_s=a.at_s, **summary, episodes=rows)))


if __name__ == "__main__":
    main()
