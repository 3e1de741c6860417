"""Exact Euclidean shortest paths for a disc robot among rectangles and discs: the tangent graph.

A robot of radius r may put its centre where every footprint is at least r away. The obstacles of
its centre are the footprints grown by r: a rectangle becomes a rounded rectangle (its corners
circles of radius r), a disc a disc of radius R + r. A shortest path among such convex obstacles
is straight except where it wraps around one of those circles, so it is made of segments tangent
to two circles (or from an end to a circle) and arcs of the circles between tangent points. The
tangent graph holds every such segment that keeps clearance r (``segment_clearance_m``) and every
arc between neighbouring tangent points on one circle that does (checked at 16 points of the arc);
Dijkstra on it gives the exact geodesic, up to rounding (tangent points are accepted 1e-9 m inside
the clearance) and arcs' samples.

The circle-to-circle part is built once per clearance (``TangentGraph``); a query adds the
tangents from its two ends.
"""

from __future__ import annotations

import math

import numpy as np
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import dijkstra

from .apartment_geometry import Footprints, point_clearance_m, rect_corners_xy_m, segment_clearance_m

EPS_M = 1e-9
"""Tangent points sit exactly at the clearance; accepted this far inside it (rounding)."""
ARC_CHECKS = 16


def _bitangents(ca, ra, cb, rb):
    """The (up to) 4 common tangents of circle pairs (M,2),(M,) and (M,2),(M,): points on a and b,
    each (4, M, 2), and (4, M) bool where the tangent exists."""
    d_vec = cb - ca
    d = np.hypot(d_vec[:, 0], d_vec[:, 1])
    u = d_vec / np.maximum(d, 1e-300)[:, None]
    perp = np.stack([-u[:, 1], u[:, 0]], -1)
    pa, pb, ok = [], [], []
    for s in (1.0, -1.0):  # external, internal
        c = (ra - s * rb) / np.maximum(d, 1e-12)  # coincident centres (d = 0) have no tangent
        h = np.sqrt(np.maximum(1.0 - c * c, 0.0))
        for side in (1.0, -1.0):
            n = c[:, None] * u + side * h[:, None] * perp
            pa.append(ca + ra[:, None] * n)
            pb.append(cb + s * rb[:, None] * n)
            ok.append((c * c <= 1.0) & (d > 1e-12))
    return np.stack(pa), np.stack(pb), np.stack(ok)


def _point_tangents(p, cc, cr):
    """Tangent points from point p (2,) to circles (C,2),(C,): (2, C, 2) and (2, C) bool."""
    v = p - cc
    d = np.hypot(v[:, 0], v[:, 1])
    base = np.arctan2(v[:, 1], v[:, 0])
    alpha = np.arccos(np.clip(cr / np.maximum(d, 1e-300), -1.0, 1.0))
    pts = np.stack([cc + cr[:, None] * np.stack([np.cos(base + s * alpha), np.sin(base + s * alpha)], -1)
                    for s in (1.0, -1.0)])
    ok = np.broadcast_to(d >= cr, (2, len(cr)))
    return pts, ok


