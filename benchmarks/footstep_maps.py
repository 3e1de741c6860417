"""Footstep planner on seeded ROS map_server maps, every plan checked by an independent shapely checker.

    python benchmarks/footstep_maps.py [--maps-per-category 34] [--seed 0] [--png-dir DIR]

Seven categories of maps, built as a user's would be and written as map_server YAML + PGM into a
temporary folder with ``ambulo.maps.save_map_yaml``, then loaded back with ``load_map_yaml`` (the
planner sees only what the loader returns, through ``GridMap.from_map``; unknown cells blocked):

- ``open_rooms``: one room, 5-8 m a side, a few pieces of furniture along its walls;
- ``clutter``: an 8 m room with 12-25 boxes (rotated) and discs of 0.1-0.35 m;
- ``doors``: two or three rooms in a row, walls 0.1-0.2 m thick, doors 0.60-1.0 m wide (every
  third map has a door of exactly 0.60 m); start in the first room, goal in the last;
- ``narrow_passages``: two rooms joined by a corridor 0.60-0.80 m wide and 1.5-4 m long, straight
  or with a bend;
- ``u_traps``: a U-shaped obstacle opening towards the start, the goal behind its base;
- ``serpentines``: 3-5 walls across a room, alternately from either side, gaps 0.7-1.2 m;
- ``angled_doors``: a wall across a room at up to 30 degrees off the cell lines (jagged raster
  edges), thickness 0.1-0.2 m, one door 0.65-1.0 m wide; start on one side, goal on the other
  (added after the planner's 98 % run, where doors approached at an angle failed).

Every problem gives the exact start feet (left and right sole poses, up to 4 cm and 0.1 rad off
the nominal stance), which foot stays down first (random), and a goal body pose (random yaw).
A problem is kept only if its start and goal are joined through cells whose every point keeps the
body clearance from the blocked cells (so every problem has a plan).

The checker shares no code with the planner: it builds the blocked cells of the loaded map as
shapely boxes and tests, for every footstep, the sole rectangle (inside the map, touching no
blocked cell), the step's length, width and yaw change against the walker's limits (typed below,
not imported), alternating feet with the requested foot moving first, the soles apart, the legs'
and the swing foot's segments clear of obstacles, the body's track (the feet's midpoint) keeping
the body clearance, the start feet exactly as given, and the final stance at the goal.

Prints one line per category and ``RESULT {json}``: ``valid_pct`` (plans that claim success and
pass the checker, over all problems), ``false_successes`` (claimed successes the checker rejects:
must be 0), planning ms p50/p95 per category (``plan_ms``: ``FootstepPlanner(grid)`` plus its
``plan`` call, i.e. a fresh map each query; ``query_ms``: the ``plan`` call alone; ``plan_cpu_ms``:
the process time of ``plan_ms``, near what a quiet machine's wall time would be), lattice
expansions p50/p95/max per category (0 where the walk along the body path is the plan), the load
average.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import tempfile
import time
from collections import Counter, defaultdict
from pathlib import Path

import numpy as np
import shapely
from scipy import ndimage
from shapely import affinity
from shapely.geometry import LineString, Point, box

from ambulo.maps import Grid2D, load_map_yaml, save_map_yaml
from ambulo.nav import FootstepPlanner, GridMap, PlanStatus, plot_plan
from ambulo.nav.footstep_lattice import LEFT, RIGHT

CATEGORIES = ("open_rooms", "clutter", "doors", "narrow_passages", "u_traps", "serpentines", "angled_doors")
RESOLUTION_M = 0.05
# the checker's numbers: the bundled humanoid's walker limits and sole, typed here on purpose
STEP_LENGTH_M = (-0.10, 0.25)
STEP_WIDTH_M = (0.12, 0.30)
MAX_STEP_YAW_RAD = 0.30
FOOT_SIZE_M = (0.22, 0.10)
MIN_FOOT_GAP_M = 0.01
BODY_CLEARANCE_M = 0.25
STANCE_WIDTH_M = 0.18
GOAL_TOLERANCE_M = 0.10
GOAL_TOLERANCE_YAW_RAD = 0.20
EPS = 1e-6


# -- maps ---------------------------------------------------------------------------------------
class Canvas:
    """An occupancy raster drawn in metres from the map's lower-left corner (cell centres decide)."""

    def __init__(self, size_x_m: float, size_y_m: float):
        self.num_x, self.num_y = round(size_x_m / RESOLUTION_M), round(size_y_m / RESOLUTION_M)
        self.occupied = np.zeros((self.num_y, self.num_x), bool)
        xs = (np.arange(self.num_x) + 0.5) * RESOLUTION_M
        ys = (np.arange(self.num_y) + 0.5) * RESOLUTION_M
        self.cx, self.cy = np.meshgrid(xs, ys, indexing="xy")

    def rect(self, x0, y0, x1, y1, value=True):
        """Axis-aligned rectangle snapped to the cell lines (edges rounded to the nearest line)."""
        i0, i1 = (min(max(round(v / RESOLUTION_M), 0), self.num_y) for v in (y0, y1))
        j0, j1 = (min(max(round(v / RESOLUTION_M), 0), self.num_x) for v in (x0, x1))
        self.occupied[i0:i1, j0:j1] = value

    def box(self, center, size, yaw):
        dx, dy = self.cx - center[0], self.cy - center[1]
        c, s = math.cos(yaw), math.sin(yaw)
        self.occupied |= (np.abs(c * dx + s * dy) <= size[0] / 2) & (np.abs(-s * dx + c * dy) <= size[1] / 2)

    def disc(self, center, radius):
        self.occupied |= np.hypot(self.cx - center[0], self.cy - center[1]) <= radius

    def walls(self, thickness_m=0.1):
        t = thickness_m
        self.rect(0, 0, self.num_x * RESOLUTION_M, t)
        self.rect(0, self.num_y * RESOLUTION_M - t, self.num_x * RESOLUTION_M, self.num_y * RESOLUTION_M)
        self.rect(0, 0, t, self.num_y * RESOLUTION_M)
        self.rect(self.num_x * RESOLUTION_M - t, 0, self.num_x * RESOLUTION_M, self.num_y * RESOLUTION_M)


