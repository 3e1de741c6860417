"""Leg-inertial odometry alone (``navigation.leg_odometry``) on policy walks: drift per metre walked.

    python benchmarks/leg_odometry.py [--seeds 200,201,202] [--stand-s 3.0] [--settle-s 1.0]

Each walk: ``apartment(seed)`` with the benchmark's start and goal (episode seed 0), the oracle
navigator (true pose, true map) walking it with the policy, and the leg odometry running alongside
from the start pose on the encoders and the noisy head gyro. The robot first stands ``--stand-s``
and the gyro's bias is the mean reading over that stand after ``--settle-s`` (an AHRS's start-up
calibration; the robot sways as it settles from its spawn pose at first); no VO
anchors anything, so the figures are the odometry's open-loop drift. Per walk: final position
error as % of the true distance walked, final |yaw error| in degrees per metre, and the largest
position error over any 3 m stretch (the navigator's bridge limit). The ceiling is 0 drift; the
RESULT gives the medians.
"""

from __future__ import annotations

import argparse
import json
import math
import time

import numpy as np

from ambulo.navigation.leg_odometry import LegOdometry
from ambulo.navigation.metrics import EpisodeCfg
from ambulo.navigation.navigator import Navigator, NavigatorCfg
from ambulo.navigation.world import NavWorld
from ambulo.robots import humanoid
from ambulo.scenes.apartment import apartment


def _wrap(a: float) -> float:
    return (a + math.pi) % (2 * math.pi) - math.pi


def walk(seed: int, stand_s: float, settle_s: float) -> dict:
    cfg = EpisodeCfg()
    apt = apartment(seed)
    ep = apt.sample_start_goal(0, cfg.min_geodesic_m, cfg.max_geodesic_m, humanoid.BODY_RADIUS_M)
    world = NavWorld.from_apartment(apt, ep.start_pose)
    nav = Navigator(world, NavigatorCfg(mode="oracle", time_limit_s=cfg.time_limit_base_s + 6 * ep.geodesic_m))
    readings = []
    while world.time_s < stand_s:
        nav.step()
        if world.time_s > settle_s:
            readings.append(world.gyro.latest()[1])
    legs = LegOdometry()
    legs.gyro_bias_rad_s = np.mean(readings, axis=0)
    legs.reset(world)
    nav.set_goal(ep.goal_xy_m)
    t0 = time.perf_counter()
    true_xy, est_xy, true_yaw, est_yaw = [], [], [], []
    while not nav.done:
        nav.step()
        legs.update()
        true = world.true_pose()
        true_xy.append(true[:2])
        est_xy.append(legs.xyyaw[:2])
        true_yaw.append(true[2])
        est_yaw.append(legs.xyyaw[2])
    wall_s = time.perf_counter() - t0
    world.close()
    true_xy, est_xy = np.array(true_xy), np.array(est_xy)
    walked = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(true_xy, axis=0), axis=1))])
    err = np.linalg.norm(est_xy - true_xy, axis=1)
    yaw_err = np.array([_wrap(a - b) for a, b in zip(est_yaw, true_yaw, strict=True)])
    # the worst 3 m stretch: the error gained between i and the first j >= 3 m further on, with the
    # start of the stretch aligned (what a bridge from a VO fix at i would have reached)
    worst3 = 0.0
    for i in range(0, len(walked), 20):
        j = int(np.searchsorted(walked, walked[i] + 3.0))
        if j >= len(walked):
            break
        c, s = math.cos(yaw_err[i]), math.sin(yaw_err[i])
        d_est = est_xy[j] - est_xy[i]
        d_est = np.array([c * d_est[0] + s * d_est[1], -s * d_est[0] + c * d_est[1]])  # undo the yaw error at i
        worst3 = max(worst3, float(np.linalg.norm(d_est - (true_xy[j] - true_xy[i]))))
    dist = float(walked[-1])
    return {"seed": seed, "status": nav.status, "walked_m": dist, "final_error_m": float(err[-1]),
            "drift_percent": 100 * float(err[-1]) / max(dist, 1e-9), "max_error_m": float(err.max()),
            "yaw_drift_deg_per_m": math.degrees(abs(yaw_err[-1])) / max(dist, 1e-9),
            "final_yaw_error_deg": math.degrees(float(yaw_err[-1])), "worst_3m_error_m": worst3,
            "stance_switches": legs.switches, "legs_distance_m": legs.distance_m, "wall_s": wall_s}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--seeds", default="200,201,202")
    ap.add_argument("--stand-s", type=float, default=3.0)
    ap.add_argument("--settle-s", type=float, default=1.0)
    args = ap.parse_args()
    rows = [walk(int(s), args.stand_s, args.settle_s) for s in args.seeds.split(",")]
    for r in rows:
        print(f"apt {r['seed']}: {r['status']:8s} walked {r['walked_m']:.2f} m, end error {r['final_error_m']:.3f} m "
              f"({r['drift_percent']:.2f} %), yaw {r['final_yaw_error_deg']:+.2f} deg "
              f"({r['yaw_drift_deg_per_m']:.2f} deg/m), worst 3 m stretch {r['worst_3m_error_m']:.3f} m")
    print("RESULT " + json.dumps({
        "benchmark": "leg_odometry", "walks": rows, "ceiling": "0 drift",
        "median_drift_percent": float(np.median([r["drift_percent"] for r in rows])),
        "median_yaw_drift_deg_per_m": float(np.median([r["yaw_drift_deg_per_m"] for r in rows])),
        "median_worst_3m_error_m": float(np.median([r["worst_3m_error_m"] for r in rows]))}))


if __name__ == "__main__":
    main()
