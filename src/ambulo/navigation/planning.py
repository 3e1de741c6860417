"""Planning on a map that grows: a route to the goal with unknown space optimistic, then footsteps
on observed free cells only, up to a subgoal on the route.

1. **Route** (``RoutePlanner``): Dijkstra from the goal over the 8-connected cells whose clearance
   (exact distance to the nearest occupied cell, ``nav.grid_map.clearance_m``) is at least
   ``route_clearance_m``, unknown cells counted free (optimistic: the unseen may be a door). A move
   costs its length times ``1 + inflation_gain * exp(-(clearance - r) / inflation_decay_m)``
   (Nav2's inflation in spirit): routes keep to the middle of doors and corridors. The search
   (scikit-image's compiled ``MCP_Geometric``, whose move cost is exactly that: length times the
   mean of the two cells' costs) stops once the cells around the robot are settled, so a replan
   pays for the part of the map nearer the goal than the robot, not for the whole map: on the
   recorded replans of a full-mode episode (apartment 200) 8 % of the map, 9 ms against 52 ms
   for the whole field (scipy's Dijkstra on a graph built per map version). The cost grid is built
   once per map version and goal.
2. **Subgoal** (``choose_subgoal``): the farthest route point within ``horizon_m`` of path length
   whose every route point before it lies in observed free space with the footstep clearance
   (unknown = blocked); the route's own end when that holds all the way (a final plan).
3. **Footsteps**: ``nav.FootstepPlanner`` on the map with unknown cells blocked, cropped to the
   window around the robot and the subgoal, from the robot's pose to the subgoal, its yaw the
   route's direction there.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass

import numpy as np
from skimage.graph import MCP_Geometric

from ..maps import Grid2D
from ..nav import FootstepPlan, FootstepPlanner, GridMap, humanoid_footstep_cfg
from ..nav.grid_map import clearance_m
from ..utils.validate import Checked


@dataclass(kw_only=True)
class PlanningCfg(Checked):
    route_clearance_m: float = 0.25
    """The route's cells keep this exact clearance from occupied cells (the footstep planner's
    ``body_clearance_m``; the humanoid's radius is 0.265 m, its shoulders' half width 0.24 m), m."""
    inflation_gain: float = 3.0
    inflation_decay_m: float = 0.15
    horizon_m: float = 3.0
    """Footsteps are planned this far along the route at most, m."""
    window_margin_m: float = 1.2
    """The footstep planner's map is the box around the robot and the subgoal grown by this, m."""
    footstep_max_expansions: int = 400
    """Budget of one footstep query in lattice expansions (``FootstepPlannerCfg.max_expansions``), no
    wall-time limit: an episode's decisions must not depend on the machine's speed or load (under
    the former 0.3 s wall-time budget, a benchmark episode replayed on another host took other
    decisions). 400 is about what 0.3 s bought on a 2-core VM; 6 of 4,700 replans of the last
    randomized benchmark ran out of it, most need none (the walk along the body path)."""
    goal_snap_m: float = 0.4
    """A goal (or start) cell without the route clearance moves to the nearest cell with it within this, m."""


@dataclass
class Route:
    """A route on the map, robot to goal."""

    path_xy_m: np.ndarray
    """(K, 2) cell centres from the robot's cell to the goal's, m."""
    length_m: float
    found: bool


