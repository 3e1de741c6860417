"""Footstep planner: hand-checkable plans, the caller's start feet and stance foot, exact
clearance (a 0.60 m door), walks that turn while walking, failure reasons, the heuristic's bound,
the grid-map geometry against brute force, and the benchmark's independent shapely checker (also
run on a few benchmark maps)."""

import heapq
import math
from pathlib import Path

import numpy as np
import pytest

shapely = pytest.importorskip("shapely")
from shapely.geometry import LineString, box

from ambulo.maps import Grid2D
from ambulo.nav import FootstepPlanner, GridMap, PlanStatus, humanoid_footstep_cfg, plan_footsteps
from ambulo.nav.footstep_checks import FootstepChecks
from ambulo.nav.footstep_heuristic import GoalHeuristic
from ambulo.nav.footstep_lattice import LEFT, RIGHT, build_lattice, compose, relative, steps_within_limits
from ambulo.nav.grid_map import GridGraph, clearance_m, crossed_cells, near_occupied
from ambulo.utils.checks import InvalidValueError
from script_loader import load_script

ROOT = Path(__file__).resolve().parents[2]


BENCH = load_script(ROOT / "benchmarks" / "footstep_maps.py")


def corridor(length_m=6.0, width_m=2.0) -> GridMap:
    """A free strip with walls (one cell thick) along its long sides and ends."""
    grid = GridMap.empty((length_m, width_m), resolution_m=0.05)
    grid.occupied[[0, -1], :] = True
    grid.occupied[:, [0, -1]] = True
    return grid


def assert_valid(plan, grid, goal=None, body_clearance_m=0.25, **expect):
    """Every step passes the benchmark's shapely checker (which shares no planner code)."""
    blocked, extent = BENCH.blocked_geometry(Grid2D.from_masks(grid.occupied, origin_xy_m=grid.origin_xy_m,
                                                               resolution_m=grid.resolution_m))
    problems = BENCH.check_plan(plan.footsteps_xyyaw_w, plan.foot_sides, blocked, extent, goal=goal,
                                body_clearance_m=body_clearance_m, **expect)
    assert problems == [], problems[:5]


# -- hand-checkable plans ----------------------------------------------------------------------
def test_straight_corridor_walk_has_the_expected_steps():
    grid = corridor()
    plan = plan_footsteps(grid, (0.5, 1.0, 0.0), (4.0, 1.0, 0.0))
    assert plan.status is PlanStatus.SUCCESS
    # the walk along the body path: 3.5 m in 14 steps of 0.95 x 0.25 m and one of 0.175 m, then
    # the trailing foot steps beside the leading one; no turn, at the humanoid's 0.18 m stance
    assert plan.num_steps == 16
    rel = relative(plan.footsteps_xyyaw_w[1:-1], plan.footsteps_xyyaw_w[2:])
    np.testing.assert_allclose(rel[:14, 0], 0.2375, atol=1e-9)
    assert rel[14, 0] == pytest.approx(0.175) and rel[15, 0] == pytest.approx(0.0, abs=1e-9)
    np.testing.assert_allclose(np.abs(rel[:, 1]), 0.18, atol=1e-9)
    np.testing.assert_allclose(plan.footsteps_xyyaw_w[:, 2], 0.0, atol=1e-9)
    assert_valid(plan, grid, goal=np.array([4.0, 1.0, 0.0]))


def test_the_caller_chooses_the_start_feet_and_the_foot_that_stays_down():
    grid = corridor()
    # feet as they stand: the left 3 cm ahead and turned 0.05 rad in, not the nominal stance
    feet = np.array([[0.53, 1.09, -0.05], [0.50, 0.91, 0.0]])
    goal = np.array([3.0, 1.0, 0.0])
    for stance, first in ((LEFT, RIGHT), (RIGHT, LEFT), ("right", LEFT)):
        plan = FootstepPlanner(grid).plan(goal_xyyaw_w=goal, start_feet_xyyaw_w=feet, stance_side=stance)
        assert plan.status is PlanStatus.SUCCESS
        assert plan.foot_sides[0] == first and plan.foot_sides[2] == first  # the other foot moves first
        np.testing.assert_array_equal(plan.footsteps_xyyaw_w[:2], feet[[0, 1] if first == LEFT else [1, 0]])
        assert_valid(plan, grid, goal=goal, start_feet=feet, stance_side=-first)
    with pytest.raises(InvalidValueError, match="stance_side"):
        FootstepPlanner(grid).plan(goal_xyyaw_w=goal, start_feet_xyyaw_w=feet, stance_side=2)


def door_map(door_width_m: float) -> GridMap:
    """Two rooms (3 m x 3 m each) joined by one door in a 0.1 m wall at x = 3.0-3.1 m; the door's
    edges lie on cell lines, so the map's opening is exactly ``door_width_m``."""
    grid = GridMap.empty((6.1, 3.0), resolution_m=0.05)
    grid.occupied[[0, -1], :] = True
    grid.occupied[:, [0, -1]] = True
    grid.occupied[:, 60:62] = True
    lo = 30 - round(door_width_m / 0.05 / 2)
    grid.occupied[lo:lo + round(door_width_m / 0.05), 60:62] = False
    return grid


