"""The footstep lattice: the discrete successor set, its reach constants, the points that stand
for a step in the collision test, the progress bound of the heuristic, and the straight walk.
Built once per (config, map resolution) and cached.

Frames: a foot's frame has x forward (heel to toe) and y to the robot's left, origin at the
centre of the sole rectangle. A step places the swing foot at ``(dx, dy, dyaw)`` in the stance
foot's frame: ``dx`` is the step length, ``|dy|`` the step width, ``dyaw`` the yaw change.
Sides are +1 (left) and -1 (right); the swing foot is always on the other side of the stance
foot, so from a left stance ``dy < 0`` and from a right stance ``dy > 0``.
"""

from __future__ import annotations

import bisect
import dataclasses
import itertools
import math
from dataclasses import dataclass

import numpy as np
from scipy.spatial import ConvexHull

LEFT = 1
RIGHT = -1
SEGMENT_SPACING_CELLS = 1.5
"""Largest gap between test points on a leg segment, in cells. A point of the segment is then
within 0.75 cell of a point that is at least one cell from every occupied cell, so the whole
segment keeps >= 0.25 cell of clearance (any clearance > 0 keeps it off the obstacles)."""


def wrap_angle(angle_rad):
    """Angle(s) wrapped to [-pi, pi)."""
    return (np.asarray(angle_rad) + np.pi) % (2 * np.pi) - np.pi


def wrap_angle_scalar(angle_rad: float) -> float:
    """``wrap_angle`` of one float, in plain Python (the walks' per-step arithmetic)."""
    return (angle_rad + math.pi) % (2 * math.pi) - math.pi


def compose(pose_xyyaw, rel_xyyaw) -> np.ndarray:
    """(..., 3) world pose of ``rel_xyyaw`` given in the frame ``pose_xyyaw`` (x m, y m, yaw rad)."""
    pose, rel = np.asarray(pose_xyyaw, float), np.asarray(rel_xyyaw, float)
    c, s = np.cos(pose[..., 2]), np.sin(pose[..., 2])
    return np.stack([pose[..., 0] + c * rel[..., 0] - s * rel[..., 1],
                     pose[..., 1] + s * rel[..., 0] + c * rel[..., 1],
                     wrap_angle(pose[..., 2] + rel[..., 2])], axis=-1)


def relative(pose_xyyaw, other_xyyaw) -> np.ndarray:
    """(..., 3) ``other_xyyaw`` expressed in the frame ``pose_xyyaw``; ``compose``'s inverse."""
    pose, other = np.asarray(pose_xyyaw, float), np.asarray(other_xyyaw, float)
    c, s = np.cos(pose[..., 2]), np.sin(pose[..., 2])
    dx, dy = other[..., 0] - pose[..., 0], other[..., 1] - pose[..., 1]
    return np.stack([c * dx + s * dy, -s * dx + c * dy, wrap_angle(other[..., 2] - pose[..., 2])], axis=-1)


def footprint_samples(foot_size_m: tuple[float, float], spacing_m: float) -> np.ndarray:
    """(M, 2) points on a regular grid over the sole rectangle, edges and corners included, at most
    ``spacing_m`` apart along x and y, in the foot frame, m. Every point of the sole is then within
    ``spacing_m / sqrt(2)`` of a sample."""
    length, width = foot_size_m
    xs = np.linspace(-length / 2, length / 2, math.ceil(length / spacing_m - 1e-9) + 1)
    ys = np.linspace(-width / 2, width / 2, math.ceil(width / spacing_m - 1e-9) + 1)
    return np.stack(np.meshgrid(xs, ys, indexing="ij"), axis=-1).reshape(-1, 2)


