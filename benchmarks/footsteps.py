"""Footstep planner on seeded random rooms, every plan checked by an independent shapely checker.

    python benchmarks/footsteps.py [--maps 200] [--seed 0] [--budget-ms 100] [--png-dir DIR]

Each map is a 10 m x 10 m room (walls around it) with clutter: 2-4 walls 2-6 m long (two of them
across the way from start to goal) and 10-20 boxes of 0.2-0.8 m. A corridor 1.2 m wide (a
polyline from the start through 1-2 points near the straight line to the goal) is cut out of
every obstacle, so a plan exists by construction: walls get gaps (doors) where it crosses them,
boxes are cut back. Start and goal are 4-7 m apart, with random yaws.

The planner sees only the occupancy grid (5 cm cells, a cell is occupied when it touches an
obstacle polygon). The checker sees only the obstacle polygons and the limits of issue 14 (typed
below, not read from the planner) and shares no code with the planner: for every step it tests
sole rectangles against obstacles and the room, the step's length/width/yaw change and side, the
two soles apart, the swing and between-the-feet segments against obstacles, the body track's
clearance, and the final stance against the goal tolerance.

Prints success rate, planning time percentiles (p50/p95/max; the ``FootstepPlanner.plan`` call,
and separately the per-map preprocessing and the one-off lattice build), plan lengths, failure
reasons and checker violations, then one ``RESULT {json}`` line. ``ratio`` = p95 planning time of
the successful plans of up to 30 steps / the time budget (100 ms, the acceptance's limit; <= 1
meets it). Failed and partial plans are checked too (their steps, not the goal).
``--lattice-only`` turns the straight walks off, to measure the lattice search alone.
"""

from __future__ import annotations

import argparse
import json
import math
import time
from collections import Counter
from pathlib import Path

import numpy as np
import shapely
from shapely import affinity
from shapely.geometry import LineString, Point, Polygon, box
from shapely.ops import unary_union
from tqdm import tqdm

from ambulo.nav import FootstepPlanner, GridMap, PlanStatus, humanoid_footstep_cfg, plot_plan
from ambulo.nav.footstep_lattice import build_lattice

ROOM_M = 10.0
RESOLUTION_M = 0.05
CORRIDOR_HALF_WIDTH_M = 0.6
START_GOAL_M = (4.0, 7.0)
# the checker's limits: issue 14's numbers, typed here on purpose (not read from the planner)
STEP_LENGTH_M = (-0.10, 0.35)
STEP_WIDTH_M = (0.12, 0.30)
MAX_STEP_YAW_RAD = 0.3
FOOT_SIZE_M = (0.22, 0.10)
MIN_FOOT_GAP_M = 0.01
BODY_CLEARANCE_M = 0.25
GOAL_TOLERANCE_M = 0.10
GOAL_TOLERANCE_YAW_RAD = 0.20
EPS = 1e-6


# -- maps ------------------------------------------------------------------------------------
def random_room(rng: np.random.Generator) -> dict:
    """Obstacle polygons, start and goal body poses (x, y, yaw) and the corridor kept free."""
    while True:
        start_xy = rng.uniform(1.0, ROOM_M - 1.0, 2)
        goal_xy = rng.uniform(1.0, ROOM_M - 1.0, 2)
        if START_GOAL_M[0] <= np.linalg.norm(goal_xy - start_xy) <= START_GOAL_M[1]:
            break
    # the corridor bends through 1-2 points within 1.5 m of the straight line
    along = start_xy + np.sort(rng.uniform(0.25, 0.75, rng.integers(1, 3)))[:, None] * (goal_xy - start_xy)
    waypoints = np.clip(along + rng.uniform(-1.5, 1.5, along.shape), 0.8, ROOM_M - 0.8)
    corridor = LineString([start_xy, *waypoints, goal_xy]).buffer(CORRIDOR_HALF_WIDTH_M)
    t = 0.1  # room wall thickness, inside the map
    obstacles = [box(0, 0, ROOM_M, t), box(0, ROOM_M - t, ROOM_M, ROOM_M), box(0, 0, t, ROOM_M),
                 box(ROOM_M - t, 0, ROOM_M, ROOM_M)]
    direction = math.atan2(*(goal_xy - start_xy)[::-1])
    for k in range(rng.integers(2, 5)):
        length, thickness = rng.uniform(2.0, 6.0), rng.uniform(0.10, 0.20)
        if k < 2:  # across the way from start to goal: the corridor cuts its gap (a door)
            yaw = direction + math.pi / 2 + rng.uniform(-0.5, 0.5)
            center = start_xy + rng.uniform(0.3, 0.7) * (goal_xy - start_xy)
        else:
            yaw = rng.choice([0.0, math.pi / 2]) if rng.random() < 0.7 else rng.uniform(0, math.pi)
            center = rng.uniform(1.0, ROOM_M - 1.0, 2)
        wall = affinity.rotate(box(-length / 2, -thickness / 2, length / 2, thickness / 2), yaw, use_radians=True)
        obstacles.append(affinity.translate(wall, *center))
    for _ in range(rng.integers(10, 21)):
        sx, sy = rng.uniform(0.2, 0.8, 2)
        piece = affinity.rotate(box(-sx / 2, -sy / 2, sx / 2, sy / 2), rng.uniform(0, math.pi), use_radians=True)
        obstacles.append(affinity.translate(piece, *rng.uniform(0.5, ROOM_M - 0.5, 2)))
    kept = []
    for obstacle in obstacles:
        rest = obstacle.difference(corridor)
        kept.extend(g for g in getattr(rest, "geoms", [rest]) if isinstance(g, Polygon) and not g.is_empty)
    return dict(obstacles=kept, corridor=corridor,
                start=np.array([*start_xy, rng.uniform(-math.pi, math.pi)]),
                goal=np.array([*goal_xy, rng.uniform(-math.pi, math.pi)]))


