"""Shortest paths with the robot's clearance through an apartment, and the start/goal sampler.

The free space of a robot of radius ``clearance_m`` is the set of points whose exact distance to
every footprint (``apartment_geometry``) is at least ``clearance_m``: the occupancy inflated by the
clearance, without the grid's rounding. The geodesic between two points is the length of the
shortest path in it, computed exactly on the tangent graph (``apartment_tangents``).

The sampler picks candidates with a grid first: Dijkstra on the 8-connected graph of cell centres
whose clearance is at least ``sqrt(clearance_m**2 + resolution_m**2 / 2)`` (a straight step between
two such centres, at most a diagonal long, keeps ``clearance_m`` all along: the nearest obstacle
point of any point on it is at least ``clearance_m`` from both ends). That grid distance is never
shorter than the geodesic and at most 1/cos(22.5 deg) = 1.082 times it in the open, so goals whose
grid distance lies in [min, max / cos(22.5 deg)] are tried, and each is kept iff its exact
geodesic is in [min, max].
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import dijkstra

from .apartment_geometry import Footprints, point_clearance_m
from .apartment_tangents import TangentGraph


@dataclass(frozen=True)
class StartGoal:
    """A navigation episode's ends and the geodesic between them."""

    start_pose: tuple[float, float, float]
    """Start (x m, y m, yaw rad) in the world."""
    goal_xy_m: tuple[float, float]
    geodesic_m: float
    """Length of ``path_xy_m``: the shortest path with the clearance, m."""
    path_xy_m: np.ndarray
    """(K, 2) float64 that path, start to goal, m: straight segments and arcs (drawn every 5 deg on
    circles grown so that the chords keep the clearance; its length exceeds ``geodesic_m`` by
    under 0.1 %)."""
    clearance_m: float


