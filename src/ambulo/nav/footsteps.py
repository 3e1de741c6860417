"""Footstep planner: weighted A* over a footstep lattice on a ``GridMap``, with alternating feet,
the walker's step limits, sole-shaped collision checks, exact body clearance, step up/down limits, an admissible
heuristic, goal tolerances, an expansion budget that returns the best partial plan, and an explicit
failure reason (``PlanStatus``).

Search. A node is a footstep (x, y, yaw, side) with its exact continuous pose, so every step of a
plan is exactly one lattice action (``footstep_lattice``) or one step of a walk, and
the limits hold exactly. Duplicates are pruned per cell of ``state_resolution_m`` x
2 pi / ``state_yaw_bins`` and side, in a dense array. Each expansion generates, transforms and
tests all K successors with array operations (``FootstepChecks.steps``: sole samples, leg
segments and the body's crossed cells, each gathered from the map at once) and pushes them into
the open list as one f-sorted batch (one heap entry per batch, re-inserted with its next element
when its head is popped), so no Python code runs per successor. f = g + w h_path + (h - h_path)
with the admissible h of ``footstep_heuristic`` (``steps_left``) and its part h_path that follows
the way to the goal (the larger of the geodesic and yaw bounds; h adds the turning that facing
away from the straight line to the goal costs); w = ``heuristic_weight``. Weighting only h_path
keeps the search from preferring footsteps that face the goal across a wall: in a corridor that
bends away from the goal, w h would rise by w times the turning bound at the bend, and the
search expanded every state before it (1,531 expansions on one benchmark map; 6 now).

Walks along the body path (Hybrid A*'s analytic expansion, Dolgov et al. 2008, for feet). The
body path is the shortest path of the feet's midpoint to the goal through the body cells, with an
inflation cost that keeps it to the middle of corridors and doors (``GoalHeuristic.path``; scipy's
Dijkstra from the goal, once per query), straightened where the straight piece keeps as much room.
First from the start feet, then from every node that comes closer to the goal than any before
(and at least ``WALK_SPACING_M`` from where the last walk started),
the planner walks that path (``follow_path``: pure pursuit that turns while walking, side-steps
onto the path in narrow passages, and ends in the goal stance) and tests every step as above. A
walk that passes ends the search; one that fails part way opens its last good footstep as a
node. On most maps the first walk is the plan (no lattice expansion at all); the lattice search
covers the rest (tight spots, clutter at the feet, steps in the height map).

Start. The caller gives the exact start feet (``start_feet_xyyaw_w``: the left and right soles'
poses) and which foot stays down first (``stance_side``), or a body pose (the nominal stance)
and lets the planner choose the first foot.
"""

from __future__ import annotations

import copy
import dataclasses
import enum
import heapq
import math
import time
from dataclasses import dataclass

import numpy as np

from ..robots.humanoid import (
    STANCE_WIDTH_M,
    WALK_MAX_STEP_YAW_RAD,
    WALK_STEP_LENGTH_RANGE_M,
    WALK_STEP_WIDTH_RANGE_M,
)
from ..utils.checks import Described, InvalidValueError, check_int, check_positive, check_range, check_vector
from ..utils.validate import Checked
from .footstep_checks import FootstepChecks
from .footstep_heuristic import GoalHeuristic
from .footstep_lattice import (
    LEFT,
    RIGHT,
    build_lattice,
    compose,
    follow_path,
    relative,
    step_costs,
    steps_within_limits,
    wrap_angle,
)
from .grid_map import GridMap

WALK_SPACING_M = 0.1
"""The search walks the body path again only from a footstep whose feet's midpoint lies this far
from where the last walk started, so that expansions, not repeated walks from one spot, spend
the budget."""
PATH_LOOKAHEADS_M = (0.6, 0.25, 0.1)
"""Lookaheads of the walks along the body path (``follow_path``), tried in turn: the first cuts
corners smoothly in the open, the others keep closer to the path through doors and bends (on
the map benchmark the third turned 4 of 6 failures into plans)."""