class RoutePlanner:
    """Routes on one map version at a time (module docstring, step 1)."""

    def __init__(self, cfg: PlanningCfg):
        self.cfg = cfg
        self._key = None
        self._grid = self._free = self._search = self._goal_cell = None

    def _prepare(self, grid: Grid2D, version: int, goal_xy) -> None:
        key = (id(grid), version, tuple(np.round(goal_xy, 4)))
        if key == self._key and grid is self._grid:
            return
        c = self.cfg
        clr = footstep_clearance(grid, optimistic=True)
        free = clr >= c.route_clearance_m
        cost = grid.resolution_m * (1.0 + c.inflation_gain * np.exp(-(clr - c.route_clearance_m) / c.inflation_decay_m))
        # MCP_Geometric: a move costs its length in cells times the mean of its two cells' costs
        # (1 + inflation per m, times the cell size); inf cells are impassable; diagonal moves
        # between two free cells whatever the cells beside them hold (corner cutting)
        self._search = MCP_Geometric(np.where(free, cost, np.inf), fully_connected=True)
        self._goal_cell = _snap(grid, free, goal_xy, c.goal_snap_m)
        self._free, self._key, self._grid = free, key, grid

    def _settle(self, start_xy) -> tuple[tuple[int, int] | None, np.ndarray | None]:
        """Search from the goal until the free cells within ``goal_snap_m`` of the start are settled;
        (the start's cell if it is reachable, else the nearest reachable one within that radius,
        or None; the costs so far, inf where unreached)."""
        grid, free = self._grid, self._free
        if self._goal_cell is None:
            return None, None
        iy, ix = grid.cell_of(start_xy)
        ny, nx = grid.shape
        if 0 <= iy < ny and 0 <= ix < nx and free[iy, ix]:  # the usual case: the start's own cell
            costs, _ = self._search.find_costs([self._goal_cell], [(iy, ix)])
            if np.isfinite(costs[iy, ix]):
                return (iy, ix), costs
        near = _cells_near(grid, free, (iy, ix), self.cfg.goal_snap_m)
        if not len(near):
            return None, None
        costs, _ = self._search.find_costs([self._goal_cell], [tuple(c) for c in near])
        reached = near[np.isfinite(costs[near[:, 0], near[:, 1]])]
        return (None, costs) if not len(reached) else ((int(reached[0, 0]), int(reached[0, 1])), costs)

    def route(self, grid: Grid2D, version: int, start_xy, goal_xy) -> Route:
        """The route from ``start_xy`` to ``goal_xy`` on ``grid`` (whose contents are ``version``)."""
        self._prepare(grid, version, goal_xy)
        start, _ = self._settle(start_xy)
        if start is None:
            return Route(np.zeros((0, 2)), math.inf, False)
        cells = np.array(self._search.traceback(start)[::-1])  # start's cell first, the goal's last
        xs, ys = grid.cell_center_xy_m(cells[:, 0], cells[:, 1])
        path = np.stack([xs, ys], -1)
        path = np.concatenate([np.asarray(start_xy, float)[None, :2], path[1:] if len(path) > 1 else path,
                               np.asarray(goal_xy, float)[None, :2]])
        length = float(np.linalg.norm(np.diff(path, axis=0), axis=1).sum())
        return Route(path, length, True)


def _cells_near(grid: Grid2D, ok: np.ndarray, cell: tuple[int, int], radius_m: float) -> np.ndarray:
    """(K, 2) the ``ok`` cells within ``radius_m`` (centre to centre) of ``cell``, nearest first
    (ties in row-major order)."""
    iy, ix = cell
    k = int(math.ceil(radius_m / grid.resolution_m))
    ny, nx = grid.shape
    y0, y1, x0, x1 = max(0, iy - k), min(ny, iy + k + 1), max(0, ix - k), min(nx, ix + k + 1)
    if y0 >= y1 or x0 >= x1:
        return np.zeros((0, 2), np.int64)
    yy, xx = np.nonzero(ok[y0:y1, x0:x1])
    yy, xx = yy + y0, xx + x0
    d2 = (yy - iy) ** 2 + (xx - ix) ** 2
    keep = np.sqrt(d2) * grid.resolution_m <= radius_m
    order = np.argsort(d2[keep], kind="stable")
    return np.stack([yy[keep][order], xx[keep][order]], -1)


def _snap(grid: Grid2D, free: np.ndarray, xy, radius_m: float):
    """The cell of ``xy`` if free, else the nearest free cell within ``radius_m``, else None."""
    near = _cells_near(grid, free, grid.cell_of(xy), radius_m)
    return None if not len(near) else (int(near[0, 0]), int(near[0, 1]))


_CLEARANCE_CACHE: dict[bool, tuple[Grid2D, np.ndarray, np.ndarray]] = {}
"""Per ``optimistic``: the last grid, a copy of its occupancy and its clearance (read-only)."""


def footstep_clearance(grid: Grid2D, optimistic: bool) -> np.ndarray:
    """(num_y, num_x) exact clearance of each cell for footsteps, m (read-only): unknown cells are
    blocked unless ``optimistic`` (a map with no unknown cells, e.g. the ground truth). The last
    grid's is kept: a replan asks for it up to four times (route, subgoal, start snap, blocked
    plan), and a map that did not change between replans keeps its grid; a grid whose occupancy
    was changed in place is computed afresh (the copy is compared, ~10 us)."""
    hit = _CLEARANCE_CACHE.get(optimistic)
    if hit is not None and hit[0] is grid and np.array_equal(hit[1], grid.occupancy):
        return hit[2]
    blocked = grid.occupied() if optimistic else grid.blocked()
    clr = clearance_m(blocked, grid.resolution_m)
    clr.flags.writeable = False
    _CLEARANCE_CACHE[optimistic] = (grid, grid.occupancy.copy(), clr)
    return clr