def rectangles_overlap(rel_xyyaw: np.ndarray, foot_size_m: tuple[float, float], gap_m: float) -> np.ndarray:
    """(K,) bool: does a sole at ``rel_xyyaw`` (K, 3), in the frame of a sole at the origin, come
    closer than ``gap_m`` to it? Separating-axis test on the two rectangles grown by ``gap_m / 2``."""
    half = np.array(foot_size_m) / 2 + gap_m / 2
    c, s = np.cos(rel_xyyaw[:, 2]), np.sin(rel_xyyaw[:, 2])
    d = rel_xyyaw[:, :2]
    # axes of the origin sole (x, y), then of the moved sole (u, v)
    sep_x = np.abs(d[:, 0]) > half[0] + half[0] * np.abs(c) + half[1] * np.abs(s)
    sep_y = np.abs(d[:, 1]) > half[1] + half[0] * np.abs(s) + half[1] * np.abs(c)
    sep_u = np.abs(d[:, 0] * c + d[:, 1] * s) > half[0] + half[0] * np.abs(c) + half[1] * np.abs(s)
    sep_v = np.abs(-d[:, 0] * s + d[:, 1] * c) > half[1] + half[0] * np.abs(s) + half[1] * np.abs(c)
    return ~(sep_x | sep_y | sep_u | sep_v)


def step_costs(rel_xyyaw: np.ndarray, cfg) -> np.ndarray:
    """(K,) cost of steps ``rel_xyyaw`` (K, 3) (swing foot in the stance frame): 1 per step, plus
    penalties for turning, for a width away from the nominal one and for stepping backwards."""
    return (1.0 + cfg.yaw_cost_per_rad * np.abs(rel_xyyaw[:, 2])
            + cfg.width_cost_per_m * np.abs(np.abs(rel_xyyaw[:, 1]) - cfg.start_width_m)
            + cfg.backward_step_cost * (rel_xyyaw[:, 0] < 0))


def steps_within_limits(rel_xyyaw: np.ndarray, stance_sides: np.ndarray, cfg) -> np.ndarray:
    """(K,) bool: are steps ``rel_xyyaw`` (K, 3) from stance feet of ``stance_sides`` (K,) within the
    length, width and yaw limits, with the swing foot on the far side and clear of the stance sole?"""
    eps = 1e-9
    width = -stance_sides * rel_xyyaw[:, 1]  # > 0 when the swing foot is on the correct side
    return ((rel_xyyaw[:, 0] >= cfg.step_length_range_m[0] - eps) & (rel_xyyaw[:, 0] <= cfg.step_length_range_m[1] + eps)
            & (width >= cfg.step_width_range_m[0] - eps) & (width <= cfg.step_width_range_m[1] + eps)
            & (np.abs(rel_xyyaw[:, 2]) <= cfg.max_step_yaw_rad + eps)
            & ~rectangles_overlap(rel_xyyaw, cfg.foot_size_m, cfg.min_foot_gap_m))


def step_within_limits(stance_xyyaw, new_xyyaw, stance_side: int, cfg) -> bool:
    """``steps_within_limits`` for one step from the stance foot ``stance_xyyaw`` (3,) of
    ``stance_side`` to ``new_xyyaw`` (3,), in plain Python: the walks test one step at a time,
    where numpy's per-call overhead would be most of the cost."""
    c, s = math.cos(stance_xyyaw[2]), math.sin(stance_xyyaw[2])
    dx, dy = new_xyyaw[0] - stance_xyyaw[0], new_xyyaw[1] - stance_xyyaw[1]
    rx, ry, ryaw = c * dx + s * dy, -s * dx + c * dy, wrap_angle_scalar(new_xyyaw[2] - stance_xyyaw[2])
    eps = 1e-9
    width = -stance_side * ry
    if not (cfg.step_length_range_m[0] - eps <= rx <= cfg.step_length_range_m[1] + eps
            and cfg.step_width_range_m[0] - eps <= width <= cfg.step_width_range_m[1] + eps
            and abs(ryaw) <= cfg.max_step_yaw_rad + eps):
        return False
    # the separating-axis test of ``rectangles_overlap``
    hx, hy = cfg.foot_size_m[0] / 2 + cfg.min_foot_gap_m / 2, cfg.foot_size_m[1] / 2 + cfg.min_foot_gap_m / 2
    cr, sr = math.cos(ryaw), math.sin(ryaw)
    reach_x = hx + hx * abs(cr) + hy * abs(sr)
    reach_y = hy + hx * abs(sr) + hy * abs(cr)
    return (abs(rx) > reach_x or abs(ry) > reach_y or abs(rx * cr + ry * sr) > reach_x
            or abs(-rx * sr + ry * cr) > reach_y)