@dataclass(kw_only=True)
class FootstepPlannerCfg(Checked):
    """Footstep planner settings; lengths in m, angles in rad. The step limits default to what the
    bundled humanoid's walk controller walks (``robots.humanoid``: ``WALK_STEP_LENGTH_RANGE_M``,
    ``WALK_STEP_WIDTH_RANGE_M``, ``WALK_MAX_STEP_YAW_RAD``); plan for another walker with its own."""

    foot_size_m: tuple[float, float] = (0.22, 0.10)
    """Sole rectangle (length along the foot's x, width along its y), centred on the foot frame
    (the humanoid's sole is 0.22 m x 0.09 m; 1 cm of margin across)."""
    step_lengths_m: tuple[float, ...]
    """Lattice values of the step length: swing foot x in the stance foot's frame."""
    step_widths_m: tuple[float, ...]
    """Lattice values of the step width: |swing foot y| in the stance foot's frame."""
    step_yaws_rad: tuple[float, ...]
    """Lattice values of the yaw change (swing foot yaw - stance foot yaw), mirrored for a right stance."""
    step_length_range_m: tuple[float, float] = WALK_STEP_LENGTH_RANGE_M
    """Limits of the step length, m (any step of a plan, lattice or walk along the body path)."""
    step_width_range_m: tuple[float, float] = WALK_STEP_WIDTH_RANGE_M
    """Limits of the step width, m; the swing foot lands on its own side of the stance foot."""
    max_step_yaw_rad: float = WALK_MAX_STEP_YAW_RAD
    """Limit of |yaw change| per step, rad."""
    min_foot_gap_m: float = 0.01
    """Consecutive soles keep at least this distance (the swing foot never lands on the stance foot)."""
    body_clearance_m: float = 0.25
    """The feet's midpoint (the body's ground track) keeps this distance from obstacles, measured
    exactly to the occupied cells' edges: about half a humanoid's shoulder width, so it does not
    squeeze through gaps only its feet fit in. Doors of 0.55 m and wider are open; at 0.50 m
    the midpoint would have to keep exactly to the door's centre line, and it is closed."""
    start_width_m: float = STANCE_WIDTH_M
    """Distance between the two parallel feet of the nominal stance (start from a body pose, the
    goal, and the walks along the body path), m."""
    max_step_up_m: float = 0.15
    """Largest rise from the stance foot's terrain height to the new foot's, m (height maps)."""
    max_step_down_m: float = 0.15
    max_foothold_spread_m: float = 0.02
    """A foothold is flat enough when the height map varies by at most this much under the sole."""
    goal_tolerance_m: float = 0.10
    """The goal is reached when the midpoint of the last two feet is this close to it."""
    goal_tolerance_yaw_rad: float = 0.20
    """... and their mean yaw this close to the goal yaw."""
    max_expansions: int = 1000
    """Budget of one query in lattice expansions; then the best partial plan comes back
    (``BUDGET_EXHAUSTED``). A count, not a time, so that a plan is a function of the map and the
    query alone: the same on a quiet machine and a loaded one, on any host (a navigation episode
    replayed elsewhere took other decisions under the former 0.3 s wall-time budget). About 1 s on
    one core of a 2-core VM (1,300 expansions/s on a door map at w = 1); most plans need 0-90
    (``benchmarks/footstep_maps.py``)."""
    time_budget_s: float | None = None
    """A wall-time limit of one query on top of ``max_expansions``, s (``ambulo plan --budget-ms``);
    None: none, so the plan does not depend on the machine's speed or load."""
    heuristic_weight: float = 8.0
    """w in f = g + w h (weighted A*; 1 is A*). Over lattice steps, a plan costs at most w times
    the best plan the pruning leaves. humanoid_navigation's ARA* starts at 8
    (``planning_params.yaml``). The admissible h (``footstep_heuristic``) counts about a third of
    the steps a walk needs (it allows the longest swing and any turn), so with w = 3 f stays flat
    while g grows and the search spreads over every turn near the start. On
    ``benchmarks/footstep_maps.py`` (204 maps; the search runs where the walks along the body
    path stall: doors at an angle, bent corridors): w = 3 planned 98.0-98.5 % in the 1 s budget,
    w = 5 99.0 % on doors, corridors and clutter, w = 8 100 % (at most 80 expansions); with seeds 1
    and 2 at a load average of 10-12 on 2 cores, w = 8 planned 99.0 % (two budget exhaustions after
    107 and 144 expansions, which a 20 s budget plans) and 100 %. With w weighting only the path
    part of h (module docstring): 100 % on seeds 0, 1 and 3 (238 maps each, load 10-14), at most
    86 expansions.
    Earlier, lattice steps only, 40 cluttered rooms at issue 14's step limits: w = 2 planned 50 %,
    w = 3 95 %, w = 5 97.5 %."""
    state_resolution_m: float = 0.05
    """Footsteps within one such cell (and yaw bin, same side) count as one state, m."""
    state_yaw_bins: int = 64
    yaw_cost_per_rad: float = 0.3
    """Step cost per rad of yaw change (on top of 1 per step)."""
    width_cost_per_m: float = 1.0
    """Cost per m of step width away from ``start_width_m``."""
    backward_step_cost: float = 0.5
    """Extra cost of a step with a negative length."""
    walk_along_body_path: bool = True
    """From every node that comes closer to the goal than any before, try straight walks: to the
    goal, else along the body path (module docstring). False: lattice steps only."""