def rasterize(obstacles: list[Polygon]) -> GridMap:
    """The occupancy grid: a cell is occupied when its closed square touches an obstacle."""
    n = round(ROOM_M / RESOLUTION_M)
    ix, iy = np.meshgrid(np.arange(n), np.arange(n), indexing="xy")
    cells = shapely.box(ix * RESOLUTION_M, iy * RESOLUTION_M, (ix + 1) * RESOLUTION_M, (iy + 1) * RESOLUTION_M)
    tree = shapely.STRtree(obstacles)
    hit_cells, _ = tree.query(cells.ravel(), predicate="intersects")
    occupied = np.zeros(n * n, bool)
    occupied[hit_cells] = True
    return GridMap.from_array(occupied.reshape(n, n), origin_xy_m=(0.0, 0.0), resolution_m=RESOLUTION_M)


# -- the independent checker ------------------------------------------------------------------
def sole_polygon(x: float, y: float, yaw: float) -> Polygon:
    half_l, half_w = FOOT_SIZE_M[0] / 2, FOOT_SIZE_M[1] / 2
    return affinity.translate(affinity.rotate(box(-half_l, -half_w, half_l, half_w), yaw, origin=(0, 0),
                                              use_radians=True), x, y)


def in_frame(pose, other) -> tuple[float, float, float]:
    """``other`` (x, y, yaw) seen from the frame ``pose``."""
    c, s = math.cos(pose[2]), math.sin(pose[2])
    dx, dy = other[0] - pose[0], other[1] - pose[1]
    dyaw = (other[2] - pose[2] + math.pi) % (2 * math.pi) - math.pi
    return c * dx + s * dy, -s * dx + c * dy, dyaw


def check_plan(footsteps: np.ndarray, sides: np.ndarray, obstacles: list[Polygon], goal=None, *,
               body_clearance_m: float = BODY_CLEARANCE_M) -> list[str]:
    """Every violation in a plan (rows: the two start feet, then the steps), as text; [] if none."""
    union = unary_union(obstacles)
    room = box(0, 0, ROOM_M, ROOM_M)
    soles = [sole_polygon(*pose) for pose in footsteps]
    problems = []
    for i, (pose, sole) in enumerate(zip(footsteps, soles)):
        if sole.intersects(union) or not room.contains(sole):
            problems.append(f"foot {i} touches an obstacle or leaves the room")
        if i == 0:
            continue
        dx, dy, dyaw = in_frame(footsteps[i - 1], pose)
        side = int(sides[i])
        if side != -int(sides[i - 1]) or side not in (-1, 1):
            problems.append(f"foot {i}: sides do not alternate")
        width = dy * side  # the swing foot is on its own side of the stance foot
        if not (STEP_LENGTH_M[0] - EPS <= dx <= STEP_LENGTH_M[1] + EPS):
            problems.append(f"step {i}: length {dx:.3f} m out of {STEP_LENGTH_M}")
        if not (STEP_WIDTH_M[0] - EPS <= width <= STEP_WIDTH_M[1] + EPS):
            problems.append(f"step {i}: width {width:.3f} m out of {STEP_WIDTH_M}")
        if abs(dyaw) > MAX_STEP_YAW_RAD + EPS:
            problems.append(f"step {i}: yaw change {dyaw:.3f} rad over {MAX_STEP_YAW_RAD}")
        if sole.distance(soles[i - 1]) < MIN_FOOT_GAP_M - EPS:
            problems.append(f"step {i}: soles closer than {MIN_FOOT_GAP_M} m")
        if LineString([footsteps[i - 1][:2], pose[:2]]).intersects(union):
            problems.append(f"step {i}: an obstacle between the feet")
        if i >= 2:
            if LineString([footsteps[i - 2][:2], pose[:2]]).intersects(union):
                problems.append(f"step {i}: the swing foot passes over an obstacle")
            mid_before = (footsteps[i - 2][:2] + footsteps[i - 1][:2]) / 2
            mid_after = (footsteps[i - 1][:2] + pose[:2]) / 2
            if LineString([mid_before, mid_after]).distance(union) < body_clearance_m - EPS:
                problems.append(f"step {i}: body track closer than {body_clearance_m} m to an obstacle")
    if goal is not None:
        a, b = footsteps[-2], footsteps[-1]
        mid = (a[:2] + b[:2]) / 2
        mean_yaw = a[2] + ((b[2] - a[2] + math.pi) % (2 * math.pi) - math.pi) / 2
        yaw_err = abs((mean_yaw - goal[2] + math.pi) % (2 * math.pi) - math.pi)
        if Point(mid).distance(Point(goal[:2])) > GOAL_TOLERANCE_M + EPS or yaw_err > GOAL_TOLERANCE_YAW_RAD + EPS:
            problems.append("the final stance misses the goal")
    return problems