def open_room(rng, canvas_size):
    sx, sy = rng.uniform(5, 8), rng.uniform(5, 8)
    c = Canvas(sx, sy)
    c.walls()
    for _ in range(rng.integers(0, 4)):  # furniture against a wall
        w, d = rng.uniform(0.4, 1.2), rng.uniform(0.3, 0.6)
        if rng.random() < 0.5:
            x = rng.uniform(0.5, sx - 0.5 - w)
            y0 = 0.1 if rng.random() < 0.5 else sy - 0.1 - d
            c.rect(x, y0, x + w, y0 + d)
        else:
            y = rng.uniform(0.5, sy - 0.5 - w)
            x0 = 0.1 if rng.random() < 0.5 else sx - 0.1 - d
            c.rect(x0, y, x0 + d, y + w)
    return c, None, None, 2.0


def clutter(rng, canvas_size):
    c = Canvas(8.0, 8.0)
    c.walls()
    for _ in range(rng.integers(12, 26)):
        center = rng.uniform(0.6, 7.4, 2)
        if rng.random() < 0.6:
            c.box(center, rng.uniform(0.15, 0.7, 2), rng.uniform(0, math.pi))
        else:
            c.disc(center, rng.uniform(0.1, 0.35))
    return c, None, None, 3.0


def doors(rng, index):
    num_rooms = int(rng.integers(2, 4))
    widths = rng.uniform(2.2, 3.0, num_rooms)
    sy = rng.uniform(4.0, 6.0)
    c = Canvas(float(widths.sum()) + 0.2, sy)
    c.walls()
    x = 0.1
    for k in range(num_rooms - 1):
        x += widths[k]
        t = rng.choice([0.10, 0.15, 0.20])
        door = 0.60 if (index % 3 == 0 and k == 0) else rng.uniform(0.60, 1.0)
        door = math.ceil(door / RESOLUTION_M - 1e-9) * RESOLUTION_M
        y0 = rng.uniform(0.5, sy - 0.5 - door)
        c.rect(x - t / 2, 0, x + t / 2, sy)
        c.rect(x - t / 2 - 0.01, y0, x + t / 2 + 0.01, y0 + door, value=False)
    start_box = (0.5, 0.5, 0.1 + widths[0] - 0.5, sy - 0.5)
    goal_box = (c.num_x * RESOLUTION_M - widths[-1] + 0.4, 0.5, c.num_x * RESOLUTION_M - 0.5, sy - 0.5)
    return c, start_box, goal_box, 0.0