def humanoid_footstep_cfg(**overrides) -> FootstepPlannerCfg:
    """The bundled humanoid's walker limits (length -0.10..0.25 m, width 0.12..0.30 m, |yaw
    change| <= 0.3 rad, stance 0.18 m) on a lattice of 7 lengths x 4 widths x 5 yaw changes,
    less the successors whose sole would come within ``min_foot_gap_m`` of the stance sole."""
    values = dict(step_lengths_m=(-0.10, 0.0, 0.05, 0.10, 0.15, 0.20, 0.25),
                  step_widths_m=(0.12, 0.18, 0.24, 0.30),
                  step_yaws_rad=(-0.30, -0.15, 0.0, 0.15, 0.30))
    values.update(overrides)
    return FootstepPlannerCfg(**values)


_DEFAULT_CFG: FootstepPlannerCfg | None = None


def _default_cfg() -> FootstepPlannerCfg:
    """A copy of ``humanoid_footstep_cfg()``, validated once per process (validation takes ms,
    and a navigator builds a planner per map update)."""
    global _DEFAULT_CFG
    if _DEFAULT_CFG is None:
        _DEFAULT_CFG = humanoid_footstep_cfg()
    return copy.copy(_DEFAULT_CFG)


def check_footstep_cfg(cfg: FootstepPlannerCfg) -> None:
    """Raise ``InvalidValueError`` naming the first setting that is out of range."""
    size = check_vector("foot_size_m", cfg.foot_size_m, 2, "pass (length, width) of the sole in m")
    if min(size) <= 0:
        raise InvalidValueError("foot_size_m", cfg.foot_size_m, "both sides must be > 0", "e.g. (0.22, 0.10)")
    lo_len, hi_len = check_range("step_length_range_m", cfg.step_length_range_m, "e.g. (-0.10, 0.25)",
                                 minimum=-math.inf)
    lo_w, hi_w = check_range("step_width_range_m", cfg.step_width_range_m, "e.g. (0.12, 0.30)")
    max_yaw = check_positive("max_step_yaw_rad", cfg.max_step_yaw_rad, "e.g. 0.3")
    for name, values, lo, hi in (("step_lengths_m", cfg.step_lengths_m, lo_len, hi_len),
                                 ("step_widths_m", cfg.step_widths_m, lo_w, hi_w),
                                 ("step_yaws_rad", cfg.step_yaws_rad, -max_yaw, max_yaw)):
        if len(values) == 0 or any(not (lo - 1e-12 <= v <= hi + 1e-12) for v in values):
            raise InvalidValueError(name, values, f"every value must lie in [{lo:g}, {hi:g}]",
                                    "sample the lattice inside the step limits")
    if not lo_w <= cfg.start_width_m <= hi_w:
        raise InvalidValueError("start_width_m", cfg.start_width_m, f"it must lie in [{lo_w:g}, {hi_w:g}]",
                                "start and goal stances must be reachable stances")
    for name in ("goal_tolerance_m", "goal_tolerance_yaw_rad", "state_resolution_m",
                 "max_step_up_m", "max_step_down_m", "max_foothold_spread_m"):
        check_positive(name, getattr(cfg, name), "pass a positive number")
    if cfg.time_budget_s is not None:
        check_positive("time_budget_s", cfg.time_budget_s, "pass None or seconds, e.g. 0.5")
    if not cfg.heuristic_weight >= 1.0:
        raise InvalidValueError("heuristic_weight", cfg.heuristic_weight, "it must be >= 1",
                                "1 is A*; larger values trade plan cost for speed")
    check_int("state_yaw_bins", cfg.state_yaw_bins, "e.g. 64", minimum=1)
    check_int("max_expansions", cfg.max_expansions, "pass a positive count, e.g. 1000", minimum=1)


