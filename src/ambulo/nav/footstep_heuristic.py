"""The footstep planner's heuristic for one goal, and the body path its straight walks follow.

``steps_left`` is admissible: it never exceeds the number of steps a plan of lattice steps still
needs, so never the cost either (each step costs >= 1). It is the largest of three lower bounds.

* Geodesic. ``G`` is the 5-7 chamfer distance (``chamfer_distance_m``) through the body cells
  (``FootstepChecks``) from the cells within ``goal_tolerance_m`` (plus half a cell diagonal) of
  the goal, where the final midpoint lies. Per step the feet's midpoint moves along a straight
  segment of length <= D_swing / 2 (half the foot's swing) and every cell that segment crosses is
  a body cell (checked exactly). Those cells hold an 8-connected path of chamfer length
  <= 1.077 L + 2 r: ``CHAMFER_MAX_RATIO`` for the metric, 1.4 r for rounding both ends to their
  cells, 0.6 r for one unpaired side move (in the crossed cells of a segment whose slope is
  <= 1, side moves across rows never come two in a row, so each pairs with a column move into
  one diagonal move). Hence steps >= G(mid) / (1.077 D_swing / 2 + 2 r).
* Walking and turning. The midpoint must also advance, along the fixed direction u from it to
  the goal, by the straight-line distance D minus the tolerance. After n steps it has advanced by
  half the sum of the two feet's footstep chains, each bounded by ``progress_m`` from the feet's
  headings relative to u now and the heading the final stance must have (``progress_table``). The
  least such n, T, splits into D / rate (rate: the most a step advances facing u) and the turning
  extra T - D / rate; min(G bound, D / rate) + extra <= T is a lower bound too, and it keeps the
  geodesic's shape around obstacles.
* Yaw. The newest foot turns <= ``max_step_yaw_rad`` per step and the final mean yaw is within
  half a step's turn of it: steps >= (|yaw error| - yaw tolerance - dyaw_max / 2) / dyaw_max.

Cells that cannot reach the goal get G = inf; a start there is ``GOAL_UNREACHABLE`` at once.
The body path (``waypoint``) follows a second field, over the same cells less those near height
steps too high to take, with an entry cost near obstacles (``GUIDE_COST_CELLS``), so that the
straight walks along it keep some room. It only guides; it bounds nothing.
"""

from __future__ import annotations

import math

import numpy as np

from .footstep_checks import PAD, FootstepChecks
from .footstep_lattice import HEADING_BINS, wrap_angle
from .grid_map import CHAMFER_MAX_RATIO, chamfer_distance_m, crossed_cells

WAYPOINT_LOOKAHEAD_M = 3.0
"""How far along the body path ``waypoint`` looks for a point to walk to in a straight line."""