def test_a_door_the_body_fits_through_is_open_and_a_narrower_one_closed():
    # body clearance 0.25 m, measured to the cells' edges: a 0.60 m door leaves the midpoint a
    # channel of 0.10 m, a 0.55 m one 0.05 m; at 0.50 m only the door's centre line would do
    start, goal = (1.5, 1.2, 0.0), (4.6, 1.8, 0.0)
    for width in (0.60, 0.55):
        plan = FootstepPlanner(door_map(width)).plan(start, goal)
        assert plan.status is PlanStatus.SUCCESS, (width, plan.detail)
        assert_valid(plan, door_map(width), goal=np.array(goal))
    for width in (0.50, 0.45):
        assert FootstepPlanner(door_map(width)).plan(start, goal).status is PlanStatus.GOAL_UNREACHABLE


def test_walks_turn_while_walking_and_never_start_backwards():
    grid = GridMap.empty((6.0, 6.0), resolution_m=0.05)
    grid.occupied[[0, -1], :] = True
    grid.occupied[:, [0, -1]] = True
    # a goal ahead and 90 deg to the left: the body curves there; it turns on the spot only for
    # the goal's yaw at the end, and never steps back or turns away from the goal first
    start, goal = (1.0, 1.0, 0.0), (3.5, 4.0, math.pi / 2)
    plan = FootstepPlanner(grid).plan(start, goal)
    assert plan.status is PlanStatus.SUCCESS
    feet = plan.footsteps_xyyaw_w
    rel = relative(feet[1:-1], feet[2:])
    at_goal = np.hypot(*(feet[2:, :2] - feet[1:-1, :2]).T) < 0.2  # steps on the spot: the final turn, the closing step
    assert at_goal[-1] and at_goal.sum() <= 4 and np.all(rel[~at_goal, 0] > 0.05)
    turning = np.abs(rel[:, 2]) > 0.05
    assert np.all(rel[turning & ~at_goal, 0] > 0.1)  # every turn on the way is made while stepping ahead
    mids = (feet[1:, :2] + feet[:-1, :2]) / 2
    assert np.all(np.diff(np.hypot(*(mids - goal[:2]).T)) < 0.02)  # the body only closes in on the goal
    assert plan.num_steps <= 22
    assert_valid(plan, grid, goal=np.array(goal))


def serpentine_map() -> GridMap:
    """A 6 m x 3 m room with four walls across it, alternately from either side, gaps of 0.85 m."""
    grid = GridMap.empty((6.0, 3.0), resolution_m=0.05)
    grid.occupied[[0, -1], :] = True
    grid.occupied[:, [0, -1]] = True
    for k, x in enumerate((1.2, 2.4, 3.6, 4.8)):
        col = round(x / 0.05)
        if k % 2 == 0:
            grid.occupied[:60 - 18, col:col + 2] = True
        else:
            grid.occupied[18:, col:col + 2] = True
    return grid


def test_serpentines_and_corridors_are_planned_without_a_search_stall():
    # four U-turns around wall tips with a 0.35 m channel for the body: walks along the body path
    # and a few hundred lattice expansions at most (a deterministic budget, not a timing)
    grid = serpentine_map()
    goal = np.array([5.5, 1.5, 0.0])
    plan = FootstepPlanner(grid, humanoid_footstep_cfg(max_expansions=100, time_budget_s=30.0)).plan(
        (0.6, 1.5, -math.pi / 2), goal, stance_side=RIGHT)
    assert plan.status is PlanStatus.SUCCESS, plan.detail
    assert_valid(plan, grid, goal=goal)


@pytest.fixture(scope="module")
def optimal_corridor_plan():
    """A* (w = 1) on lattice steps without turns in a 3 m x 1.2 m corridor: (planner, plan)."""
    grid = corridor(length_m=3.0, width_m=1.2)
    cfg = humanoid_footstep_cfg(walk_along_body_path=False, heuristic_weight=1.0, time_budget_s=60.0,
                                step_yaws_rad=(0.0,))
    planner = FootstepPlanner(grid, cfg)
    return planner, planner.plan((0.6, 0.6, 0.0), (2.1, 0.6, 0.0))


def test_lattice_search_finds_the_fewest_steps(optimal_corridor_plan):
    # A* (w = 1) on lattice steps without turns: the midpoint starts 1.5 m short; after k steps of
    # 0.25 m it has advanced 0.25 k - 0.125 and must end within 0.1 m: ceil(1.525 / 0.25) = 7 steps
    grid = corridor(length_m=3.0, width_m=1.2)
    _, plan = optimal_corridor_plan
    assert plan.status is PlanStatus.SUCCESS
    assert plan.num_steps == 7
    assert_valid(plan, grid, goal=np.array([2.1, 0.6, 0.0]))