def narrow_passage(rng, index):
    width = math.ceil(rng.uniform(0.60, 0.80) / RESOLUTION_M - 1e-9) * RESOLUTION_M
    length = rng.uniform(1.5, 4.0)
    room = 2.5
    bend = rng.random() < 0.5
    sy = 6.0
    sx = 2 * room + length + 0.2
    c = Canvas(sx, sy)
    c.occupied[:] = True
    c.rect(0.1, 0.1, 0.1 + room, sy - 0.1, value=False)
    c.rect(sx - 0.1 - room, 0.1, sx - 0.1, sy - 0.1, value=False)
    y_a = rng.uniform(0.8, sy - 0.8 - width)
    if bend:  # corridor along x at y_a, then along y to y_b, then along x again
        y_b = rng.uniform(0.8, sy - 0.8 - width)
        x_mid = 0.1 + room + rng.uniform(0.4, max(0.5, length - 0.4 - width))
        c.rect(0.1 + room - 0.05, y_a, x_mid + width, y_a + width, value=False)
        c.rect(x_mid, min(y_a, y_b), x_mid + width, max(y_a, y_b) + width, value=False)
        c.rect(x_mid, y_b, sx - 0.1 - room + 0.05, y_b + width, value=False)
    else:
        c.rect(0.1 + room - 0.05, y_a, sx - 0.1 - room + 0.05, y_a + width, value=False)
    start_box = (0.5, 0.5, 0.1 + room - 0.5, sy - 0.5)
    goal_box = (sx - room + 0.4, 0.5, sx - 0.5, sy - 0.5)
    return c, start_box, goal_box, 0.0


def u_trap(rng, index):
    c = Canvas(8.0, 8.0)
    c.walls()
    inner_w, depth, t = rng.uniform(1.4, 2.4), rng.uniform(1.4, 2.4), rng.uniform(0.1, 0.25)
    cx, cy = rng.uniform(3.6, 4.4), rng.uniform(3.4, 4.6)
    # the U opens towards -x; its base is at x = cx + depth / 2
    x0, x1 = cx - depth / 2, cx + depth / 2
    y0, y1 = cy - inner_w / 2, cy + inner_w / 2
    c.rect(x1, y0 - t, x1 + t, y1 + t)
    c.rect(x0, y0 - t, x1 + t, y0)
    c.rect(x0, y1, x1 + t, y1 + t)
    start = (max(0.6, x0 - rng.uniform(1.0, 2.0)), cy + rng.uniform(-0.3, 0.3))
    goal = (min(7.4, x1 + t + rng.uniform(0.8, 1.8)), cy + rng.uniform(-0.3, 0.3))
    return c, (start[0], start[1], start[0], start[1]), (goal[0], goal[1], goal[0], goal[1]), 0.0


def serpentine(rng, index):
    num_walls = int(rng.integers(3, 6))
    spacing = rng.uniform(1.0, 1.5)
    sy = rng.uniform(4.0, 6.0)
    sx = (num_walls + 1) * spacing + 0.2
    c = Canvas(sx, sy)
    c.walls()
    for k in range(num_walls):
        x = 0.1 + (k + 1) * spacing
        t = rng.choice([0.10, 0.15, 0.20])
        gap = math.ceil(rng.uniform(0.7, 1.2) / RESOLUTION_M - 1e-9) * RESOLUTION_M
        if k % 2 == 0:
            c.rect(x - t / 2, 0, x + t / 2, sy - 0.1 - gap)
        else:
            c.rect(x - t / 2, 0.1 + gap, x + t / 2, sy)
    start_box = (0.5, 0.5, 0.1 + spacing - 0.45, sy - 0.5)
    goal_box = (sx - spacing + 0.35, 0.5, sx - 0.5, sy - 0.5)
    return c, start_box, goal_box, 0.0