@dataclass(frozen=True, eq=False)
class Lattice:
    """Successor tables for each stance side, the check points and the reach constants."""

    actions: dict[int, np.ndarray]
    """stance side -> (K, 3) swing-foot pose (dx m, dy m, dyaw rad) in the stance foot's frame."""
    costs: np.ndarray
    """(K,) cost of each action (``step_costs``; >= 1), the same on both sides (mirror images)."""
    sole_points_m: np.ndarray
    """(M, 2) sole samples in the foot frame, at most one cell apart (``footprint_samples``)."""
    between_fractions: np.ndarray
    """(B,) interior points of the segment from the stance foot's centre to the swing foot's (the
    legs straddle no obstacle), as fractions of its length."""
    swing_fractions: np.ndarray
    """(J,) interior points of the swing segment (old to new position of the swing foot, which
    must pass over no obstacle) as fractions of its length. Both fraction sets are at most
    ``SEGMENT_SPACING_CELLS`` apart on segments up to ``max_step_reach_m`` / ``max_swing_m``."""
    max_step_reach_m: float
    """D_pair: max distance between the centres of consecutive footsteps (stance to swing)."""
    max_swing_m: float
    """D_swing: max distance one foot moves in one swing (footstep k-1 to k+1); the feet's
    midpoint moves half as far per step."""
    progress_m: np.ndarray
    """(HEADING_BINS + 1, HEADING_BINS + 1, TABLE_STEPS + 1) float: entry [j0, jf, n] bounds how
    far a chain of n footsteps (footstep k to k + n) can advance along a fixed direction when
    footstep k's heading starts j0 pi / HEADING_BINS away from it and footstep k + n must end
    jf pi / HEADING_BINS away (``progress_table``), m."""


def build_lattice(cfg, resolution_m: float) -> Lattice:
    """The lattice of ``cfg`` (a ``FootstepPlannerCfg``) for a map of ``resolution_m`` cells,
    built once per distinct (config, resolution) in a process (it takes a few hundred ms)."""
    # the fields' values are numbers, tuples and bools (dataclasses.astuple deep-copies: ms a call)
    key = (tuple(getattr(cfg, f.name) for f in dataclasses.fields(cfg)), float(resolution_m))
    if key not in _LATTICES:
        if len(_LATTICES) >= 8:
            _LATTICES.pop(next(iter(_LATTICES)))
        _LATTICES[key] = _build_lattice(cfg, resolution_m)
    return _LATTICES[key]


_LATTICES: dict[tuple, Lattice] = {}


def _build_lattice(cfg, resolution_m: float) -> Lattice:
    combos = np.array(list(itertools.product(cfg.step_lengths_m, cfg.step_widths_m, cfg.step_yaws_rad)), float)
    # side +1 (left stance): swing foot to the right (dy = -width); mirrored for a right stance
    left = np.stack([combos[:, 0], -combos[:, 1], combos[:, 2]], axis=1)
    left = left[steps_within_limits(left, np.full(len(left), LEFT), cfg)]
    right = left * np.array([1.0, -1.0, -1.0])

    # the start stance (feet start_width_m apart, parallel) acts as one more "previous step"
    start_rel = np.array([[0.0, -cfg.start_width_m, 0.0]])
    reach = float(np.hypot(*np.concatenate([left, start_rel])[:, :2].T).max())
    # one swing moves a foot from footstep k-1 to k+1 past the stance foot k. With a left stance k,
    # footstep k-1 is the right foot that k was placed from (k = (k-1) + a, a a right-stance action,
    # so k-1 sits at -R(-yaw_a) t_a in k's frame) or the right start foot at (0, -start_width).
    prev_in_k = np.concatenate([-_rotate(right[:, :2], -right[:, 2]), start_rel[:, :2]])
    swing = float(np.hypot(*(left[:, None, :2] - prev_in_k[None, :, :]).reshape(-1, 2).T).max())

    progress = progress_table(left, cfg.max_step_yaw_rad)
    spacing_m = SEGMENT_SPACING_CELLS * resolution_m
    num_between = max(0, math.ceil(reach / spacing_m - 1e-9) - 1)
    num_swing = max(0, math.ceil(swing / spacing_m - 1e-9) - 1)
    return Lattice(actions={LEFT: left, RIGHT: right}, costs=step_costs(left, cfg),
                   sole_points_m=footprint_samples(cfg.foot_size_m, resolution_m),
                   between_fractions=np.arange(1, num_between + 1) / (num_between + 1),
                   swing_fractions=np.arange(1, num_swing + 1) / (num_swing + 1),
                   max_step_reach_m=reach, max_swing_m=swing, progress_m=progress)