def test_heuristic_never_exceeds_the_steps_left_on_an_optimal_plan(optimal_corridor_plan):
    planner, plan = optimal_corridor_plan
    feet = plan.footsteps_xyyaw_w
    # rows i (newest) and i - 1 (moves next): plan.num_steps + 1 - i steps remain
    h = np.array([planner.heuristic.steps_left(feet[[i]], feet[i - 1])[0] for i in range(1, len(feet))])
    remaining = plan.num_steps + 1 - np.arange(1, len(feet))
    assert np.all(h <= remaining + 1e-9), (h, remaining)
    assert h[0] > 0.5 * remaining[0]  # and it is informative


def test_wall_forces_a_detour_through_its_gap():
    grid = GridMap.empty((6.0, 4.0), resolution_m=0.05)
    grid.add_box((3.0, 1.6), (0.2, 3.2))  # a wall from y = 0 to 3.2: the gap is y in (3.2, 4.0)
    start, goal = (1.0, 1.0, 0.0), (5.0, 1.0, 0.0)
    for walks in (True, False):
        cfg = humanoid_footstep_cfg(walk_along_body_path=walks, time_budget_s=5.0)
        plan = FootstepPlanner(grid, cfg).plan(start, goal)
        assert plan.status is PlanStatus.SUCCESS, (walks, plan.detail)
        feet = plan.footsteps_xyyaw_w
        mids = (feet[1:, :2] + feet[:-1, :2]) / 2
        at_wall = mids[np.abs(mids[:, 0] - 3.0) < 0.3]
        assert len(at_wall) and np.all(at_wall[:, 1] > 3.2)  # the body passes the wall in the gap
        assert plan.num_steps > 18  # more than the straight 4 m walk would take
        assert_valid(plan, grid, goal=np.array(goal))


def test_a_step_too_high_is_walked_around():
    grid = GridMap.empty((5.0, 3.0), resolution_m=0.05, with_height=True)
    grid.add_box((2.5, 1.0), (1.0, 2.0), height_m=0.3)  # a 0.3 m block, 2 m of the 3 m width
    plan = plan_footsteps(grid, (0.7, 1.0, 0.0), (4.3, 1.0, 0.0))
    assert plan.status is PlanStatus.SUCCESS
    assert np.all(plan.foot_z_m == 0.0)
    grid.height_m[grid.height_m > 0] = 0.1  # low enough to step on (max_step_up_m = 0.15)
    plan = plan_footsteps(grid, (0.7, 1.0, 0.0), (4.3, 1.0, 0.0))
    assert plan.status is PlanStatus.SUCCESS
    assert set(np.round(plan.foot_z_m, 6)) == {0.0, 0.1}
    assert np.all(np.abs(np.diff(plan.foot_z_m)) <= 0.15)


def test_small_obstacles_at_the_feet_are_stepped_around():
    # poles (one cell each) where the straight walk would put a sole, a heel and a swing: with
    # little body clearance only the foot and swing tests keep the feet off them
    grid = corridor()
    for x, y in ((1.773, 1.1), (2.62, 0.9), (2.727, 1.1)):
        grid.occupied[int(y / 0.05), int(x / 0.05)] = True
    goal = (4.0, 1.0, 0.0)
    for walks in (True, False):
        cfg = humanoid_footstep_cfg(body_clearance_m=0.02, walk_along_body_path=walks, time_budget_s=5.0)
        plan = FootstepPlanner(grid, cfg).plan((0.5, 1.0, 0.0), goal)
        assert plan.status is PlanStatus.SUCCESS, (walks, plan.detail)
        assert_valid(plan, grid, goal=np.array(goal), body_clearance_m=0.02)


def test_step_checks_are_conservative():
    # random steps near random clutter: whatever the vectorized test passes, shapely finds clear
    rng = np.random.default_rng(5)
    grid = GridMap.empty((4.0, 4.0), resolution_m=0.05)
    for _ in range(12):
        grid.add_box(rng.uniform(0.5, 3.5, 2), rng.uniform(0.03, 0.3, 2), rng.uniform(0, np.pi))
    cfg = humanoid_footstep_cfg(body_clearance_m=0.1)
    checks = FootstepChecks(grid, cfg, build_lattice(cfg, grid.resolution_m))
    n = 3000
    stance = np.column_stack([rng.uniform(0.5, 3.5, (n, 2)), rng.uniform(-np.pi, np.pi, n)])
    sides = rng.choice([LEFT, RIGHT], n)
    new = compose(stance, np.column_stack([rng.uniform(-0.1, 0.25, n), -sides * rng.uniform(0.12, 0.3, n),
                                           rng.uniform(-0.3, 0.3, n)]))
    prev = compose(stance, np.column_stack([rng.uniform(-0.35, 0.1, n), -sides * rng.uniform(0.12, 0.3, n),
                                            np.zeros(n)]))
    free, _ = checks.steps(prev[:, :2], stance, new)
    assert 0.2 < free.mean() < 0.9
    union, _ = BENCH.blocked_geometry(Grid2D.from_masks(grid.occupied, origin_xy_m=(0.0, 0.0), resolution_m=0.05))
    for k in np.flatnonzero(free):
        assert not BENCH.sole_polygon(*new[k]).intersects(union)
        assert not LineString([stance[k, :2], new[k, :2]]).intersects(union)
        assert not LineString([prev[k, :2], new[k, :2]]).intersects(union)
        body = LineString([(prev[k, :2] + stance[k, :2]) / 2, (new[k, :2] + stance[k, :2]) / 2])
        assert body.distance(union) >= 0.1 - 1e-9