# -- run -------------------------------------------------------------------------------------
def percentiles_ms(values_s) -> dict:
    if len(values_s) == 0:
        return {"p50": None, "p95": None, "max": None}
    ms = np.asarray(values_s) * 1e3
    return {"p50": round(float(np.percentile(ms, 50)), 2), "p95": round(float(np.percentile(ms, 95)), 2),
            "max": round(float(ms.max()), 2)}


def main(argv=None) -> dict:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--maps", type=int, default=200)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--budget-ms", type=float, default=100.0)
    parser.add_argument("--png-dir", type=Path, default=None, help="write a picture of each failed plan (and the first 5)")
    parser.add_argument("--lattice-only", action="store_true",
                        help="no straight walks along the body path: lattice steps only (an ablation)")
    args = parser.parse_args(argv)
    cfg = humanoid_footstep_cfg(time_budget_s=args.budget_ms / 1e3, walk_along_body_path=not args.lattice_only)
    t0 = time.perf_counter()
    build_lattice(cfg, RESOLUTION_M)  # once per process and config: kept out of the per-map times
    lattice_ms = (time.perf_counter() - t0) * 1e3
    rng = np.random.default_rng(args.seed)
    rows = []
    for index in tqdm(range(args.maps), desc="maps", leave=False):
        room = random_room(rng)
        grid = rasterize(room["obstacles"])
        t0 = time.perf_counter()
        planner = FootstepPlanner(grid, cfg)
        prep_s = time.perf_counter() - t0
        plan = planner.plan(room["start"], room["goal"])
        ok = plan.status is PlanStatus.SUCCESS
        problems = check_plan(plan.footsteps_xyyaw_w, plan.foot_sides, room["obstacles"], room["goal"] if ok else None)
        rows.append(dict(status=plan.status.value, steps=plan.num_steps, plan_s=plan.planning_time_s, prep_s=prep_s,
                         expansions=plan.expansions, problems=problems))
        if args.png_dir is not None and (not ok or problems or index < 5):
            args.png_dir.mkdir(parents=True, exist_ok=True)
            plot_plan(grid, plan, args.png_dir / f"map{index:03d}_{plan.status.value}.png", goal_xyyaw_w=room["goal"])
        if problems:
            print(f"map {index}: {len(problems)} checker violations, first: {problems[0]}")

    success = [r for r in rows if r["status"] == "success"]
    short = [r for r in success if r["steps"] <= 30]
    steps_checked = sum(r["steps"] + 2 for r in rows)
    bad_plans = sum(bool(r["problems"]) for r in rows)
    result = {
        "maps": len(rows),
        "success_rate": round(len(success) / len(rows), 4),
        "failures": dict(Counter(r["status"] for r in rows if r["status"] != "success")),
        "plan_ms": percentiles_ms([r["plan_s"] for r in rows]),
        "plan_ms_up_to_30_steps": percentiles_ms([r["plan_s"] for r in short]),
        "plans_up_to_30_steps": len(short),
        "prep_ms": percentiles_ms([r["prep_s"] for r in rows]),
        "steps": {"p50": int(np.median([r["steps"] for r in success])) if success else None,
                  "max": max((r["steps"] for r in success), default=None)},
        "expansions_p95": int(np.percentile([r["expansions"] for r in rows], 95)),
        "plans_with_lattice_expansions": sum(r["expansions"] > 0 for r in rows),
        "footsteps_checked": steps_checked,
        "plans_with_violations": bad_plans,
        "budget_ms": args.budget_ms,
        "lattice_only": args.lattice_only,
        "lattice_build_ms": round(lattice_ms, 1),
    }
    p95 = result["plan_ms_up_to_30_steps"]["p95"]
    result["ratio"] = round(p95 / args.budget_ms, 3) if p95 is not None else None
    print(f"success {len(success)}/{len(rows)} ({100 * result['success_rate']:.1f} %), failures {result['failures']}")
    print(f"plan time ms: all {result['plan_ms']}, plans <= 30 steps ({len(short)}) {result['plan_ms_up_to_30_steps']}")
    print(f"map preprocessing ms: {result['prep_ms']} (lattice, once: {lattice_ms:.0f} ms); steps {result['steps']}; "
          f"expansions p95 {result['expansions_p95']} ({result['plans_with_lattice_expansions']} plans expanded any)")
    print(f"independent checker: {steps_checked} footsteps in {len(rows)} plans, {bad_plans} plans with violations")
    print("RESULT " + json.dumps(result))
    return result


if __name__ == "__main__":
    main()