class TangentGraph:
    """The circle-to-circle part of the tangent graph of ``fp`` for clearance ``clearance_m``."""

    def __init__(self, fp: Footprints, clearance_m: float):
        self.fp, self.r = fp, float(clearance_m)
        corners = rect_corners_xy_m(fp.rect_center_xy_m, fp.rect_half_xy_m, fp.rect_yaw_rad).reshape(-1, 2)
        self.cc = np.concatenate([corners, fp.disc_center_xy_m])
        self.cr = np.concatenate([np.full(len(corners), self.r), fp.disc_radius_m + self.r])
        # drop the circles no point of which keeps the clearance (a table leg's corners under its
        # top, wall corners inside another wall), tried at 64 points of each
        theta = np.linspace(0.0, 2 * np.pi, 64, endpoint=False)
        ring = self.cc[:, None] + self.cr[:, None, None] * np.stack([np.cos(theta), np.sin(theta)], -1)
        live = self._clear(ring.reshape(-1, 2)).reshape(ring.shape[:2]).any(1)
        self.cc, self.cr = self.cc[live], self.cr[live]
        num = len(self.cc)
        i, j = np.triu_indices(num, 1)
        pa, pb, ok = _bitangents(self.cc[i], self.cr[i], self.cc[j], self.cr[j])
        ci, cj = np.broadcast_to(i, ok.shape)[ok], np.broadcast_to(j, ok.shape)[ok]
        pa, pb = pa[ok], pb[ok]
        good = (self._clear(pa) & self._clear(pb))
        pa, pb, ci, cj = pa[good], pb[good], ci[good], cj[good]
        good = segment_clearance_m(fp, pa, pb) >= self.r - EPS_M
        self.pts = np.concatenate([pa[good], pb[good]])
        self.circle = np.concatenate([ci[good], cj[good]])
        m = int(good.sum())
        self.seg_a, self.seg_b = np.arange(m), np.arange(m) + m
        self.seg_len = np.hypot(*(pa[good] - pb[good]).T) if m else np.zeros(0)

    def _clear(self, pts: np.ndarray) -> np.ndarray:
        return point_clearance_m(self.fp, pts) >= self.r - EPS_M

    def _arcs(self, pts, circle):
        """Arcs between angularly neighbouring points of each circle (cyclic), where every checked
        point of the arc keeps the clearance: (from, to, length)."""
        if len(pts) == 0:
            return np.zeros(0, int), np.zeros(0, int), np.zeros(0)
        ang = np.arctan2(pts[:, 1] - self.cc[circle, 1], pts[:, 0] - self.cc[circle, 0])
        order = np.lexsort((ang, circle))
        c_sorted, a_sorted = circle[order], ang[order]
        nxt = np.roll(np.arange(len(order)), -1)
        # the next point on the same circle; the last of a circle wraps to its first
        starts = np.flatnonzero(np.r_[True, c_sorted[1:] != c_sorted[:-1]])
        ends = np.r_[starts[1:], len(order)] - 1
        nxt[ends] = starts
        frm, to = order, order[nxt]
        dtheta = np.mod(a_sorted[nxt] - a_sorted, 2 * np.pi)
        single = frm == to
        frm, to, dtheta = frm[~single], to[~single], dtheta[~single]
        c = circle[frm]
        t = np.linspace(0.0, 1.0, ARC_CHECKS + 2)[1:-1]
        theta = ang[frm][:, None] + dtheta[:, None] * t[None]
        samples = self.cc[c][:, None] + self.cr[c][:, None, None] * np.stack([np.cos(theta), np.sin(theta)], -1)
        ok = self._clear(samples.reshape(-1, 2)).reshape(samples.shape[:2]).all(1)
        return frm[ok], to[ok], (self.cr[c] * dtheta)[ok]

    def shortest_path(self, start_xy_m, goal_xy_m, arc_step_rad: float = math.radians(5.0)):
        """(length m, (K, 2) path) from start to goal with the clearance, or (inf, None). The path's
        arcs are drawn as points on the circle grown by 1/cos(step/2), so its chords keep the clearance."""
        start, goal = np.asarray(start_xy_m, float), np.asarray(goal_xy_m, float)
        if not (self._clear(start[None])[0] and self._clear(goal[None])[0]):
            return math.inf, None
        n0 = len(self.pts)
        rows, cols, w = [self.seg_a], [self.seg_b], [self.seg_len]
        if segment_clearance_m(self.fp, start, goal) >= self.r - EPS_M:
            rows.append(np.array([n0])), cols.append(np.array([n0 + 1])), w.append(np.array([np.hypot(*(goal - start))]))
        end_nodes = [start, goal]
        new_pts, new_circle = [], []
        offset = n0 + 2
        for k, p in enumerate(end_nodes):
            tp, ok = _point_tangents(p, self.cc, self.cr)
            cidx = np.broadcast_to(np.arange(len(self.cc)), ok.shape)[ok]
            tp = tp[ok]
            good = self._clear(tp)
            tp, cidx = tp[good], cidx[good]
            good = segment_clearance_m(self.fp, p, tp) >= self.r - EPS_M
            tp, cidx = tp[good], cidx[good]
            idx = offset + np.arange(len(tp))
            rows.append(np.full(len(tp), n0 + k)), cols.append(idx), w.append(np.hypot(*(tp - p).T))
            new_pts.append(tp), new_circle.append(cidx)
            offset += len(tp)
        all_pts = np.concatenate([self.pts, start[None], goal[None], *new_pts])
        all_circle = np.concatenate([self.circle, [-1, -1], *new_circle])
        # arcs again over every point on a circle, the ends' tangent points included
        on_circle = np.flatnonzero(all_circle >= 0)
        fa, fb, fl = self._arcs(all_pts[on_circle], all_circle[on_circle])
        rows.append(on_circle[fa]), cols.append(on_circle[fb]), w.append(fl)
        rows, cols, w = (np.concatenate(v) for v in (rows, cols, w))
        n = len(all_pts)
        # each node pair appears once (a coo matrix would add repeats); arcs run counter-clockwise
        # from a to b, and are travelled either way: an undirected graph (weights > 0 to be stored)
        graph = coo_matrix((w + 1e-12, (rows, cols)), shape=(n, n)).tocsr()
        dist, pred = dijkstra(graph, directed=False, indices=n0, return_predecessors=True)
        if not np.isfinite(dist[n0 + 1]):
            return math.inf, None
        nodes = [n0 + 1]
        while nodes[-1] != n0:
            nodes.append(int(pred[nodes[-1]]))
        nodes = nodes[::-1]
        path = [all_pts[nodes[0]]]
        for a, b in zip(nodes[:-1], nodes[1:]):
            if all_circle[a] >= 0 and all_circle[a] == all_circle[b]:  # an arc: points on the grown circle
                c = all_circle[a]
                ta = math.atan2(*(all_pts[a] - self.cc[c])[::-1])
                tb = math.atan2(*(all_pts[b] - self.cc[c])[::-1])
                ccw, cw = (tb - ta) % (2 * math.pi), (ta - tb) % (2 * math.pi)
                travelled = dist[b] - dist[a]  # the arc the graph took, whichever way round
                sweep = ccw if abs(self.cr[c] * ccw - travelled) <= abs(self.cr[c] * cw - travelled) else -cw
                steps = max(int(math.ceil(abs(sweep) / arc_step_rad)), 1)
                grown = self.cr[c] / math.cos(abs(sweep) / steps / 2)
                for s in range(steps):
                    th = ta + sweep * (s + 0.5) / steps
                    path.append(self.cc[c] + grown * np.array([math.cos(th), math.sin(th)]))
            path.append(all_pts[b])
        return float(dist[n0 + 1] - 1e-12 * (len(nodes) - 1)), np.array(path)


__all__ = ["TangentGraph"]