def test_step_limits_are_the_walkers():
    from ambulo.robots import humanoid

    cfg = humanoid_footstep_cfg()
    assert cfg.step_length_range_m == humanoid.WALK_STEP_LENGTH_RANGE_M == (-0.10, 0.25)
    assert cfg.step_width_range_m == humanoid.WALK_STEP_WIDTH_RANGE_M
    assert cfg.max_step_yaw_rad == humanoid.WALK_MAX_STEP_YAW_RAD and cfg.start_width_m == humanoid.STANCE_WIDTH_M
    steps = np.array([[0.25, -0.2, 0.0], [0.26, -0.2, 0.0], [-0.10, -0.2, 0.0], [-0.11, -0.2, 0.0],
                      [0.2, -0.12, 0.0], [0.2, -0.11, 0.0], [0.2, -0.30, 0.0], [0.2, -0.31, 0.0],
                      [0.2, -0.2, 0.3], [0.2, -0.2, -0.31], [0.2, 0.2, 0.0], [0.0, -0.12, 0.3]])
    ok = steps_within_limits(steps, np.full(len(steps), LEFT), cfg)
    # the last: a 0.3 rad inward turn at the narrowest width puts the toe on the stance sole
    assert ok.tolist() == [True, False, True, False, True, False, True, False, True, False, False, False]
    mirrored = steps * np.array([1.0, -1.0, -1.0])
    assert steps_within_limits(mirrored, np.full(len(steps), RIGHT), cfg).tolist() == ok.tolist()


def test_goal_test_uses_the_mean_yaw_of_the_last_two_feet():
    grid = corridor()
    cfg = humanoid_footstep_cfg()
    checks = FootstepChecks(grid, cfg, build_lattice(cfg, grid.resolution_m))
    stance, new = np.array([2.0, 1.1, 0.0]), np.array([[2.05, 0.9, 0.3]])  # midpoint (2.025, 1.0), mean yaw 0.15
    assert GoalHeuristic(checks, np.array([2.0, 1.0, 0.15])).is_goal(new, stance)[0]
    assert GoalHeuristic(checks, np.array([2.0, 1.0, 0.34])).is_goal(new, stance)[0]
    assert not GoalHeuristic(checks, np.array([2.0, 1.0, -0.1])).is_goal(new, stance)[0]
    assert not GoalHeuristic(checks, np.array([2.0, 1.12, 0.15])).is_goal(new, stance)[0]
    across_pi = GoalHeuristic(checks, np.array([2.0, 1.0, np.pi]))
    assert across_pi.is_goal(np.array([[2.0, 0.9, -3.1]]), np.array([2.0, 1.1, 3.1]))[0]


def test_the_lattice_never_takes_a_step_too_high():
    # a 0.2 m step across the whole corridor (max_step_up_m = 0.15): no plan, and no partial plan
    # climbs it
    grid = GridMap.empty((4.0, 1.5), resolution_m=0.05, with_height=True)
    grid.add_box((3.0, 0.75), (2.0, 1.5), height_m=0.2)
    cfg = humanoid_footstep_cfg(walk_along_body_path=False, max_expansions=300)
    plan = FootstepPlanner(grid, cfg).plan((0.6, 0.75, 0.0), (3.0, 0.75, 0.0))
    assert plan.status is not PlanStatus.SUCCESS
    assert np.all(np.abs(np.diff(plan.foot_z_m)) <= 0.15)


# -- failures ------------------------------------------------------------------------------------
def test_failure_reasons():
    grid = GridMap.empty((6.0, 4.0), resolution_m=0.05)
    grid.add_box((1.0, 1.0), (0.3, 0.3))
    grid.add_box((5.0, 3.0), (0.3, 0.3))
    planner = FootstepPlanner(grid)
    start_blocked = planner.plan((1.0, 1.0, 0.0), (3.0, 2.0, 0.0))
    assert start_blocked.status is PlanStatus.START_IN_COLLISION and "touch an obstacle" in start_blocked.detail
    on_box = planner.plan((3.0, 2.0, 0.0), (5.0, 3.0, 0.0))
    assert on_box.status is PlanStatus.GOAL_IN_COLLISION and "touches an obstacle" in on_box.detail
    # a goal off the map (a typo, another frame) says so, with the map's span, not "an obstacle"
    off_map = planner.plan((3.0, 2.0, 0.0), (9.0, 2.0, 0.0))
    assert off_map.status is PlanStatus.GOAL_IN_COLLISION
    assert "off the map" in off_map.detail and "x 0..6 m, y 0..4 m" in off_map.detail
    off_start = planner.plan((-1.0, 2.0, 0.0), (3.0, 2.0, 0.0))
    assert off_start.status is PlanStatus.START_IN_COLLISION and "off the map" in off_start.detail
    # a goal inside a closed 1 m x 1 m room (x 2-3 m, y 2.5-3.5 m): known before any search
    grid.occupied[50:70, 40:42] = grid.occupied[50:70, 58:60] = True
    grid.occupied[50:52, 40:60] = grid.occupied[68:70, 40:60] = True
    plan = FootstepPlanner(grid).plan((1.0, 3.0, 0.0), (2.5, 3.0, 0.0))
    assert plan.status is PlanStatus.GOAL_UNREACHABLE and plan.expansions == 0 and "no path" in plan.detail
    assert plan.num_steps == 0