class PathFinder:
    """Clearance fields and shortest paths over one apartment's footprints.

    Args:
      fp: the obstacle footprints of the body band.
      origin_xy_m, resolution_m, shape: the occupancy grid's cells (``maps.Grid2D`` convention).
      inside_xy_m: (x_min, y_min, x_max, y_max): only points inside are walkable (the apartment).
    """

    def __init__(self, fp: Footprints, origin_xy_m, resolution_m: float, shape, inside_xy_m):
        self.fp, self.resolution_m, self.shape = fp, float(resolution_m), tuple(shape)
        self.origin_xy_m = (float(origin_xy_m[0]), float(origin_xy_m[1]))
        ny, nx = self.shape
        xs = self.origin_xy_m[0] + (np.arange(nx) + 0.5) * self.resolution_m
        ys = self.origin_xy_m[1] + (np.arange(ny) + 0.5) * self.resolution_m
        self.centers_xy_m = np.stack(np.meshgrid(xs, ys, indexing="xy"), -1)  # (ny, nx, 2)
        x0, y0, x1, y1 = inside_xy_m
        self.inside = ((self.centers_xy_m[..., 0] > x0) & (self.centers_xy_m[..., 0] < x1)
                       & (self.centers_xy_m[..., 1] > y0) & (self.centers_xy_m[..., 1] < y1))
        self.clearance_field_m = np.where(self.inside, point_clearance_m(fp, self.centers_xy_m), 0.0)
        """(ny, nx) exact distance from each cell centre to the nearest footprint (0 outside), m."""
        self.inside_xy_m = tuple(float(v) for v in inside_xy_m)
        self._graphs: dict[float, tuple[np.ndarray, object]] = {}
        self._tangents: dict[float, TangentGraph] = {}

    def node_threshold_m(self, clearance_m: float) -> float:
        """Clearance a cell centre needs to be a node of the grid graph (see the module docstring)."""
        return math.sqrt(clearance_m ** 2 + self.resolution_m ** 2 / 2)

    def walkable(self, clearance_m: float) -> np.ndarray:
        """(ny, nx) bool: cell centres that are nodes of the grid graph for ``clearance_m``."""
        return self.clearance_field_m >= self.node_threshold_m(clearance_m)

    def _graph(self, clearance_m: float):
        key = round(float(clearance_m), 9)
        if key not in self._graphs:
            walk = self.walkable(clearance_m)
            ny, nx = self.shape
            idx = np.arange(ny * nx).reshape(ny, nx)
            rows, cols, weights = [], [], []
            for dy, dx in ((0, 1), (1, 0), (1, 1), (1, -1)):
                a = (slice(0, ny - dy), slice(max(-dx, 0), nx - max(dx, 0)))
                b = (slice(dy, ny), slice(max(dx, 0), nx - max(-dx, 0)))
                ok = walk[a] & walk[b]
                rows.append(idx[a][ok])
                cols.append(idx[b][ok])
                weights.append(np.full(int(ok.sum()), self.resolution_m * math.hypot(dy, dx)))
            rows, cols, weights = np.concatenate(rows), np.concatenate(cols), np.concatenate(weights)
            graph = coo_matrix((weights, (rows, cols)), shape=(ny * nx, ny * nx)).tocsr()
            self._graphs[key] = (walk, graph)
        return self._graphs[key]

    def grid_distances(self, start_cell: tuple[int, int], clearance_m: float):
        """(ny, nx) 8-connected path lengths from ``start_cell`` (inf where unreachable) and the
        predecessor of each node (-9999 where none)."""
        walk, graph = self._graph(clearance_m)
        node = start_cell[0] * self.shape[1] + start_cell[1]
        dist, pred = dijkstra(graph, directed=False, indices=node, return_predecessors=True)
        return dist.reshape(self.shape), pred

    def tangents(self, clearance_m: float) -> TangentGraph:
        """The tangent graph for ``clearance_m`` (built once per clearance)."""
        key = round(float(clearance_m), 9)
        if key not in self._tangents:
            self._tangents[key] = TangentGraph(self.fp, clearance_m)
        return self._tangents[key]

    def shortest_path(self, start_xy_m, goal_xy_m, clearance_m: float) -> tuple[float, np.ndarray | None]:
        """(geodesic m, (K, 2) path) from ``start_xy_m`` to ``goal_xy_m`` with ``clearance_m``: exact
        (``apartment_tangents``); (inf, None) if an end lacks the clearance or they are not connected."""
        start, goal = np.asarray(start_xy_m, float), np.asarray(goal_xy_m, float)
        x0, y0, x1, y1 = self.inside_xy_m
        if not all(x0 < p[0] < x1 and y0 < p[1] < y1 for p in (start, goal)):
            return math.inf, None
        return self.tangents(clearance_m).shortest_path(start, goal)

    def _cell(self, xy) -> tuple[int, int] | None:
        ix = int(math.floor((xy[0] - self.origin_xy_m[0]) / self.resolution_m))
        iy = int(math.floor((xy[1] - self.origin_xy_m[1]) / self.resolution_m))
        return (iy, ix) if 0 <= iy < self.shape[0] and 0 <= ix < self.shape[1] else None

    def sample_start_goal(self, rng: np.random.Generator, min_geodesic_m: float, max_geodesic_m: float,
                          clearance_m: float, max_starts: int = 50, goals_per_start: int = 8) -> StartGoal:
        """A start pose and a goal, both cell centres walkable with ``clearance_m``, connected, with
        a geodesic in [min_geodesic_m, max_geodesic_m]; RuntimeError if ``max_starts`` starts find none."""
        walk, _ = self._graph(clearance_m)
        cells = np.argwhere(walk)
        if len(cells) == 0:
            raise RuntimeError(f"no cell of this apartment is walkable with clearance {clearance_m} m")
        centers = self.centers_xy_m.reshape(-1, 2)
        for _ in range(max_starts):
            start = tuple(int(v) for v in cells[rng.integers(len(cells))])
            dist, pred = self.grid_distances(start, clearance_m)
            # the taut length is at most the grid length and at least 1/cos(22.5 deg) of it
            near = np.flatnonzero((dist.ravel() >= min_geodesic_m)
                                  & (dist.ravel() <= max_geodesic_m / math.cos(math.pi / 8)))
            if len(near) == 0:
                continue
            for goal_node in rng.permutation(near)[:goals_per_start]:
                sx, sy = centers[start[0] * self.shape[1] + start[1]]
                gx, gy = centers[goal_node]
                length, path = self.shortest_path((sx, sy), (gx, gy), clearance_m)
                if min_geodesic_m <= length <= max_geodesic_m:
                    yaw = float(rng.uniform(-math.pi, math.pi))
                    return StartGoal((float(sx), float(sy), yaw), (float(gx), float(gy)), length, path,
                                     float(clearance_m))
        raise RuntimeError(f"no start and goal {min_geodesic_m}-{max_geodesic_m} m apart with clearance "
                           f"{clearance_m} m in {max_starts} tries; widen the range or lower the clearance")


def path_length_m(path_xy_m: np.ndarray) -> float:
    """Length of a polyline (K, 2), m (0 for fewer than two points)."""
    xy = np.asarray(path_xy_m, float).reshape(-1, 2)
    return float(np.linalg.norm(np.diff(xy, axis=0), axis=1).sum())


__all__ = ["PathFinder", "StartGoal", "path_length_m"]


def walk_poses(path_xy_m: np.ndarray, yaw0_rad: float, max_frames: int, *, turn_rad: float = math.radians(6.0),
               step_m: float = 0.05) -> list[tuple[float, float, float]]:
    """A scripted camera walk along ``path_xy_m`` (K, 2): (x m, y m, yaw rad) per frame, turning on the spot
    towards the next waypoint by at most ``turn_rad`` a frame, then walking to it by ``step_m`` a frame
    (defaults: 60 deg/s and 0.5 m/s at 10 Hz). Drives the head camera's VO checks without the walking policy."""
    x, y = (float(v) for v in path_xy_m[0])
    yaw, out, k = yaw0_rad, [], 1
    while len(out) < max_frames and k < len(path_xy_m):
        dx, dy = path_xy_m[k, 0] - x, path_xy_m[k, 1] - y
        dist = math.hypot(dx, dy)
        if dist < 1e-6:
            k += 1
            continue
        turn = (math.atan2(dy, dx) - yaw + math.pi) % (2 * math.pi) - math.pi
        if abs(turn) > math.radians(1.0):
            yaw += math.copysign(min(abs(turn), turn_rad), turn)
        else:
            step = min(step_m, dist)
            x, y = x + step * math.cos(yaw), y + step * math.sin(yaw)
            k += step == dist
        out.append((x, y, yaw))
    return out