def angled_door(rng, index):
    """A wall across the room at up to 30 degrees from the y axis, not on the cell lines (its raster
    edges are jagged), with one door 0.65-1.0 m wide; start on one side, goal on the other."""
    sx, sy = rng.uniform(7.0, 8.0), rng.uniform(4.0, 5.5)
    c = Canvas(sx, sy)
    c.walls()
    tilt, t = rng.uniform(-math.pi / 6, math.pi / 6), rng.uniform(0.1, 0.2)
    door = rng.uniform(0.65, 1.0)
    along = np.array([math.sin(tilt), math.cos(tilt)])  # the wall's direction
    center = np.array([sx / 2, sy / 2])
    offset = rng.uniform(-sy / 2 + 0.8, sy / 2 - 0.8)  # the door's centre along the wall
    reach = sy  # each wall piece runs past the room's edge
    for lo, hi in ((-reach, offset - door / 2), (offset + door / 2, reach)):
        c.box(center + along * (lo + hi) / 2, (hi - lo, t), math.atan2(along[1], along[0]))
    start_box = (0.5, 0.5, sx / 2 - 1.8, sy - 0.5)
    goal_box = (sx / 2 + 1.8, 0.5, sx - 0.5, sy - 0.5)
    return c, start_box, goal_box, 0.0


BUILDERS = {"open_rooms": open_room, "clutter": clutter, "doors": doors, "narrow_passages": narrow_passage,
            "u_traps": u_trap, "serpentines": serpentine, "angled_doors": angled_door}


def clearance_m(occupied: np.ndarray) -> np.ndarray:
    """(num_y, num_x) distance from every point of each cell to the nearest blocked cell, m (a blocked
    cell's neighbours, diagonal ones included, are 0): the cell-centre distance transform of the
    blocked cells grown by one cell."""
    grown = ndimage.binary_dilation(occupied, np.ones((3, 3), bool), border_value=1)
    return ndimage.distance_transform_edt(~grown) * RESOLUTION_M


def make_problem(category: str, index: int, rng: np.random.Generator) -> dict:
    """A solvable problem of ``category``: the canvas, exact start feet, stance side and goal pose."""
    for _ in range(200):
        canvas, start_box, goal_box, min_dist = BUILDERS[category](rng, index)
        clear = clearance_m(canvas.occupied)
        body_ok = clear >= BODY_CLEARANCE_M
        roomy = clear >= 0.40  # start and goal: the feet fit in any yaw, off by a few cm

        def sample(region):
            for _ in range(300):
                if region is None:
                    x = rng.uniform(0, canvas.num_x * RESOLUTION_M)
                    y = rng.uniform(0, canvas.num_y * RESOLUTION_M)
                else:
                    x, y = rng.uniform(region[0], region[2]), rng.uniform(region[1], region[3])
                j, i = int(x / RESOLUTION_M), int(y / RESOLUTION_M)
                if 0 <= i < canvas.num_y and 0 <= j < canvas.num_x and roomy[i, j]:
                    return np.array([x, y])
            return None

        start_xy, goal_xy = sample(start_box), sample(goal_box)
        if start_xy is None or goal_xy is None or np.linalg.norm(goal_xy - start_xy) < max(min_dist, 1.0):
            continue
        labels, _ = ndimage.label(body_ok, np.ones((3, 3), bool))
        a = labels[int(start_xy[1] / RESOLUTION_M), int(start_xy[0] / RESOLUTION_M)]
        b = labels[int(goal_xy[1] / RESOLUTION_M), int(goal_xy[0] / RESOLUTION_M)]
        if a == 0 or a != b:
            continue
        if category == "u_traps":  # facing the goal, i.e. into the trap
            start_yaw = math.atan2(*(goal_xy - start_xy)[::-1]) + rng.uniform(-0.3, 0.3)
        else:
            start_yaw = rng.uniform(-math.pi, math.pi)
        origin = np.round(rng.uniform(-6.0, 2.0, 2), 3)
        body = np.array([*(start_xy + origin), start_yaw])
        # exact start feet: the nominal stance, each foot up to 4 cm and 0.1 rad off
        feet = []
        for side in (LEFT, RIGHT):
            yaw = start_yaw + rng.uniform(-0.1, 0.1)
            along, across = rng.uniform(-0.02, 0.02), side * STANCE_WIDTH_M / 2 + rng.uniform(-0.02, 0.02)
            feet.append([body[0] + math.cos(start_yaw) * along - math.sin(start_yaw) * across,
                         body[1] + math.sin(start_yaw) * along + math.cos(start_yaw) * across, yaw])
        return dict(category=category, index=index, occupied=canvas.occupied, origin_xy_m=tuple(origin),
                    start_feet=np.array(feet), stance_side=int(rng.choice([LEFT, RIGHT])),
                    goal=np.array([*(goal_xy + origin), rng.uniform(-math.pi, math.pi)]))
    raise RuntimeError(f"no solvable {category} problem in 200 tries")