def test_budget_exhaustion_returns_a_partial_plan_closer_to_the_goal():
    grid = corridor(length_m=9.0, width_m=1.5)
    start, goal = np.array([0.6, 0.75, 0.0]), np.array([8.4, 0.75, 0.0])
    cfg = humanoid_footstep_cfg(walk_along_body_path=False, max_expansions=15)
    plan = FootstepPlanner(grid, cfg).plan(start, goal)
    assert plan.status is PlanStatus.BUDGET_EXHAUSTED and plan.expansions == 15
    assert plan.num_steps >= 3
    end_mid = plan.footsteps_xyyaw_w[-2:, :2].mean(axis=0)
    assert np.linalg.norm(end_mid - goal[:2]) < np.linalg.norm(start[:2] - goal[:2]) - 0.5
    assert_valid(plan, grid)
    timed = FootstepPlanner(grid, humanoid_footstep_cfg(walk_along_body_path=False)).plan(start, goal,
                                                                                         time_budget_s=0.02)
    assert timed.status is PlanStatus.BUDGET_EXHAUSTED and timed.planning_time_s < 0.2


def test_bad_settings_name_the_problem():
    with pytest.raises(InvalidValueError, match="step_lengths_m"):
        FootstepPlanner(corridor(), humanoid_footstep_cfg(step_lengths_m=(0.0, 0.5)))
    with pytest.raises(InvalidValueError, match="heuristic_weight"):
        FootstepPlanner(corridor(), humanoid_footstep_cfg(heuristic_weight=0.5))
    with pytest.raises(InvalidValueError, match="start_xyyaw_w"):
        FootstepPlanner(corridor()).plan((0.5, float("nan"), 0.0), (4.0, 1.0, 0.0))


# -- grid-map geometry against brute force ------------------------------------------------------
def test_grid_graph_distances_match_dijkstra():
    rng = np.random.default_rng(3)
    free = rng.random((25, 30)) > 0.25
    seeds = np.zeros_like(free)
    seeds[12, 15] = seeds[3, 4] = True
    got, nxt = GridGraph(free, 0.1).distances(seeds)
    ref = np.full(free.shape, np.inf)
    heap = [(0.0, (i, j)) for i, j in zip(*np.nonzero(seeds & free))]
    for _, (i, j) in heap:
        ref[i, j] = 0.0
    while heap:
        d, (i, j) = heapq.heappop(heap)
        if d > ref[i, j]:
            continue
        for di in (-1, 0, 1):
            for dj in (-1, 0, 1):
                a, b = i + di, j + dj
                if (di or dj) and 0 <= a < 25 and 0 <= b < 30 and free[a, b]:
                    nd = d + 0.1 * (math.sqrt(2.0) if di and dj else 1.0)
                    if nd < ref[a, b] - 1e-12:
                        ref[a, b] = nd
                        heapq.heappush(heap, (nd, (a, b)))
    np.testing.assert_allclose(got, ref, atol=1e-9)
    # the next cell of each reached cell is a neighbour one move closer
    i, j = np.nonzero(np.isfinite(got) & (got > 0))
    ni, nj = np.divmod(nxt[i, j], 30)
    assert np.all(np.maximum(np.abs(ni - i), np.abs(nj - j)) == 1)
    step = 0.1 * np.where((ni != i) & (nj != j), math.sqrt(2.0), 1.0)
    np.testing.assert_allclose(got[ni, nj] + step, got[i, j], atol=1e-9)


def test_clearance_is_the_exact_distance_between_cell_edges():
    rng = np.random.default_rng(8)
    blocked = rng.random((18, 22)) > 0.93
    got = clearance_m(blocked, 0.1)
    r = 0.1
    cells = [box(j * r, i * r, (j + 1) * r, (i + 1) * r) for i, j in zip(*np.nonzero(blocked))]
    outside = box(-1, -1, 3.2, 2.8).difference(box(0, 0, 2.2, 1.8))  # off the map counts as blocked
    union = shapely.union_all(cells + [outside])
    for i in range(18):
        for j in range(22):
            assert got[i, j] == pytest.approx(box(j * r, i * r, (j + 1) * r, (i + 1) * r).distance(union), abs=1e-9)