def choose_subgoal(route: Route, clearance: np.ndarray, grid: Grid2D, cfg: PlanningCfg,
                   skip_m: float = 0.35) -> tuple[int, bool]:
    """(index into ``route.path_xy_m``, final): the farthest route point within the horizon whose
    route so far lies in observed free space with the footstep clearance (the first ``skip_m`` of
    the route, under the robot, is not tested); final when it is the route's end."""
    path = route.path_xy_m
    seg = np.linalg.norm(np.diff(path, axis=0), axis=1)
    s = np.concatenate([[0.0], np.cumsum(seg)])
    iy, ix = grid.cells_of(path)
    ny, nx = grid.shape
    inside = (iy >= 0) & (iy < ny) & (ix >= 0) & (ix < nx)
    ok = np.zeros(len(path), bool)
    # one cell more than the route's clearance: the planner tests the stance at the exact point,
    # which may lie up to a cell's half-diagonal nearer the blocked cells than its cell's centre
    ok[inside] = clearance[iy[inside], ix[inside]] >= cfg.route_clearance_m + grid.resolution_m
    # the goal itself needs only the route's clearance: a goal stance that touches something is the
    # navigator's to recover (other headings, a step back along the route)
    end = len(path) - 1
    ok[end] = bool(inside[end] and clearance[iy[end], ix[end]] >= cfg.route_clearance_m)
    passable = ok | (s < skip_m)
    bad = np.flatnonzero(~passable)
    last = (bad[0] - 1) if bad.size else len(path) - 1
    last = min(last, int(np.searchsorted(s, cfg.horizon_m, side="right") - 1))
    # the subgoal itself needs the clearance (the stretch under the robot is only passed through)
    good = np.flatnonzero(ok[:max(last, 0) + 1])
    k = int(good[-1]) if good.size else 0
    return k, k == len(path) - 1


def roomy_goal(grid: Grid2D, clearance: np.ndarray, goal_xy_m, room_m: float, shift_m: float) -> np.ndarray:
    """(2,) where to stand for a goal, m: the goal itself when its cell has ``room_m`` of clearance,
    else the cell centre within ``shift_m`` of it with the most clearance (capped at ``room_m``;
    the nearest among equals). A goal beside a wall is a stance beside it: the policy's arms
    reach 0.30-0.33 m from the pelvis while it stands and turns (``benchmarks/turn_on_the_spot.py``),
    and the goals are drawn with 0.265 m of clearance, so a robot standing on the goal itself
    touches the wall (nominal apartments 24, 52, 70, 78, 88 of the benchmark: feet and forearms on a
    wall at the goal). ``shift_m`` stays well inside the success radius."""
    goal = np.asarray(goal_xy_m, float)
    iy, ix = grid.cell_of(goal)
    ny, nx = grid.shape
    if not (0 <= iy < ny and 0 <= ix < nx) or clearance[iy, ix] >= room_m:
        return goal.copy()
    k = int(math.ceil(shift_m / grid.resolution_m))
    y0, y1, x0, x1 = max(0, iy - k), min(ny, iy + k + 1), max(0, ix - k), min(nx, ix + k + 1)
    yy, xx = np.mgrid[y0:y1, x0:x1]
    cx, cy = grid.cell_center_xy_m(yy.ravel(), xx.ravel())
    d = np.hypot(cx - goal[0], cy - goal[1])
    room = np.minimum(clearance[yy.ravel(), xx.ravel()], room_m)
    ok = d <= shift_m
    if not ok.any():
        return goal.copy()
    best = np.lexsort((d[ok], -room[ok]))[0]
    if room[ok][best] <= min(clearance[iy, ix], room_m):
        return goal.copy()
    return np.array([cx[ok][best], cy[ok][best]])