def write_and_load(problem: dict, folder: Path) -> Grid2D:
    """The problem's map through map_server YAML + PGM and back, as a user's map file would come."""
    grid = Grid2D.from_masks(problem["occupied"], origin_xy_m=problem["origin_xy_m"], resolution_m=RESOLUTION_M)
    path = save_map_yaml(folder / f"{problem['category']}_{problem['index']:03d}.yaml", grid)
    return load_map_yaml(path)


# -- the independent checker -----------------------------------------------------------------------
def blocked_geometry(grid: Grid2D):
    """(union of blocked cells as shapely geometry, the map's extent as a box): runs of blocked
    cells along each row become one rectangle each."""
    blocked = grid.occupancy != 0  # occupied or unknown (trinary maps hold -1, 0, 100)
    (ox, oy), r = grid.origin_xy_m, grid.resolution_m
    rects = []
    for iy in range(blocked.shape[0]):
        row = np.concatenate([[False], blocked[iy], [False]])
        edges = np.flatnonzero(row[1:] != row[:-1])
        for j0, j1 in zip(edges[::2], edges[1::2]):
            rects.append(box(ox + j0 * r, oy + iy * r, ox + j1 * r, oy + (iy + 1) * r))
    extent = box(ox, oy, ox + blocked.shape[1] * r, oy + blocked.shape[0] * r)
    return shapely.union_all(rects), extent


def sole_polygon(x: float, y: float, yaw: float):
    half_l, half_w = FOOT_SIZE_M[0] / 2, FOOT_SIZE_M[1] / 2
    return affinity.translate(affinity.rotate(box(-half_l, -half_w, half_l, half_w), yaw, origin=(0, 0),
                                              use_radians=True), x, y)


def in_frame(pose, other) -> tuple[float, float, float]:
    """``other`` (x, y, yaw) seen from the frame ``pose``."""
    c, s = math.cos(pose[2]), math.sin(pose[2])
    dx, dy = other[0] - pose[0], other[1] - pose[1]
    return c * dx + s * dy, -s * dx + c * dy, (other[2] - pose[2] + math.pi) % (2 * math.pi) - math.pi


