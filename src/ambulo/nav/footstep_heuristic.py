"""The footstep planner's heuristic for one goal, and the body path its straight walks follow.

``steps_left`` is admissible: it never exceeds the number of steps a plan of lattice steps still
needs, so never the cost either (each step costs >= 1). It is the largest of three lower bounds.

* Geodesic. ``G`` is the length of the shortest 8-connected path (side moves r, diagonal moves
  sqrt(2) r; ``GridGraph``) through the body cells (``FootstepChecks``) from the cells within
  ``goal_tolerance_m`` (plus half a cell diagonal) of the goal, where the final midpoint lies. Per step the feet's midpoint moves along a straight
  segment of length <= D_swing / 2 (half the foot's swing) and every cell that segment crosses is
  a body cell (checked exactly). Those cells hold an 8-connected path of length
  <= 1.0824 L + 2 r: ``OCTILE_MAX_RATIO`` for the metric, sqrt(2) r for rounding both ends to
  their cells, (2 - sqrt(2)) r for one unpaired side move (in the crossed cells of a segment
  whose slope is <= 1, side moves across rows never come two in a row, so each pairs with a
  column move into one diagonal move). Hence steps >= G(mid) / (1.0824 D_swing / 2 + 2 r).
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
G is computed on first use: a plan that the walk along the body path finds needs none.
The body path (``path``) follows a second field, over the same cells less those near height
steps too high to take, with an inflation cost near obstacles (``GUIDE_COST_PER_M``), so that
the walks along it keep to the middle of corridors. It only guides; it bounds nothing.
"""

from __future__ import annotations

import math

import numpy as np

from .footstep_checks import PAD, FootstepChecks
from .footstep_lattice import HEADING_BINS, wrap_angle
from .grid_map import OCTILE_MAX_RATIO, crossed_cells

PULL_REACH = 80
"""Farthest a straight piece of the body path reaches, in path cells (about 4-5 m)."""
PULL_MARGIN_M = 0.15
"""Room beyond the body clearance that a straightened piece of the body path keeps where the
path it replaces did."""