def test_crossed_cells_are_exactly_the_cells_a_segment_crosses():
    rng = np.random.default_rng(4)
    a = rng.uniform(0, 20, (60, 2))
    b = a + rng.normal(size=(60, 2)) * 3
    u, v = crossed_cells(a[:, 0], a[:, 1], b[:, 0], b[:, 1], 12)
    for k in range(60):
        got = set(zip(np.floor(u[k]).astype(int), np.floor(v[k]).astype(int)))
        segment = LineString([a[k], b[k]])
        lo, hi = np.floor(np.minimum(a[k], b[k])).astype(int) - 1, np.floor(np.maximum(a[k], b[k])).astype(int) + 1
        ref = {(i, j) for i in range(lo[0], hi[0] + 1) for j in range(lo[1], hi[1] + 1)
               if segment.intersection(box(i, j, i + 1, j + 1)).length > 1e-9}
        assert got == ref


def test_near_occupied_and_box_cells_are_conservative_and_exact():
    occupied = np.zeros((21, 21), bool)
    occupied[10, 10] = True
    r = 0.1
    for radius, centers in ((0.25, True), (0.25, False), (0.32, True)):
        got = near_occupied(occupied, r, radius, from_cell_centers=centers)
        cell = box(1.0, 1.0, 1.1, 1.1)
        for i in range(21):
            for j in range(21):
                probe = (box(j * r, i * r, (j + 1) * r, (i + 1) * r) if not centers
                         else box((j + 0.5) * r, (i + 0.5) * r, (j + 0.5) * r, (i + 0.5) * r))
                assert got[i, j] == (probe.distance(cell) < radius or (i, j) == (10, 10))
    grid = GridMap.empty((3.0, 3.0), resolution_m=0.1)
    cells = grid.box_cells((1.43, 1.61), (1.1, 0.37), yaw_rad=0.6)
    from shapely import affinity

    rect = affinity.translate(affinity.rotate(box(-0.55, -0.185, 0.55, 0.185), 0.6, use_radians=True), 1.43, 1.61)
    for i in range(30):
        for j in range(30):
            assert cells[i, j] == rect.intersects(box(j * 0.1, i * 0.1, (j + 1) * 0.1, (i + 1) * 0.1))


# -- the independent checker and the benchmark ---------------------------------------------------
def test_checker_catches_bad_steps():
    grid = corridor()
    goal = np.array([4.0, 1.0, 0.0])
    plan = plan_footsteps(grid, (0.5, 1.0, 0.0), goal)
    feet, sides = plan.footsteps_xyyaw_w.copy(), plan.foot_sides
    blocked, extent = BENCH.blocked_geometry(Grid2D.from_masks(grid.occupied, origin_xy_m=(0.0, 0.0),
                                                               resolution_m=0.05))
    assert BENCH.check_plan(feet, sides, blocked, extent, goal=goal) == []
    long_step = feet.copy()
    long_step[5:, 0] += 0.05  # step 5 becomes 0.2875 m long
    assert any("length" in p for p in BENCH.check_plan(long_step, sides, blocked, extent, goal=goal))
    into_wall = feet.copy()
    into_wall[6, 1] = 0.1  # a sole on the wall along y = 0
    problems = BENCH.check_plan(into_wall, sides, blocked, extent, goal=goal)
    assert any("touches" in p for p in problems) and any("width" in p for p in problems)
    assert any("body track" in p for p in BENCH.check_plan(feet, sides, blocked, extent, body_clearance_m=0.95))
    assert any("alternate" in p for p in BENCH.check_plan(feet, np.ones_like(sides), blocked, extent, goal=goal))
    assert any("misses the goal" in p for p in BENCH.check_plan(feet[:-3], sides[:-3], blocked, extent, goal=goal))
    moved = feet.copy()
    moved[0, 0] += 0.01
    assert any("start foot 0" in p for p in BENCH.check_plan(moved, sides, blocked, extent,
                                                             start_feet=feet[[1, 0]] if sides[0] < 0 else feet[:2]))
    assert any("stance" in p for p in BENCH.check_plan(feet, sides, blocked, extent, stance_side=-int(sides[1])))


def test_map_benchmark_short_version_every_claimed_success_passes_the_checker(tmp_path):
    pytest.importorskip("matplotlib")
    figure = tmp_path / "plans.png"
    result = BENCH.run(2, seed=11, verbose=False, figure=figure)  # 2 maps of each category
    assert figure.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert result["maps"] == 2 * len(BENCH.CATEGORIES)
    assert result["false_successes"] == 0 and result["plans_with_violations"] == 0
    assert result["valid_pct"] >= 90.0
    assert set(result["per_category"]) == set(BENCH.CATEGORIES)