def check_plan(footsteps, sides, blocked, extent, *, start_feet=None, stance_side=None, goal=None,
               body_clearance_m: float = BODY_CLEARANCE_M) -> list[str]:
    """Every violation in a plan (rows 0-1: the start feet, row 1 the first stance foot; then one
    row per step), as text; [] if none. ``start_feet`` (2, 3) left and right, as requested."""
    footsteps = np.asarray(footsteps, float)
    problems = []
    soles = [sole_polygon(*pose) for pose in footsteps]
    if start_feet is not None:
        for row, side in ((0, int(sides[0])), (1, int(sides[1]))):
            want = start_feet[0 if side == LEFT else 1]
            if not np.allclose(footsteps[row], want, atol=1e-9):
                problems.append(f"start foot {row} is not the requested {'left' if side == LEFT else 'right'} foot")
    if stance_side is not None and int(sides[1]) != stance_side:
        problems.append("the first stance foot is not the requested one")
    for i, (pose, sole) in enumerate(zip(footsteps, soles)):
        if sole.intersects(blocked) or not extent.contains(sole):
            problems.append(f"foot {i} touches a blocked cell or leaves the map")
        if i == 0:
            continue
        side = int(sides[i])
        if side not in (-1, 1) or side != -int(sides[i - 1]):
            problems.append(f"foot {i}: sides do not alternate")
        if i >= 2:  # row 1 is the given start stance, not a step
            dx, dy, dyaw = in_frame(footsteps[i - 1], pose)
            width = dy * side
            if not STEP_LENGTH_M[0] - EPS <= dx <= STEP_LENGTH_M[1] + EPS:
                problems.append(f"step {i}: length {dx:.3f} m out of {STEP_LENGTH_M}")
            if not STEP_WIDTH_M[0] - EPS <= width <= STEP_WIDTH_M[1] + EPS:
                problems.append(f"step {i}: width {width:.3f} m out of {STEP_WIDTH_M}")
            if abs(dyaw) > MAX_STEP_YAW_RAD + EPS:
                problems.append(f"step {i}: yaw change {dyaw:.3f} rad over {MAX_STEP_YAW_RAD}")
            if sole.distance(soles[i - 1]) < MIN_FOOT_GAP_M - EPS:
                problems.append(f"step {i}: soles closer than {MIN_FOOT_GAP_M} m")
            if LineString([footsteps[i - 1][:2], pose[:2]]).intersects(blocked):
                problems.append(f"step {i}: a blocked cell between the feet")
            if LineString([footsteps[i - 2][:2], pose[:2]]).intersects(blocked):
                problems.append(f"step {i}: the swing foot passes over a blocked cell")
            before = (footsteps[i - 2][:2] + footsteps[i - 1][:2]) / 2
            after = (footsteps[i - 1][:2] + pose[:2]) / 2
            if LineString([before, after]).distance(blocked) < body_clearance_m - EPS:
                problems.append(f"step {i}: body track closer than {body_clearance_m} m to a blocked cell")
    if goal is not None:
        a, b = footsteps[-2], footsteps[-1]
        mid = (a[:2] + b[:2]) / 2
        mean_yaw = a[2] + ((b[2] - a[2] + math.pi) % (2 * math.pi) - math.pi) / 2
        yaw_err = abs((mean_yaw - goal[2] + math.pi) % (2 * math.pi) - math.pi)
        if Point(mid).distance(Point(goal[:2])) > GOAL_TOLERANCE_M + EPS or yaw_err > GOAL_TOLERANCE_YAW_RAD + EPS:
            problems.append("the final stance misses the goal")
    return problems


# -- run --------------------------------------------------------------------------------------------
def percentiles_ms(values_s) -> dict:
    if len(values_s) == 0:
        return {"p50": None, "p95": None, "max": None}
    ms = np.asarray(values_s) * 1e3
    return {"p50": round(float(np.percentile(ms, 50)), 1), "p95": round(float(np.percentile(ms, 95)), 1),
            "max": round(float(ms.max()), 1)}