HEADING_BINS = 64
TABLE_STEPS = 48
"""Steps in ``Lattice.progress_m``; beyond them every step adds at most the full rate."""


def progress_table(left_actions: np.ndarray, max_step_yaw_rad: float) -> np.ndarray:
    """The ``Lattice.progress_m`` table from the actions of a left stance (K, 3) and their mirror images.

    Consecutive steps alternate sides, so a pair of them (left-stance action then right-stance
    action, or the reverse) moves a footstep to the one two later by t1 + R(yaw1) t2: forward up
    to two step lengths, sideways only the difference of two widths. Along a direction at angle b
    from the first footstep's heading that advances at most S2(b), the support function of all
    pair displacements (on 256 angles, plus the most it can change between two of them);
    U2(x) = max over |b| >= x of S2(b) does not increase with x. Per step we count u = U2 / 2:
    for a pair starting at b, u(b) + u(b - dyaw_max) >= U2(b), so a chain of footsteps advances at
    most the sum of u over its steps, plus ``c1`` = max (S1 - u) for an odd step out (S1: one
    action). Footstep k's heading is at least max(b0 - k dyaw, bf - (n - k) dyaw, 0) away from
    the direction when the chain starts b0 away and its footstep n must end bf away; angles are
    rounded down to the table's grid (which only raises u).

    Returns (HEADING_BINS + 1, HEADING_BINS + 1, TABLE_STEPS + 1): [j0, jf, n] for b0 = j0 pi / HEADING_BINS,
    bf = jf pi / HEADING_BINS, n steps."""
    right_actions = left_actions * np.array([1.0, -1.0, -1.0])
    singles = np.concatenate([left_actions[:, :2], right_actions[:, :2]])
    pairs = np.concatenate([
        (first[:, None, :2] + _rotate(second[None, :, :2], first[:, None, 2])).reshape(-1, 2)
        for first, second in ((left_actions, right_actions), (right_actions, left_actions))])
    angles = np.linspace(-np.pi, np.pi, 257)
    e = np.stack([np.cos(angles), np.sin(angles)])
    grid = np.linspace(0.0, np.pi, HEADING_BINS + 1)

    def envelope(points):  # U on the grid; a support function's maximum lies on the convex hull
        hull = points[ConvexHull(points).vertices]
        support = (hull @ e).max(axis=0) + np.hypot(*points.T).max() * (angles[1] - angles[0]) / 2
        return np.array([support[np.abs(angles) >= x - 1e-12].max() for x in grid])

    per_step = envelope(pairs) / 2
    odd_step_out = max(float((envelope(singles) - per_step).max()), 0.0)
    step = np.pi / HEADING_BINS
    table = np.zeros((HEADING_BINS + 1, HEADING_BINS + 1, TABLE_STEPS + 1))
    # u of the heading max(b - m dyaw, 0) rounded down to the grid, for b on the grid and m steps:
    # (HEADING_BINS + 1, TABLE_STEPS + 1). Since u does not increase with the heading, u of
    # max(b0 - k dyaw, bf - (n - k) dyaw, 0) is the smaller of the two u's.
    m = np.arange(TABLE_STEPS + 1)
    u = per_step[np.maximum(np.floor((grid[:, None] - max_step_yaw_rad * m) / step + 1e-9), 0).astype(int)]
    for n in range(1, TABLE_STEPS + 1):  # steps k = 0 .. n - 1: u[j0, k] against u[jf, n - k]
        table[:, :, n] = np.minimum(u[:, None, :n], u[None, :, n:0:-1]).sum(axis=2) + odd_step_out
    return table


STEER_CANDIDATES = ((math.inf, 1.0, 1.0), (0.3, 1.0, 1.0), (0.0, 1.0, 1.0), (0.1, 1.0, 1.0), (math.inf, 0.5, 0.5),
                    (0.0, 1.0, 0.5), (0.1, 1.0, 0.5), (0.0, 1.0, 0.0), (0.1, 1.0, 0.0), (0.1, 0.5, 0.0),
                    (0.1, 0.25, 0.0))