def route_heading(path: np.ndarray, k: int, back_m: float = 0.4) -> float:
    """Direction of the route arriving at point ``k``, averaged over the last ``back_m``, rad."""
    if k == 0:
        d = path[min(1, len(path) - 1)] - path[0]
    else:
        j = k
        while j > 0 and np.linalg.norm(path[k] - path[j - 1]) < back_m:
            j -= 1
        j = max(0, j - 1) if np.linalg.norm(path[k] - path[j]) < 1e-6 else j
        d = path[k] - path[j]
    return float(math.atan2(d[1], d[0])) if np.linalg.norm(d) > 1e-9 else 0.0


class FootstepStage:
    """Footsteps to a subgoal on the map with unknown cells blocked (module docstring, step 3)."""

    def __init__(self, cfg: PlanningCfg, body_clearance_m: float | None = None):
        """``body_clearance_m``: the planner's (``FootstepPlannerCfg.body_clearance_m``) if None."""
        self.cfg = cfg
        extra = {} if body_clearance_m is None else {"body_clearance_m": body_clearance_m}
        self.footstep_cfg = humanoid_footstep_cfg(max_expansions=cfg.footstep_max_expansions, **extra)
        self._full: tuple | None = None

    def plan(self, grid: Grid2D, version: int, optimistic: bool, start_xyyaw, goal_xyyaw, *,
             start_feet=None, stance_side=None) -> FootstepPlan:
        """A plan from the nominal stance at ``start_xyyaw`` (or from ``start_feet`` (2, 3), left then
        right, keeping ``stance_side`` down first, for a walker that steps on the plan's footholds)
        to ``goal_xyyaw`` (x m, y m, yaw rad)."""
        blocked = grid.occupied() if optimistic else grid.blocked()
        if optimistic:  # a map that never changes (the ground truth): one planner for the whole map
            key = (id(grid), version)
            if self._full is None or self._full[0] != key:
                gm = GridMap(occupied=blocked, origin_xy_m=tuple(grid.origin_xy_m), resolution_m=grid.resolution_m)
                self._full = (key, FootstepPlanner(gm, self.footstep_cfg))
            planner = self._full[1]
        else:
            planner = FootstepPlanner(self._window(grid, blocked, start_xyyaw, goal_xyyaw), self.footstep_cfg)
        if start_feet is not None:
            return planner.plan(goal_xyyaw_w=np.asarray(goal_xyyaw, float), start_feet_xyyaw_w=start_feet,
                                stance_side=stance_side)
        return planner.plan(np.asarray(start_xyyaw, float), np.asarray(goal_xyyaw, float))

    def _window(self, grid: Grid2D, blocked: np.ndarray, a, b) -> GridMap:
        m = self.cfg.window_margin_m
        lo = np.minimum(a[:2], b[:2]) - m
        hi = np.maximum(a[:2], b[:2]) + m
        iy0, ix0 = grid.cell_of(lo)
        iy1, ix1 = grid.cell_of(hi)
        ny, nx = grid.shape
        iy0, ix0, iy1, ix1 = max(0, iy0), max(0, ix0), min(ny - 1, iy1), min(nx - 1, ix1)
        if iy1 < iy0 or ix1 < ix0:  # robot and goal off the map (a drifted estimate): one blocked cell there
            return GridMap(occupied=np.ones((1, 1), bool), origin_xy_m=(float(lo[0]), float(lo[1])),
                           resolution_m=grid.resolution_m)
        ox, oy, _, _ = grid.cell_rect_xy_m(iy0, ix0)
        return GridMap(occupied=np.ascontiguousarray(blocked[iy0:iy1 + 1, ix0:ix1 + 1]), origin_xy_m=(ox, oy),
                       resolution_m=grid.resolution_m)


@dataclass
class ReplanRecord:
    """One replan: when, why, how long it took and how it ended."""

    time_s: float
    """Simulated time, s."""
    wall_s: float
    """Wall time of route + subgoal + footsteps, s."""
    reason: str
    route_found: bool
    footstep_status: str
    num_steps: int
    final: bool
    refused: str | None = None
    """The walker's reason for refusing the plan, if it did."""


def timed(fn, *args):
    t0 = time.perf_counter()
    out = fn(*args)
    return out, time.perf_counter() - t0


__all__ = ["FootstepStage", "PlanningCfg", "ReplanRecord", "Route", "RoutePlanner", "choose_subgoal",
           "footstep_clearance", "roomy_goal", "route_heading"]