def run(maps_per_category: int, seed: int = 0, png_dir: Path | None = None, categories=CATEGORIES,
        verbose: bool = True, figure: Path | None = None) -> dict:
    rows = []
    shown = {}  # category -> (grid, plan, goal) of its first valid plan, for --figure
    load_before = os.getloadavg()
    with tempfile.TemporaryDirectory() as tmp:
        for category in categories:
            rng = np.random.default_rng([seed, CATEGORIES.index(category)])
            for index in range(maps_per_category):
                problem = make_problem(category, index, rng)
                loaded = write_and_load(problem, Path(tmp))
                grid = GridMap.from_map(loaded)
                c0 = time.process_time()
                t0 = time.perf_counter()
                planner = FootstepPlanner(grid)
                t1 = time.perf_counter()
                plan = planner.plan(goal_xyyaw_w=problem["goal"], start_feet_xyyaw_w=problem["start_feet"],
                                    stance_side=problem["stance_side"])
                t2 = time.perf_counter()
                c2 = time.process_time()
                ok = plan.status is PlanStatus.SUCCESS
                blocked, extent = blocked_geometry(loaded)
                problems = check_plan(plan.footsteps_xyyaw_w, plan.foot_sides, blocked, extent,
                                      start_feet=problem["start_feet"], stance_side=problem["stance_side"],
                                      goal=problem["goal"] if ok else None)
                rows.append(dict(category=category, index=index, status=plan.status.value, ok=ok, problems=problems,
                                 plan_s=t2 - t0, query_s=t2 - t1, cpu_s=c2 - c0, steps=plan.num_steps,
                                 expansions=plan.expansions))
                if ok and problems and verbose:
                    print(f"{category} {index}: claimed success, checker: {problems[:3]}")
                if ok and not problems and category not in shown:
                    shown[category] = (grid, plan, problem["goal"])
                if png_dir is not None and (not ok or problems):
                    png_dir.mkdir(parents=True, exist_ok=True)
                    plot_plan(grid, plan, png_dir / f"{category}_{index:03d}_{plan.status.value}.png",
                              goal_xyyaw_w=problem["goal"])
    if figure is not None and shown:
        draw_figure(shown, figure)
    by_category = defaultdict(list)
    for row in rows:
        by_category[row["category"]].append(row)
    per_category = {}
    for category, group in by_category.items():
        valid = [r for r in group if r["ok"] and not r["problems"]]
        per_category[category] = {
            "maps": len(group), "valid_pct": round(100 * len(valid) / len(group), 1),
            "plan_ms": percentiles_ms([r["plan_s"] for r in group]),
            "query_ms": percentiles_ms([r["query_s"] for r in group]),
            "plan_cpu_ms": percentiles_ms([r["cpu_s"] for r in group]),
            "steps_p50": int(np.median([r["steps"] for r in valid])) if valid else None,
            "expansions": {"p50": int(np.percentile([r["expansions"] for r in group], 50)),
                           "p95": int(np.percentile([r["expansions"] for r in group], 95)),
                           "max": int(max(r["expansions"] for r in group))},
            "failures": dict(Counter(r["status"] for r in group if not r["ok"])),
        }
        if verbose:
            c = per_category[category]
            print(f"{category:16s} valid {c['valid_pct']:5.1f} %  plan ms p50 {c['plan_ms']['p50']:6.1f} "
                  f"p95 {c['plan_ms']['p95']:6.1f} max {c['plan_ms']['max']:7.1f}  query ms p95 "
                  f"{c['query_ms']['p95']:6.1f}  CPU ms p50/p95 {c['plan_cpu_ms']['p50']}/{c['plan_cpu_ms']['p95']}  steps p50 {c['steps_p50']}  expansions p50/p95/max "
                  f"{c['expansions']['p50']}/{c['expansions']['p95']}/{c['expansions']['max']}  failures {c['failures']}")
    valid_all = sum(r["ok"] and not r["problems"] for r in rows)
    result = {
        "maps": len(rows),
        "valid_pct": round(100 * valid_all / len(rows), 2),
        "false_successes": sum(r["ok"] and bool(r["problems"]) for r in rows),
        "plans_with_violations": sum(bool(r["problems"]) for r in rows),
        "plan_ms": percentiles_ms([r["plan_s"] for r in rows]),
        "query_ms": percentiles_ms([r["query_s"] for r in rows]),
        "plan_cpu_ms": percentiles_ms([r["cpu_s"] for r in rows]),
        "per_category": per_category,
        "cpu_count": os.cpu_count(),
        "loadavg_1m_before_after": [round(load_before[0], 2), round(os.getloadavg()[0], 2)],
        "seed": seed,
    }
    return result


def draw_figure(shown: dict, path: Path) -> None:
    """One plan per category side by side (the docs' picture)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(2, 4, figsize=(20, 9.5), dpi=110)
    for ax, (category, (grid, plan, goal)) in zip(axes.ravel(), shown.items()):
        plot_plan(grid, plan, None, goal_xyyaw_w=goal, ax=ax,
                  title=f"{category}: {plan.num_steps} steps, {plan.planning_time_s * 1e3:.0f} ms")
    for ax in axes.ravel()[len(shown):]:
        ax.axis("off")
    fig.tight_layout()
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path)
    plt.close(fig)


def main(argv=None) -> dict:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--maps-per-category", type=int, default=34, help="34 x 7 = 238 maps (default)")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--categories", default=",".join(CATEGORIES))
    parser.add_argument("--png-dir", type=Path, default=None, help="write a picture of each failed or invalid plan")
    parser.add_argument("--figure", type=Path, default=None, help="write one valid plan per category to this PNG")
    args = parser.parse_args(argv)
    result = run(args.maps_per_category, args.seed, args.png_dir, tuple(args.categories.split(",")),
                 figure=args.figure)
    print("RESULT " + json.dumps(result))
    return result


if __name__ == "__main__":
    main()