class GoalHeuristic:
    """Distance fields for one goal body pose (x m, y m, yaw rad; world frame)."""

    def __init__(self, checks: FootstepChecks, goal_xyyaw: np.ndarray):
        self.checks, self.cfg, self.lattice = checks, checks.cfg, checks.lattice
        self.goal = np.asarray(goal_xyyaw, float)
        grid, r = checks.grid, checks.grid.resolution_m
        goal_dist_m = np.hypot(*(grid.cell_centers_xy_m() - self.goal[:2]).transpose(2, 0, 1))
        self._seeds = goal_dist_m <= self.cfg.goal_tolerance_m + r / math.sqrt(2)
        guide, nxt = checks.guide_graph.distances(self._seeds)
        self.guide_cost = np.full(checks.shape_p, np.inf)
        self.guide_cost[PAD:-PAD, PAD:-PAD] = guide
        self.guide_cost = self.guide_cost.ravel()
        """Flat padded cost to go along the body path (inf where it cannot reach the goal)."""
        self._next = nxt
        self.mid_step_bound_m = OCTILE_MAX_RATIO * self.lattice.max_swing_m / 2 + 2.0 * r
        self._dist_m: np.ndarray | None = None

    @property
    def dist_m(self) -> np.ndarray:
        """Flat padded G, m (inf where the goal cannot be reached); computed on first use."""
        if self._dist_m is None:
            dist = np.full(self.checks.shape_p, np.inf)
            dist[PAD:-PAD, PAD:-PAD] = self.checks.body_graph.distances(self._seeds)[0]
            self._dist_m = dist.ravel()
        return self._dist_m

    def path(self, mid_xy) -> np.ndarray | None:
        """(n, 2) world points of the body path from the cell of ``mid_xy`` to the goal: the point
        itself, the cell centres down the guide field, then the goal; None where the body path
        cannot reach the goal from there."""
        checks = self.checks
        (ox, oy), r = checks.grid.origin_xy_m, checks.grid.resolution_m
        iy, ix = math.floor((mid_xy[1] - oy) / r), math.floor((mid_xy[0] - ox) / r)
        num_y, num_x = checks.grid.shape
        if not (0 <= iy < num_y and 0 <= ix < num_x) or not np.isfinite(self.guide_cost[(iy + PAD) * checks.shape_p[1]
                                                                                         + ix + PAD]):
            return None
        cells = [iy * num_x + ix]
        nxt = self._next.ravel()
        while nxt[cells[-1]] >= 0:
            cells.append(int(nxt[cells[-1]]))
        rows, cols = np.divmod(np.array(cells), num_x)
        centers = np.stack([ox + (cols + 0.5) * r, oy + (rows + 0.5) * r], axis=1)
        return self._pull_string(np.concatenate([np.asarray(mid_xy, float)[None, :2], centers[1:], self.goal[None, :2]]))

    def _pull_string(self, points: np.ndarray) -> np.ndarray:
        """The corners of ``points`` (n, 2) a taut string keeps: from each kept point, the farthest
        later point (at most ``PULL_REACH`` on) that every point before it is seen from through
        body-path cells (``crossed_cells``), so straight stretches of the path are straight."""
        checks, r = self.checks, self.checks.grid.resolution_m
        (ox, oy) = checks.grid.origin_xy_m
        kept, k, n = [0], 0, len(points)
        clear = checks.clearance_flat
        while k < n - 1:
            cand = np.arange(k + 1, min(n, k + 1 + PULL_REACH))
            length = np.hypot(*(points[cand] - points[k]).T) / r
            u, v = crossed_cells((points[k, 0] - ox) / r, (points[k, 1] - oy) / r, (points[cand, 0] - ox) / r,
                                 (points[cand, 1] - oy) / r, math.ceil(length.max()) + 1)
            # a shortcut keeps as much room as the path it replaces has (up to PULL_MARGIN_M more
            # than the body needs), so a walk that cuts its corners a little still passes
            room = np.minimum.accumulate(clear[checks.cells(points[cand, 0], points[cand, 1])])
            need = np.minimum(room, self.cfg.body_clearance_m + PULL_MARGIN_M)
            crossed = checks.cells(ox + u * r, oy + v * r)
            seen = ~checks.guide_blocked[crossed].any(axis=1) & (clear[crossed].min(axis=1) >= need - 1e-9)
            seen[0] = True  # the next point is always reachable along the path itself
            k = int(cand[np.argmin(seen) - 1] if not seen.all() else cand[-1])
            kept.append(k)
        return points[kept]

    def reachable(self, x_m: float, y_m: float) -> bool:
        """Does a path of body cells join the point (x, y) (m, world) to the goal?"""
        cell = self.checks.cells(x_m, y_m)
        return bool(np.isfinite(self.guide_cost[cell]) or np.isfinite(self.dist_m[cell]))

    def is_goal(self, new_feet: np.ndarray, stance_foot: np.ndarray) -> np.ndarray:
        """(K,) bool: do ``new_feet`` (K, 3) beside ``stance_foot`` (3,) stand at the goal (midpoint
        and mean yaw within the tolerances)?"""
        mid = 0.5 * (new_feet[:, :2] + stance_foot[:2])
        mean_yaw = stance_foot[2] + 0.5 * wrap_angle(new_feet[:, 2] - stance_foot[2])
        return ((np.hypot(*(mid - self.goal[:2]).T) <= self.cfg.goal_tolerance_m)
                & (np.abs(wrap_angle(mean_yaw - self.goal[2])) <= self.cfg.goal_tolerance_yaw_rad))

    def steps_left(self, new_feet: np.ndarray, stance_foot: np.ndarray, *, split: bool = False):
        """(K,) lower bound on the steps still needed once footsteps ``new_feet`` (K, 3) stand
        beside ``stance_foot`` (3,), which moves next (module docstring). With ``split``: (that
        bound, its path part (K,): the larger of the geodesic and the yaw bound, without the
        turning towards the straight line to the goal), which the planner weights apart."""
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
        h = np.maximum(np.maximum(np.minimum(steps_geodesic, steps_line) + steps_turning, steps_geodesic), steps_yaw)
        if not split:
            return h
        return h, np.maximum(steps_geodesic, steps_yaw)

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