def test_plot_plan_writes_a_png(tmp_path):
    pytest.importorskip("matplotlib")
    from ambulo.nav import plot_plan

    grid = corridor()
    plan = plan_footsteps(grid, (0.5, 1.0, 0.0), (4.0, 1.0, 0.0))
    plot_plan(grid, plan, tmp_path / "plan.png", goal_xyyaw_w=(4.0, 1.0, 0.0))
    assert (tmp_path / "plan.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_planner_reuses_its_buffers_between_queries():
    grid = corridor()
    planner = FootstepPlanner(grid, humanoid_footstep_cfg(walk_along_body_path=False))
    first = planner.plan((0.6, 1.0, 0.0), (2.5, 1.0, 0.0))
    assert not planner._state.any()  # the pruning record is cleared after each query
    second = planner.plan((0.6, 1.0, 0.0), (2.5, 1.0, 0.0))
    np.testing.assert_array_equal(first.footsteps_xyyaw_w, second.footsteps_xyyaw_w)
    assert math.isclose(first.cost, second.cost)


# -- the fast paths agree with the exact ones -----------------------------------------------------
def test_grid_graph_without_corner_cutting_and_with_costs_matches_dijkstra():
    # the guide graph's kind: diagonal moves only between two free side cells, each move's length
    # times 1 + the mean cost of its two cells
    rng = np.random.default_rng(5)
    free = rng.random((20, 24)) > 0.2
    cost = rng.uniform(0.0, 2.0, free.shape)
    seeds = np.zeros_like(free)
    seeds[10, 12] = seeds[2, 3] = True
    got, _ = GridGraph(free, 0.1, cost_per_m=cost, corner_cutting=False).distances(seeds)
    ref = np.full(free.shape, np.inf)
    heap = [(0.0, (i, j)) for i, j in zip(*np.nonzero(seeds & free))]
    for _, (i, j) in heap:
        ref[i, j] = 0.0
    while heap:
        d, (i, j) = heapq.heappop(heap)
        if d > ref[i, j]:
            continue
        for di in (-1, 0, 1):
            for dj in (-1, 0, 1):
                a, b = i + di, j + dj
                if not ((di or dj) and 0 <= a < 20 and 0 <= b < 24 and free[a, b]):
                    continue
                if di and dj and not (free[a, j] and free[i, b]):
                    continue
                nd = d + 0.1 * (math.sqrt(2.0) if di and dj else 1.0) * (1.0 + 0.5 * (cost[i, j] + cost[a, b]))
                if nd < ref[a, b] - 1e-12:
                    ref[a, b] = nd
                    heapq.heappush(heap, (nd, (a, b)))
    np.testing.assert_allclose(got, ref, atol=1e-9)


def test_the_walks_scalar_step_test_agrees_with_the_vectorized_one():
    # follow_path tests one step at a time in plain Python; it must accept exactly the steps the
    # lattice's array test accepts (limits, far side, soles apart)
    from ambulo.nav.footstep_lattice import step_within_limits

    cfg = humanoid_footstep_cfg()
    rng = np.random.default_rng(6)
    stance = np.column_stack([rng.uniform(-2, 2, (4000, 2)), rng.uniform(-np.pi, np.pi, 4000)])
    rel = np.column_stack([rng.uniform(-0.2, 0.35, 4000), rng.uniform(-0.4, 0.4, 4000), rng.uniform(-0.4, 0.4, 4000)])
    sides = rng.choice([LEFT, RIGHT], 4000)
    new = compose(stance, rel)
    want = steps_within_limits(relative(stance, new), sides, cfg)
    got = np.array([step_within_limits(a, b, int(s), cfg) for a, b, s in zip(stance, new, sides)])
    assert 200 < want.sum() < 3800  # both outcomes well represented
    np.testing.assert_array_equal(got, want)


def test_the_walks_body_track_test_is_exactly_the_crossed_cells():
    # a random map's body cells; segments of any length: blocked iff one crossed cell is not a body cell
    rng = np.random.default_rng(7)
    grid = GridMap.empty((3.0, 2.5), resolution_m=0.05, origin_xy_m=(-1.0, 0.5))
    for _ in range(6):
        grid.add_box(rng.uniform([-1, 0.5], [2, 3]), rng.uniform(0.05, 0.3, 2), rng.uniform(0, np.pi))
    cfg = humanoid_footstep_cfg()
    checks = FootstepChecks(grid, cfg, build_lattice(cfg, 0.05))
    assert 0.2 < checks.body_free.mean() < 0.9
    body = checks.body_free
    outcomes = []
    for _ in range(300):
        a = rng.uniform([-1.0, 0.5], [2.0, 3.0])
        b = a + rng.normal(size=2) * 0.4
        segment = LineString([a, b])
        (ox, oy), r = grid.origin_xy_m, grid.resolution_m
        lo = np.floor((np.minimum(a, b) - (ox, oy)) / r).astype(int) - 1
        hi = np.floor((np.maximum(a, b) - (ox, oy)) / r).astype(int) + 1
        blocked = any(segment.intersection(box(ox + j * r, oy + i * r, ox + (j + 1) * r, oy + (i + 1) * r)).length > 1e-9
                      and not (0 <= i < body.shape[0] and 0 <= j < body.shape[1] and body[i, j])
                      for i in range(lo[1], hi[1] + 1) for j in range(lo[0], hi[0] + 1))
        got = checks.body_segment_free(*a, *b)
        assert got == (not blocked), (a, b)
        outcomes.append(got)
    assert 30 < sum(outcomes) < 270


def plans_a_narrow_passage_within(seed: int, index: int, max_expansions: int) -> None:
    """Problem ``index`` of the footstep benchmark's narrow_passages category as drawn with ``seed`` is
    planned (valid footsteps) within ``max_expansions`` expansions (and 60 s: a budget, not a timing)."""
    rng = np.random.default_rng([seed, BENCH.CATEGORIES.index("narrow_passages")])
    problem = [BENCH.make_problem("narrow_passages", k, rng) for k in range(index + 1)][index]
    grid = GridMap.from_array(problem["occupied"], origin_xy_m=problem["origin_xy_m"], resolution_m=0.05)
    plan = FootstepPlanner(grid, humanoid_footstep_cfg(max_expansions=max_expansions, time_budget_s=60.0)).plan(
        goal_xyyaw_w=problem["goal"], start_feet_xyyaw_w=problem["start_feet"], stance_side=problem["stance_side"])
    assert plan.status is PlanStatus.SUCCESS, plan.detail
    assert 0 < plan.expansions <= max_expansions
    assert_valid(plan, grid, goal=problem["goal"], start_feet=problem["start_feet"],
                 stance_side=problem["stance_side"])


def test_a_bent_corridor_is_planned_with_few_expansions():
    # a benchmark corridor with two right-angle bends 0.65 m wide (the body's channel is 3 cells),
    # the robot facing away: the walk along the body path stalls in the bend and the lattice search
    # takes over; a heuristic weight of 8 gets through in tens of expansions where 3 spread over
    # every turn near the start (hundreds; a deterministic budget, not a timing)
    plans_a_narrow_passage_within(seed=0, index=2, max_expansions=150)


def test_progress_table_is_the_sum_of_its_per_step_bounds():
    # the table by its definition (progress_table's docstring), brute force: the support of every
    # pair displacement on 257 angles, its envelope, and per chain the sum over the steps of u at
    # the heading bound max(b0 - k dyaw, bf - (n - k) dyaw, 0), rounded down to the grid
    from ambulo.nav.footstep_lattice import HEADING_BINS, TABLE_STEPS, _rotate, progress_table

    cfg = humanoid_footstep_cfg(step_lengths_m=(-0.1, 0.0, 0.12, 0.25), step_yaws_rad=(-0.3, 0.0, 0.3))
    left = build_lattice(cfg, 0.05).actions[LEFT]
    right = left * np.array([1.0, -1.0, -1.0])
    pairs = np.concatenate([(a[:, None, :2] + _rotate(b[None, :, :2], a[:, None, 2])).reshape(-1, 2)
                            for a, b in ((left, right), (right, left))])
    singles = np.concatenate([left[:, :2], right[:, :2]])
    angles = np.linspace(-np.pi, np.pi, 257)
    e = np.stack([np.cos(angles), np.sin(angles)])
    grid = np.linspace(0.0, np.pi, HEADING_BINS + 1)

    def envelope(points):
        support = (points @ e).max(axis=0) + np.hypot(*points.T).max() * (angles[1] - angles[0]) / 2
        return np.array([support[np.abs(angles) >= x - 1e-12].max() for x in grid])

    u = envelope(pairs) / 2
    odd = max(float((envelope(singles) - u).max()), 0.0)
    table = progress_table(left, cfg.max_step_yaw_rad)
    dyaw, step = cfg.max_step_yaw_rad, np.pi / HEADING_BINS
    rng = np.random.default_rng(9)
    for j0, jf, n in zip(rng.integers(0, HEADING_BINS + 1, 300), rng.integers(0, HEADING_BINS + 1, 300),
                         rng.integers(1, TABLE_STEPS + 1, 300)):
        heading = [max(grid[j0] - dyaw * k, grid[jf] - dyaw * (n - k), 0.0) for k in range(n)]
        want = sum(u[math.floor(h / step + 1e-9)] for h in heading) + odd
        assert table[j0, jf, n] == pytest.approx(want, abs=1e-12)


def test_a_replan_to_the_same_goal_reuses_the_goal_fields():
    # the distance fields depend on the map and the goal only: a second query to the same goal
    # from elsewhere reuses them (and plans as a fresh planner would); a new goal gets new ones
    grid = corridor()
    planner = FootstepPlanner(grid)
    goal = np.array([4.5, 1.0, 0.0])
    planner.plan((0.6, 1.0, 0.0), goal)
    fields = planner.heuristic
    again = planner.plan((1.5, 0.9, 0.3), goal)
    assert planner.heuristic is fields
    fresh = FootstepPlanner(grid).plan((1.5, 0.9, 0.3), goal)
    np.testing.assert_array_equal(again.footsteps_xyyaw_w, fresh.footsteps_xyyaw_w)
    planner.plan((1.5, 0.9, 0.3), (4.0, 1.0, 0.0))
    assert planner.heuristic is not fields and planner.heuristic.goal[0] == 4.0


def test_a_corridor_bending_away_from_the_goal_is_searched_along_the_corridor():
    # a benchmark corridor that turns down, away from a goal up and to the right: footsteps that
    # turn into it face away from the straight line to the goal. The weight multiplies only the
    # path part of the heuristic, not that turning bound, so the search goes down the corridor in
    # a handful of expansions (it took 1,531 when the weight multiplied both; a budget, not a timing)
    plans_a_narrow_passage_within(seed=3, index=12, max_expansions=100)