class PlanStatus(enum.Enum):
    """How a planning query ended."""

    SUCCESS = "success"
    START_IN_COLLISION = "start_in_collision"
    """A start sole touches an obstacle or leaves the map, or the body lacks its clearance there."""
    GOAL_IN_COLLISION = "goal_in_collision"
    """The same for the nominal stance at the goal."""
    GOAL_UNREACHABLE = "goal_unreachable"
    """No path of body cells joins start and goal (found before searching), or every reachable
    footstep was expanded; the plan is the best partial one."""
    BUDGET_EXHAUSTED = "budget_exhausted"
    """Expansion (or time) budget spent; the plan is the best partial one: it ends at the expanded
    footstep with the smallest heuristic."""


@dataclass(frozen=True, eq=False)
class FootstepPlan:
    """A plan: the two start feet, then one footstep per step, alternating sides."""

    status: PlanStatus
    footsteps_xyyaw_w: np.ndarray
    """(num_steps + 2, 3) float64 foot poses in the world frame (x m, y m, yaw rad). Rows 0 and 1
    are the start feet (row 1 is the first stance foot, row 0 the first to move); row i >= 2 is
    step i - 1, placed from the stance foot at row i - 1."""
    foot_sides: np.ndarray
    """(num_steps + 2,) int8: +1 for a left foot, -1 for a right foot."""
    foot_z_m: np.ndarray
    """(num_steps + 2,) float64 terrain height under each foot (0 without a height map), m."""
    cost: float
    """Sum of the step costs (1 per step plus the penalties of ``step_costs``)."""
    expansions: int
    planning_time_s: float
    """From the ``plan`` call to its return, s."""
    detail: str = ""
    """One line on why the plan ended (empty on success)."""

    @property
    def num_steps(self) -> int:
        return len(self.footsteps_xyyaw_w) - 2