class GoalHeuristic:
    """Distance fields for one goal body pose (x m, y m, yaw rad; world frame)."""

    def __init__(self, checks: FootstepChecks, goal_xyyaw: np.ndarray):
        self.checks, self.cfg, self.lattice = checks, checks.cfg, checks.lattice
        self.goal = np.asarray(goal_xyyaw, float)
        grid, r = checks.grid, checks.grid.resolution_m
        goal_dist_m = np.hypot(*(grid.cell_centers_xy_m() - self.goal[:2]).transpose(2, 0, 1))
        seeds = goal_dist_m <= self.cfg.goal_tolerance_m + r / math.sqrt(2)
        dist = np.full(checks.shape_p, np.inf)
        dist[PAD:-PAD, PAD:-PAD] = chamfer_distance_m(checks.body_free, seeds, r)
        self.dist_m = dist.ravel()
        """Flat padded G, m (inf where the goal cannot be reached)."""
        self.mid_step_bound_m = CHAMFER_MAX_RATIO * self.lattice.max_swing_m / 2 + 2.0 * r
        self._seeds = seeds
        self._downhill: np.ndarray | None = None

    @property
    def downhill(self) -> np.ndarray:
        """Flat padded: each cell's neighbour one move down the guide field (itself at the goal);
        computed on first use."""
        if self._downhill is None:
            checks, r = self.checks, self.checks.grid.resolution_m
            guide = np.full(checks.shape_p, np.inf)
            guide[PAD:-PAD, PAD:-PAD] = chamfer_distance_m(checks.guide_free, self._seeds, r, checks.guide_cost)
            self._downhill = _downhill(guide, r)
        return self._downhill

    def reachable(self, x_m: float, y_m: float) -> bool:
        return bool(np.isfinite(self.dist_m[self.checks.cells(x_m, y_m)]))

    def is_goal(self, new_feet: np.ndarray, stance_foot: np.ndarray) -> np.ndarray:
        """(K,) bool: do ``new_feet`` (K, 3) beside ``stance_foot`` (3,) stand at the goal (midpoint
        and mean yaw within the tolerances)?"""
        mid = 0.5 * (new_feet[:, :2] + stance_foot[:2])
        mean_yaw = stance_foot[2] + 0.5 * wrap_angle(new_feet[:, 2] - stance_foot[2])
        return ((np.hypot(*(mid - self.goal[:2]).T) <= self.cfg.goal_tolerance_m)
                & (np.abs(wrap_angle(mean_yaw - self.goal[2])) <= self.cfg.goal_tolerance_yaw_rad))

    def steps_left(self, new_feet: np.ndarray, stance_foot: np.ndarray) -> np.ndarray:
        """(K,) lower bound on the steps still needed once footsteps ``new_feet`` (K, 3) stand
        beside ``stance_foot`` (3,), which moves next (module docstring)."""
        cfg, goal = self.cfg, self.goal
        mid_x, mid_y = 0.5 * (new_feet[:, 0] + stance_foot[0]), 0.5 * (new_feet[:, 1] + stance_foot[1])
        steps_geodesic = self.dist_m[self.checks.cells(mid_x, mid_y)] / self.mid_step_bound_m
        to_goal_x, to_goal_y = goal[0] - mid_x, goal[1] - mid_y
        reach_m = np.maximum(np.hypot(to_goal_x, to_goal_y) - cfg.goal_tolerance_m, 0.0)
        bearing = np.arctan2(to_goal_y, to_goal_x)
        final_err = np.maximum(np.abs(wrap_angle(goal[2] - bearing)) - cfg.goal_tolerance_yaw_rad
                               - cfg.max_step_yaw_rad / 2, 0.0)
        steps_line, steps_turning = self._steps_to_advance(
            reach_m, np.abs(wrap_angle(bearing - new_feet[:, 2])), np.abs(wrap_angle(bearing - stance_foot[2])),
            final_err)
        yaw_err = np.abs(wrap_angle(new_feet[:, 2] - goal[2]))
        steps_yaw = np.maximum(yaw_err - cfg.goal_tolerance_yaw_rad - cfg.max_step_yaw_rad / 2, 0.0) / cfg.max_step_yaw_rad
        return np.maximum(np.maximum(np.minimum(steps_geodesic, steps_line) + steps_turning, steps_geodesic),
                          steps_yaw)

    def _steps_to_advance(self, distance_m, err_new_rad, err_other_rad, err_final_rad):
        """(D / rate, turning extra), both (K,): see the module docstring. The feet's headings
        are ``err_new_rad`` and ``err_other_rad`` from the direction now, ``err_final_rad`` at the
        end (K,); beyond the table's steps every further step advances at most the full rate."""
        table = self.lattice.progress_m
        num_steps = table.shape[2] - 1
        scale = HEADING_BINS / np.pi
        final = np.floor(err_final_rad * scale + 1e-9).astype(np.intp)
        rows = 0.5 * (table[np.floor(err_new_rad * scale + 1e-9).astype(np.intp), final]
                      + table[np.floor(err_other_rad * scale + 1e-9).astype(np.intp), final])
        rate = table[0, 0, num_steps] - table[0, 0, num_steps - 1]
        steps = np.where(distance_m > rows[:, -1], num_steps + (distance_m - rows[:, -1]) / rate,
                         (rows < distance_m[:, None]).sum(axis=1))
        line = distance_m / rate
        return line, np.maximum(steps - line, 0.0)

    def waypoint(self, mid_xy) -> np.ndarray | None:
        """The farthest point, at most ``WAYPOINT_LOOKAHEAD_M`` down the body path from ``mid_xy``,
        that the midpoint can reach in a straight line through the body path's cells
        (``FootstepChecks.guide_free``); None if none is more than two cells away."""
        checks, r = self.checks, self.checks.grid.resolution_m
        cell = int(checks.cells(mid_xy[0], mid_xy[1]))
        path = [cell]
        for _ in range(round(WAYPOINT_LOOKAHEAD_M / r)):
            cell = int(self.downhill[cell])
            if cell == path[-1]:
                break
            path.append(cell)
        targets = checks.cell_center(np.array(path[2::3] + path[-1:]))  # candidates, the farthest last
        lengths = np.hypot(*(targets - mid_xy).T) / r
        if lengths.max() <= 2.0:
            return None
        (ox, oy) = checks.grid.origin_xy_m
        u, v = crossed_cells(np.full(len(targets), (mid_xy[0] - ox) / r), np.full(len(targets), (mid_xy[1] - oy) / r),
                             (targets[:, 0] - ox) / r, (targets[:, 1] - oy) / r, math.ceil(lengths.max()) + 1)
        seen = ~checks.guide_blocked[checks.cells(ox + u * r, oy + v * r)].any(axis=1)
        visible = np.flatnonzero(seen & (lengths > 2.0))
        return targets[visible[-1]] if visible.size else None


def _downhill(field: np.ndarray, resolution_m: float) -> np.ndarray:
    """Flat index of each cell's neighbour with the least (field + move length); the cell itself
    where the field is 0 (the goal) and on the border."""
    num_y, num_x = field.shape
    ids = np.arange(num_y * num_x).reshape(num_y, num_x)
    best = np.full((num_y - 2, num_x - 2), np.inf)
    downhill = ids.copy()
    for di in (-1, 0, 1):
        for dj in (-1, 0, 1):
            if di or dj:
                value = field[1 + di:num_y - 1 + di, 1 + dj:num_x - 1 + dj] + resolution_m * (1.4 if di and dj else 1.0)
                better = value < best
                best[better] = value[better]
                downhill[1:-1, 1:-1][better] = ids[1 + di:num_y - 1 + di, 1 + dj:num_x - 1 + dj][better]
    downhill[field == 0] = ids[field == 0]
    return downhill.ravel()
