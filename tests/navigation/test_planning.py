"""Planning on a map that grows: the route treats unknown space as free, footsteps never touch it."""

import numpy as np

from ambulo.maps import FREE, OCCUPIED, UNKNOWN, Grid2D
from ambulo.navigation.planning import (
    FootstepStage,
    PlanningCfg,
    RoutePlanner,
    choose_subgoal,
    footstep_clearance,
)


def _corridor_map():
    """6 m x 3 m, 5 cm cells, all free, walls along y = 0 and y = 3; the east half (x > 3 m) is
    unknown except for nothing: a map that has seen only its west half."""
    occ = np.full((60, 120), FREE, np.int8)
    occ[:2, :] = OCCUPIED
    occ[-2:, :] = OCCUPIED
    occ[:, 60:] = np.where(occ[:, 60:] == OCCUPIED, OCCUPIED, UNKNOWN)
    return Grid2D(occupancy=occ, origin_xy_m=(0.0, 0.0), resolution_m=0.05)


def test_route_crosses_unknown_but_footsteps_stay_on_observed_free_cells():
    grid = _corridor_map()
    cfg = PlanningCfg(horizon_m=5.0)
    route = RoutePlanner(cfg).route(grid, 0, (0.5, 1.5), (5.5, 1.5))
    assert route.found and route.length_m > 4.9  # optimistic: straight through the unknown half
    assert (grid.cells_of(route.path_xy_m)[1] >= 60).any()
    clearance = footstep_clearance(grid, optimistic=False)
    k, final = choose_subgoal(route, clearance, grid, cfg)
    assert not final
    sub = route.path_xy_m[k]
    # the subgoal keeps the footstep clearance from the unknown half (x >= 3 m)
    assert sub[0] <= 3.0 - cfg.route_clearance_m + 0.05
    plan = FootstepStage(cfg).plan(grid, 0, False, (0.5, 1.5, 0.0), (sub[0], sub[1], 0.0))
    assert plan.status.value == "success" and plan.num_steps > 4
    # every sole's corners and centre lie on observed free cells
    half_l, half_w = 0.11, 0.05
    for x, y, yaw in plan.footsteps_xyyaw_w:
        c, s = np.cos(yaw), np.sin(yaw)
        pts = [(x + c * dx - s * dy, y + s * dx + c * dy) for dx in (-half_l, 0, half_l) for dy in (-half_w, 0, half_w)]
        iy, ix = grid.cells_of(np.array(pts))
        assert (grid.occupancy[iy, ix] == FREE).all(), (x, y)


def test_a_goal_in_unknown_space_is_never_a_footstep_goal():
    grid = _corridor_map()
    cfg = PlanningCfg(horizon_m=10.0)
    route = RoutePlanner(cfg).route(grid, 0, (0.5, 1.5), (5.5, 1.5))
    clearance = footstep_clearance(grid, optimistic=False)
    k, final = choose_subgoal(route, clearance, grid, cfg)
    assert not final and k < len(route.path_xy_m) - 1
    # once the east half is seen free, the goal itself is the subgoal (a final plan)
    seen = grid.occupancy.copy()
    seen[seen == UNKNOWN] = FREE
    grid2 = Grid2D(occupancy=seen, origin_xy_m=grid.origin_xy_m, resolution_m=grid.resolution_m)
    route2 = RoutePlanner(cfg).route(grid2, 1, (0.5, 1.5), (5.5, 1.5))
    k2, final2 = choose_subgoal(route2, footstep_clearance(grid2, optimistic=False), grid2, cfg)
    assert final2 and k2 == len(route2.path_xy_m) - 1


def test_route_keeps_its_clearance_and_reports_no_route():
    occ = np.full((60, 120), FREE, np.int8)
    occ[:, 58:62] = OCCUPIED  # a wall across the map with a 0.4 m gap: too narrow for 0.25 m clearance
    occ[30:38, 58:62] = FREE
    grid = Grid2D(occupancy=occ, origin_xy_m=(0.0, 0.0), resolution_m=0.05)
    route = RoutePlanner(PlanningCfg()).route(grid, 0, (1.0, 1.5), (5.0, 1.5))
    assert not route.found
    occ[26:42, 58:62] = FREE  # 0.8 m: a door
    grid = Grid2D(occupancy=occ, origin_xy_m=(0.0, 0.0), resolution_m=0.05)
    route = RoutePlanner(PlanningCfg()).route(grid, 1, (1.0, 1.5), (5.0, 1.5))
    assert route.found
    clr = footstep_clearance(grid, optimistic=True)
    iy, ix = grid.cells_of(route.path_xy_m[1:-1])
    assert clr[iy, ix].min() >= 0.25


def test_a_footstep_window_off_the_map_is_one_blocked_cell_not_the_far_side():
    """Robot and subgoal below and left of the map (a drifted estimate's turn on the spot): the clamped
    window is empty, and slicing with its negative end took rows from the map's far side."""
    grid = _corridor_map()
    stage = FootstepStage(PlanningCfg())
    window = stage._window(grid, grid.blocked(), np.array([-4.0, -4.0]), np.array([-4.0, -3.9]))
    assert window.occupied.shape == (1, 1) and window.occupied.all()
    plan = stage.plan(grid, 0, False, (-4.0, -4.0, 0.0), (-4.0, -3.9, 1.0))
    assert plan.status.value == "start_in_collision"


def test_a_goal_beside_a_wall_is_stood_on_a_little_away_from_it():
    """``roomy_goal``: a goal 0.3 m from the south wall moves up to ``shift_m`` away from it (to the
    cell with the most clearance, capped at ``room_m``); a goal with room stays where it is."""
    from ambulo.navigation.planning import roomy_goal

    grid = _corridor_map()
    clearance = footstep_clearance(grid, optimistic=True)
    near = np.array([1.5, 0.1 + 0.3])  # the wall's cells end at y = 0.1
    stance = roomy_goal(grid, clearance, near, room_m=0.35, shift_m=0.1)
    assert np.linalg.norm(stance - near) <= 0.1 + 1e-9
    assert stance[1] > near[1] + 0.04  # away from the wall
    iy, ix = grid.cell_of(stance)
    assert clearance[iy, ix] > clearance[grid.cell_of(near)]
    open_goal = np.array([1.5, 1.5])
    assert np.array_equal(roomy_goal(grid, clearance, open_goal, room_m=0.35, shift_m=0.1), open_goal)