class FootstepPlanner:
    """Plans footsteps on one map; build it once per map and reuse it for many queries."""

    def __init__(self, grid: GridMap, cfg: FootstepPlannerCfg | None = None):
        self.cfg = cfg = _default_cfg() if cfg is None else cfg
        check_footstep_cfg(cfg)
        if not isinstance(grid, GridMap):
            raise InvalidValueError("grid", type(grid).__name__, "expected a GridMap",
                                    "build one with GridMap.from_array(occupied, resolution_m=...)")
        self.grid = grid
        self.lattice = build_lattice(cfg, grid.resolution_m)
        self.checks = FootstepChecks(grid, cfg, self.lattice)
        num_y, num_x = grid.shape
        self._key_shape = (2, math.ceil(num_y * grid.resolution_m / cfg.state_resolution_m),
                           math.ceil(num_x * grid.resolution_m / cfg.state_resolution_m), cfg.state_yaw_bins)
        self._state_array: np.ndarray | None = None
        self._pool = _Pool()
        self.heuristic: GoalHeuristic | None = None
        """The heuristic of the last query (its distance fields and ``steps_left``); the next
        query to the same goal reuses it."""

    @property
    def _state(self) -> np.ndarray:
        """Per pruning cell: 0 unseen, g + 1 while open, -(g + 1) once expanded; touched cells are
        reset after each query. Allocated on first use: most queries end in a walk and never
        touch it, and an array of tens of MB that malloc serves from its heap (not fresh,
        lazily mapped pages) is zeroed in full, several ms."""
        if self._state_array is None:
            self._state_array = np.zeros(int(np.prod(self._key_shape)))
        return self._state_array

    def _blocked_detail(self, what: str, feet_xyyaw: np.ndarray, plural: bool = False) -> str:
        """Why a stance (``feet_xyyaw`` (2, 3), world) is blocked, in words: off the map (a goal
        typed in the wrong frame or units) reads differently from touching an obstacle."""
        x0, y0, x1, y1 = self.grid.extent_xy_m()
        x, y = feet_xyyaw[:, 0], feet_xyyaw[:, 1]
        if (x < x0).any() or (x >= x1).any() or (y < y0).any() or (y >= y1).any():
            return f"{what} {'lie' if plural else 'lies'} off the map, which spans x {x0:g}..{x1:g} m, y {y0:g}..{y1:g} m"
        return f"{what} {'touch' if plural else 'touches'} an obstacle"

    def stance_feet(self, body_xyyaw_w) -> np.ndarray:
        """(2, 3) left and right foot poses of the nominal stance at a body pose (x, y, yaw), world frame."""
        w = self.cfg.start_width_m / 2
        return compose(np.asarray(body_xyyaw_w, float), np.array([[0.0, w, 0.0], [0.0, -w, 0.0]]))

    def plan(self, start_xyyaw_w=None, goal_xyyaw_w=None, *, start_feet_xyyaw_w=None, stance_side=None,
             time_budget_s: float | None = None) -> FootstepPlan:
        """Plan from the start feet to the goal body pose (x m, y m, yaw rad, world frame; body =
        midpoint of the feet, within the goal tolerances).

        The start feet are ``start_feet_xyyaw_w`` ((2, 3): the left sole's pose, then the right
        sole's, exactly where they stand), or the nominal stance at the body pose
        ``start_xyyaw_w``. ``stance_side`` is the foot that stays down first (``LEFT`` / ``RIGHT``
        or "left" / "right"; the other foot moves first), or None to let the planner choose."""
        t0 = time.perf_counter()
        cfg, checks = self.cfg, self.checks
        goal = np.array(check_vector("goal_xyyaw_w", goal_xyyaw_w, 3, "pass (x m, y m, yaw rad)"))
        if start_feet_xyyaw_w is not None:
            start_feet = np.asarray(start_feet_xyyaw_w, float)
            if start_feet.shape != (2, 3) or not np.isfinite(start_feet).all():
                raise InvalidValueError("start_feet_xyyaw_w", Described(f"shape {start_feet.shape}"),
                                        "expected finite (2, 3): the left foot's (x, y, yaw), then the right's",
                                        "pass [[x_l, y_l, yaw_l], [x_r, y_r, yaw_r]] in m and rad")
            start_feet[:, 2] = wrap_angle(start_feet[:, 2])
        elif start_xyyaw_w is not None:
            start_feet = self.stance_feet(np.array(check_vector("start_xyyaw_w", start_xyyaw_w, 3,
                                                                "pass (x m, y m, yaw rad)")))
        else:
            raise InvalidValueError("start", Described("missing"), "pass start_xyyaw_w or start_feet_xyyaw_w",
                                    "e.g. plan((0, 0, 0), goal) or plan(goal_xyyaw_w=goal, start_feet_xyyaw_w=feet)")
        stances = _stance_sides(stance_side)
        budget_s = cfg.time_budget_s if time_budget_s is None else check_positive(
            "time_budget_s", time_budget_s, "pass seconds, e.g. 0.1")
        budget_s = math.inf if budget_s is None else budget_s
        self._pool = pool = _Pool()
        # per root: node 2k moves first, node 2k + 1 (the root) is the stance foot
        roots = []
        for stance in stances:
            other = 1 if stance == LEFT else 0
            rows = [other, 1 - other]
            pool.add(start_feet[rows], np.array([checks.sole_height(start_feet[i]) for i in rows]),
                     np.array([-stance, stance], np.int8), np.array([-1, pool.size]),
                     np.zeros(2), np.zeros(2), np.zeros(2), np.full(2, -1), np.zeros(2, bool))
            roots.append(pool.size - 1)

        def result(status, node=roots[0], detail="", expansions=0):
            poses, sides, z = pool.path(node)
            return FootstepPlan(status=status, footsteps_xyyaw_w=poses, foot_sides=sides, foot_z_m=z,
                                cost=float(pool.g[node]), expansions=expansions,
                                planning_time_s=time.perf_counter() - t0, detail=detail)

        start_mid = start_feet[:, :2].mean(axis=0)
        if checks.stance_blocked(start_feet):
            return result(PlanStatus.START_IN_COLLISION,
                          detail=self._blocked_detail(f"the start feet {start_feet.tolist()}", start_feet, plural=True))
        goal_feet = self.stance_feet(goal)
        if checks.stance_blocked(goal_feet):
            return result(PlanStatus.GOAL_IN_COLLISION, detail=self._blocked_detail(f"the stance at the goal {goal}", goal_feet))
        if self.heuristic is None or not np.array_equal(self.heuristic.goal, goal):
            # its fields depend on the map and the goal alone: a replan to the same goal on this
            # map (a navigator's, each control period) reuses them, Dijkstra and all
            self.heuristic = GoalHeuristic(checks, goal)
        heuristic = self.heuristic
        if not heuristic.reachable(start_mid[0], start_mid[1]):
            return result(PlanStatus.GOAL_UNREACHABLE, detail="no path of body cells joins the start and the goal")
        for root in roots:
            if heuristic.is_goal(pool.pose[[root - 1]], pool.pose[root])[0]:
                return result(PlanStatus.SUCCESS, root)
        open_list: list = []
        best_walk = None
        if cfg.walk_along_body_path:  # first the walk along the body path from each root
            for root in roots:
                walk_end, prefix_end = self._follow_body_path(root)
                if walk_end is not None and (best_walk is None or pool.g[walk_end] < pool.g[best_walk]):
                    best_walk = walk_end
                if prefix_end is not None and self._open_node(prefix_end):
                    heapq.heappush(open_list, (pool.f[prefix_end], -pool.g[prefix_end], prefix_end, prefix_end + 1))
            if best_walk is not None:
                return result(PlanStatus.SUCCESS, best_walk)
        for root in roots:
            if self._open_node(root):
                heapq.heappush(open_list, (pool.f[root], 0.0, root, root + 1))
        best = (math.inf, math.inf, roots[0])  # (h, g, node) of the expanded footstep closest to the goal
        last_walk_xy = start_mid  # where the last walk along the body path started (the feet's midpoint)
        expansions, max_expansions, state = 0, cfg.max_expansions, self._state
        try:
            while open_list:
                _, _, pos, end = heapq.heappop(open_list)
                if pos + 1 < end:
                    heapq.heappush(open_list, (pool.f[pos + 1], -pool.g[pos + 1], pos + 1, end))
                key, g = pool.key[pos], pool.g[pos]
                if state[key] < 0 or g + 1.0 > state[key]:
                    continue  # expanded already, or reached again more cheaply since
                state[key] = -(g + 1.0)
                if pool.goal[pos]:
                    return result(PlanStatus.SUCCESS, pos, expansions=expansions)
                if (pool.h[pos], g) < best[:2]:
                    best = (pool.h[pos], g, pos)
                    mid = 0.5 * (pool.pose[pos, :2] + pool.pose[pool.parent[pos], :2])
                    if (cfg.walk_along_body_path and pool.parent[pos] >= 0
                            and np.hypot(*(mid - last_walk_xy)) >= WALK_SPACING_M):
                        last_walk_xy = mid
                        walk_end, prefix_end = self._follow_body_path(pos)
                        if walk_end is not None:
                            return result(PlanStatus.SUCCESS, walk_end, expansions=expansions)
                        if prefix_end is not None and self._open_node(prefix_end):
                            heapq.heappush(open_list, (pool.f[prefix_end], -pool.g[prefix_end], prefix_end,
                                                       prefix_end + 1))
                if expansions >= max_expansions or (budget_s < math.inf and time.perf_counter() - t0 > budget_s):
                    return result(PlanStatus.BUDGET_EXHAUSTED, best[2], expansions=expansions,
                                  detail=f"budget spent after {expansions} expansions; best partial plan")
                expansions += 1
                batch = self._expand(pos)
                if batch is not None:
                    heapq.heappush(open_list, (pool.f[batch[0]], -pool.g[batch[0]], *batch))
            return result(PlanStatus.GOAL_UNREACHABLE, best[2], expansions=expansions,
                          detail="every reachable footstep was expanded; best partial plan")
        finally:
            touched = pool.key[:pool.size]
            state[touched[touched >= 0]] = 0.0

    # -- search internals -------------------------------------------------------------------
    def _keys(self, poses: np.ndarray, sides: np.ndarray) -> np.ndarray:
        """(K,) flat index of the pruning cell of footsteps (K, 3) with sides (K,)."""
        _, num_ky, num_kx, bins = self._key_shape
        ox, oy = self.grid.origin_xy_m
        res = self.cfg.state_resolution_m
        kx = np.clip(((poses[:, 0] - ox) / res).astype(np.intp), 0, num_kx - 1)
        ky = np.clip(((poses[:, 1] - oy) / res).astype(np.intp), 0, num_ky - 1)
        kyaw = ((poses[:, 2] + np.pi) * (bins / (2 * np.pi))).astype(np.intp) % bins
        return (((sides > 0) * num_ky + ky) * num_kx + kx) * bins + kyaw

    def _expand(self, i: int) -> tuple[int, int] | None:
        """Generate, test and store every successor of footstep ``i``; returns the pool range
        [start, end) of those kept, sorted by f (then larger g), or None if none was kept."""
        pool, lat, cfg = self._pool, self.lattice, self.cfg
        stance, side = pool.pose[i], int(pool.side[i])
        new = compose(stance, lat.actions[side])  # (K, 3)
        g = pool.g[i] + lat.costs
        sides = np.full(len(new), -side, np.int8)
        keys = self._keys(new, sides)
        record = self._state[keys]
        keep = np.flatnonzero((record == 0) | (g + 1.0 < record))  # new cells, or reached more cheaply
        free, new_z = self.checks.steps(pool.pose[pool.parent[i], :2], stance, new[keep])
        if self.checks.height is not None:
            free &= self.checks.rise_ok(new_z - pool.z[i])
        keep, new_z = keep[free], new_z[free]
        h, base = self.heuristic.steps_left(new[keep], stance, split=True)
        finite = np.isfinite(h)
        keep, new_z, h, base = keep[finite], new_z[finite], h[finite], base[finite]
        if keep.size == 0:
            return None
        new, g, sides, keys = new[keep], g[keep], sides[keep], keys[keep]
        self._state[keys] = g + 1.0
        f = g + cfg.heuristic_weight * base + (h - base)
        order = np.lexsort((-g, f))
        order = order[self._state[keys[order]] == g[order] + 1.0]  # of two in one pruning cell, the one written
        start = pool.add(new[order], new_z[order], sides[order], np.full(len(order), i), g[order], f[order],
                         h[order], keys[order], self.heuristic.is_goal(new[order], stance))
        return start, start + len(order)

    def _open_node(self, i: int) -> bool:
        """Give footstep ``i`` (a root or the end of a walk) its pruning key, h and f, and record
        it as open; False if its cell is expanded already, reached more cheaply, or dead."""
        pool = self._pool
        key = self._keys(pool.pose[[i]], pool.side[[i]])[0]
        record = self._state[key]
        if record < 0 or (record > 0 and pool.g[i] + 1.0 >= record):
            return False
        pool.key[i] = key
        h, base = self.heuristic.steps_left(pool.pose[[i]], pool.pose[pool.parent[i]], split=True)
        pool.h[i] = h[0]
        pool.f[i] = pool.g[i] + self.cfg.heuristic_weight * base[0] + (h[0] - base[0])
        self._state[key] = pool.g[i] + 1.0
        return bool(np.isfinite(pool.h[i]))

    def _body_free_at(self, x0_m: float, y0_m: float, x1_m: float, y1_m: float) -> bool:
        """Does the feet's midpoint keep to body cells moving from (x0, y0) to (x1, y1) (m, world)?
        Far from obstacles the answer needs no cell walk: every cell the move crosses lies within
        its length plus a cell diagonal of (x0, y0), so it keeps the body clearance when the
        start's cell has that much more."""
        checks = self.checks
        reach_m = math.hypot(x1_m - x0_m, y1_m - y0_m) + checks.grid.resolution_m * math.sqrt(2.0)
        if checks.clearance_at(x0_m, y0_m) >= self.cfg.body_clearance_m + reach_m:
            return True
        return checks.body_segment_free(x0_m, y0_m, x1_m, y1_m)

    def _follow_body_path(self, i: int) -> tuple[int | None, int | None]:
        """Walk from footstep ``i`` along the body path to the goal (``follow_path``), with each
        lookahead of ``PATH_LOOKAHEADS_M`` until one passes every test. Returns (the last node of a
        walk that reaches the goal, or None; the last node of the longest tested prefix of a walk
        that ends short, or None), every prefix stored in the pool."""
        pool, cfg, lat, checks, heuristic = self._pool, self.cfg, self.lattice, self.checks, self.heuristic
        stance, side, parent = pool.pose[i], int(pool.side[i]), int(pool.parent[i])
        path = heuristic.path(0.5 * (stance[:2] + pool.pose[parent, :2]))
        if path is None:
            return None, None
        best_prefix, best_len = None, 0
        for lookahead in PATH_LOOKAHEADS_M:
            walk = follow_path(stance, side, path, cfg, lookahead_m=lookahead, goal_xyyaw=heuristic.goal,
                               body_free=self._body_free_at)
            if len(walk) == 0:
                continue
            chain = np.concatenate([pool.pose[[parent, i]], walk])
            sides = np.where(np.arange(len(chain)) % 2 == 0, -side, side).astype(np.int8)  # parent, i, walk...
            rel = relative(chain[1:-1], chain[2:])
            ok = (steps_within_limits(rel, sides[1:-1], cfg)
                  & (np.hypot(rel[:, 0], rel[:, 1]) <= lat.max_step_reach_m + 1e-9)
                  & (np.hypot(*(chain[2:, :2] - chain[:-2, :2]).T) <= lat.max_swing_m + 1e-9))
            free, z = checks.steps(chain[:-2, :2], chain[1:-1], chain[2:])
            ok &= free
            if checks.height is not None:
                ok &= checks.rise_ok(z - np.concatenate([[pool.z[i]], z[:-1]]))  # rises after a failure do not matter
            n = len(walk) if ok.all() else int(np.argmin(ok))
            if n == 0:
                continue
            g = pool.g[i] + np.cumsum(step_costs(rel[:n], cfg))
            at_goal = heuristic.is_goal(walk[n - 1:n], chain[n])  # the last stored footstep and its stance
            goal_flags = np.zeros(n, bool)
            goal_flags[-1] = at_goal[0]
            start = pool.add(walk[:n], z[:n], sides[2:2 + n], np.concatenate([[i], pool.size + np.arange(n - 1)]),
                             g, g, np.zeros(n), np.full(n, -1), goal_flags)
            if goal_flags[-1]:
                return start + n - 1, None
            if n > best_len:
                best_prefix, best_len = start + n - 1, n
        return None, best_prefix