"""``follow_path``'s steps to try in turn: (lookahead m, capped by the walk's; share of the turn
towards that point; share of the step length). The first steers smoothly; the later ones keep
closer to the path, shorten the step or turn on the spot. Lookahead 0 means: turn to the path's
own direction and side-step towards it (for narrow passages, where the body's channel is a few
cells wide and cutting in at an angle would leave it)."""
SIDE_STEP_M = 0.05
"""Largest sideways shift of the body per step towards the path (the step width then lies
within ``start_width_m`` +- this)."""


STALL_STEPS = 14
"""``follow_path`` gives up after this many steps without progress along the path (turning
half a circle on the spot takes 11)."""


def follow_path(stance_xyyaw: np.ndarray, stance_side: int, path_xy: np.ndarray, cfg, *, lookahead_m: float,
                goal_xyyaw=None, body_free=None, max_steps: int = 400) -> np.ndarray:
    """(n, 3) footsteps that walk the body along the polyline ``path_xy`` (m, world frame),
    turning while walking, from the stance foot ``stance_xyyaw`` of ``stance_side`` (the other
    foot moves first). Nothing is checked against the map here: the planner checks these steps
    like any other (this is Hybrid A*'s analytic expansion, Dolgov et al. 2008, for feet).

    The body pose (the feet's midpoint and heading) steers by pure pursuit: each step it turns
    towards the point ``lookahead_m`` farther along the path by at most 0.95 ``max_step_yaw_rad``
    and moves ahead by up to 0.95 of the longest step, times the cosine of the heading error (so
    it turns on the spot only while the path lies behind it); each foot lands beside its body
    pose at half ``start_width_m``, and a step that would break the step limits is retried
    shorter and with less turn. ``body_free(x0, y0, x1, y1) -> bool`` (optional) says whether the
    feet's midpoint may move from one point to another; a step whose body track it refuses
    steers to a nearer point of the path instead (so the walk does not cut a corner into a wall). With ``goal_xyyaw`` the walk ends at the goal's position, turns
    to its yaw and brings the feet side by side (the goal stance); else it ends at the path's end.
    Returns fewer footsteps (possibly none) if it runs out of steps or of valid ones."""
    half = cfg.start_width_m / 2
    # plain Python lists and math: a walk takes one step at a time, where numpy's per-call
    # overhead (microseconds) would be most of the cost
    path = np.asarray(path_xy, float)
    px_list, py_list = path[:, 0].tolist(), path[:, 1].tolist()
    seg_x = [b - a for a, b in zip(px_list, px_list[1:])]
    seg_y = [b - a for a, b in zip(py_list, py_list[1:])]
    seg_len = [math.hypot(a, b) for a, b in zip(seg_x, seg_y)]
    arc = [0.0]
    for length in seg_len:
        arc.append(arc[-1] + length)
    num_seg = len(seg_len)
    end_x, end_y = px_list[-1], py_list[-1]
    turn_max, step_max = 0.95 * cfg.max_step_yaw_rad, 0.95 * cfg.step_length_range_m[1]
    stance = [float(v) for v in stance_xyyaw]
    side = -stance_side  # the foot that moves next
    # the body pose as if the stance foot stood in the nominal stance
    bx, by, byaw = stance[0] + math.sin(stance[2]) * stance_side * half, stance[1] - math.cos(stance[2]) * stance_side * half, stance[2]
    along = 0.0  # arc length of the body's progress along the path
    feet: list[list[float]] = []

    def point_at(s_m: float) -> tuple[float, float]:
        k = bisect.bisect_right(arc, s_m) - 1
        if k >= num_seg or num_seg == 0:
            return end_x, end_y
        k = max(k, 0)
        t = 0.0 if seg_len[k] == 0 else min(max((s_m - arc[k]) / seg_len[k], 0.0), 1.0)
        return px_list[k] + t * seg_x[k], py_list[k] + t * seg_y[k]

    mid = [bx, by]  # the feet's midpoint (the nominal one at the start)

    def place(x: float, y: float, yaw: float) -> bool:
        """Put the moving foot beside the body pose (x, y, yaw) if the step keeps the limits and
        the body's track stays free."""
        nonlocal stance, side, bx, by, byaw, mid
        foot = [x - math.sin(yaw) * side * half, y + math.cos(yaw) * side * half, wrap_angle_scalar(yaw)]
        new_mid = [0.5 * (stance[0] + foot[0]), 0.5 * (stance[1] + foot[1])]
        if not step_within_limits(stance, foot, -side, cfg):
            return False
        if body_free is not None and not body_free(mid[0], mid[1], new_mid[0], new_mid[1]):
            return False
        feet.append(foot)
        stance, side, bx, by, byaw, mid = foot, -side, x, y, yaw, new_mid
        return True

    best_left_m, stalled = math.inf, 0
    for _ in range(max_steps):
        dist_end = math.hypot(end_x - bx, end_y - by)
        left_m = arc[-1] - along + dist_end
        if left_m < best_left_m - 0.01:
            best_left_m, stalled = left_m, 0
        elif dist_end > 0.25 * cfg.goal_tolerance_m:
            stalled += 1
            if stalled > STALL_STEPS:
                break  # no progress along the path: the search takes over from here
        if dist_end <= 0.25 * cfg.goal_tolerance_m:
            if goal_xyyaw is None:
                break
            # at the goal: turn on the spot to its yaw, then bring the feet together
            err = wrap_angle_scalar(float(goal_xyyaw[2]) - byaw)
            if abs(err) <= 1e-9:
                place(bx, by, byaw)
                break
            turn = min(max(err, -turn_max), turn_max)
            if not (place(bx, by, byaw + turn) or place(bx, by, byaw + turn / 2)):
                break
            continue
        # progress: the path's closest point to the body, no farther back than the last one and
        # at most two steps ahead of it
        best_d2, best_s = math.inf, along
        for k in range(max(bisect.bisect_left(arc, along) - 1, 0), num_seg):
            if arc[k] > along + 2 * step_max:
                break
            if arc[k + 1] < along:
                continue
            t = ((bx - px_list[k]) * seg_x[k] + (by - py_list[k]) * seg_y[k]) / max(seg_len[k] ** 2, 1e-12)
            s_m = min(max(arc[k] + min(max(t, 0.0), 1.0) * seg_len[k], along), along + 2 * step_max)
            qx, qy = point_at(s_m)
            d2 = (qx - bx) ** 2 + (qy - by) ** 2
            if d2 < best_d2:
                best_d2, best_s = d2, s_m
        along = best_s
        for ahead_m, turn_scale, length_scale in STEER_CANDIDATES:
            shift = 0.0
            if ahead_m == 0.0:  # along the path's direction, side-stepping onto it
                (px, py), (qx, qy) = point_at(along), point_at(along + 0.1)
                if dist_end <= 0.1 or (px, py) == (qx, qy):
                    continue
                direction = math.atan2(qy - py, qx - px)
                heading_err = wrap_angle_scalar(direction - byaw)
                off = -math.sin(direction) * (bx - px) + math.cos(direction) * (by - py)  # left of the path
                shift = -min(max(off, -SIDE_STEP_M), SIDE_STEP_M)
            else:
                ahead_m = min(ahead_m, lookahead_m)
                tx, ty = (end_x, end_y) if dist_end <= ahead_m else point_at(along + ahead_m)
                heading_err = wrap_angle_scalar(math.atan2(ty - by, tx - bx) - byaw)
            yaw = byaw + min(max(heading_err, -turn_max), turn_max) * turn_scale
            length = min(step_max * max(math.cos(heading_err), 0.0) * length_scale, dist_end)
            x = bx + length * math.cos(yaw) - shift * math.sin(yaw)
            y = by + length * math.sin(yaw) + shift * math.cos(yaw)
            if length >= dist_end - 1e-9 and abs(heading_err) <= turn_max:
                x, y = end_x, end_y  # the last step lands the body on the end of the path
            if place(x, y, yaw):  # else: steer to a nearer point of the path, or step shorter
                break
        else:
            break
    return np.array(feet, float).reshape(-1, 3)


def _rotate(xy: np.ndarray, yaw_rad) -> np.ndarray:
    c, s = np.cos(yaw_rad), np.sin(yaw_rad)
    return np.stack([c * xy[..., 0] - s * xy[..., 1], s * xy[..., 0] + c * xy[..., 1]], axis=-1)