def _stance_sides(stance_side) -> tuple[int, ...]:
    """The roots to search from: (LEFT,), (RIGHT,) or both, from ``plan``'s ``stance_side``."""
    if stance_side is None:
        return (LEFT, RIGHT)
    named = {"left": LEFT, "right": RIGHT}
    value = named.get(stance_side.lower(), stance_side) if isinstance(stance_side, str) else stance_side
    if isinstance(value, (bool, np.bool_)) or value not in (LEFT, RIGHT):
        raise InvalidValueError("stance_side", stance_side, "expected LEFT (+1), RIGHT (-1), 'left', 'right' or None",
                                "name the foot that stays down while the other takes the first step")
    return (int(value),)


class _Pool:
    """Every generated footstep, in growable arrays (row = node id)."""

    def __init__(self, capacity: int = 1 << 14):
        self.size = 0
        self.pose = np.empty((capacity, 3))
        self.z, self.g, self.f, self.h = (np.empty(capacity) for _ in range(4))
        self.side = np.empty(capacity, np.int8)
        self.parent = np.empty(capacity, np.intp)
        self.key = np.empty(capacity, np.intp)
        self.goal = np.empty(capacity, bool)

    def add(self, pose, z, side, parent, g, f, h, key, goal) -> int:
        """Append n nodes (arrays of length n); returns the id of the first."""
        start, n = self.size, len(pose)
        if start + n > len(self.g):
            for name in ("pose", "z", "g", "f", "h", "side", "parent", "key", "goal"):
                old = getattr(self, name)
                grown = np.empty((max(2 * len(old), start + n), *old.shape[1:]), old.dtype)
                grown[:start] = old[:start]
                setattr(self, name, grown)
        rows = slice(start, start + n)
        self.pose[rows], self.z[rows], self.side[rows], self.parent[rows] = pose, z, side, parent
        self.g[rows], self.f[rows], self.h[rows], self.key[rows], self.goal[rows] = g, f, h, key, goal
        self.size = start + n
        return start

    def path(self, node: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Poses (n, 3), sides (n,) and heights (n,) from the root to ``node``."""
        chain = []
        while node >= 0:
            chain.append(node)
            node = int(self.parent[node])
        chain = np.array(chain[::-1])
        return self.pose[chain].copy(), self.side[chain].copy(), self.z[chain].copy()


def plan_footsteps(grid: GridMap, start_xyyaw_w, goal_xyyaw_w, cfg: FootstepPlannerCfg | None = None
                   ) -> FootstepPlan:
    """One query on a fresh ``FootstepPlanner``; ``planning_time_s`` includes the map preprocessing."""
    t0 = time.perf_counter()
    plan = FootstepPlanner(grid, cfg).plan(start_xyyaw_w, goal_xyyaw_w)
    return dataclasses.replace(plan, planning_time_s=time.perf_counter() - t0)
