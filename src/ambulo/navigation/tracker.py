"""A path tracker for a velocity-commanded walker: body path + pose estimate -> (vx, vy, yaw_rate).

Pure pursuit (Coulter 1992, CMU-RI-TR-92-01) with the refinements a walking robot needs:

- progress is the arc length of the nearest path point, searched only a little behind and ahead
  of the last one, so a path that doubles back is never short-cut;
- the carrot is ``lookahead_m`` further along; the heading error ``alpha`` is its bearing;
- beyond ``turn_in_place_rad`` of heading error the robot turns on the spot (vx = 0): a humanoid
  walking forward while facing away swings wide;
- the speed falls with the heading error (cos^2), with the turn the path makes within
  ``slow_turn_window_m`` ahead (a sharp bend is taken slowly), and near the end of a path that
  ends at the goal (``v <= goal_gain * distance``), so it stops on the goal instead of overshooting;
- the yaw rate is proportional to the heading error (a unicycle's heading loop), clipped to the
  walker's range;
- at a final goal, within ``stop_radius_m`` it commands zero and reports ``arrived`` (latched,
  unless pushed farther than ``rearm_radius_m``).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..utils.validate import Checked


@dataclass(kw_only=True)
class TrackerCfg(Checked):
    cruise_speed_m_s: float = 0.55
    """Forward speed on straight open stretches, m/s (the policy was trained on -1..1)."""
    min_speed_m_s: float = 0.12
    """Forward speed floor while walking (below it the policy shuffles), m/s."""
    max_yaw_rate_rad_s: float = 0.9
    yaw_gain_per_s: float = 1.6
    """yaw rate = gain * heading error, rad/s per rad."""
    lookahead_m: float = 0.45
    turn_in_place_rad: float = 0.75
    """Heading errors beyond this turn on the spot, rad (43 deg)."""
    resume_walk_rad: float = 0.35
    """... until the error is back under this (hysteresis), rad."""
    slow_turn_window_m: float = 0.8
    """Path length ahead scanned for bends, m."""
    slow_turn_rad: float = 1.2
    """A bend of this much within the window halves the speed, rad."""
    goal_gain_per_s: float = 0.9
    """Near a final goal the speed is at most this times the distance to it."""
    stop_radius_m: float = 0.12
    """At a final goal: closer than this, stop and stand, m (success needs 0.3)."""
    rearm_radius_m: float = 0.25
    """After arriving, walk again only if pushed farther than this, m."""


class PathTracker:
    """Follows one body path at a time (``set_path``); ``command(pose)`` each control step."""

    def __init__(self, cfg: TrackerCfg | None = None):
        self.cfg = cfg or TrackerCfg()
        self.set_path(None, final=False)

    def set_path(self, path_xy: np.ndarray | None, *, final: bool, end_yaw_rad: float | None = None) -> None:
        """Follow ``path_xy`` (K, 2) m, world frame; ``final``: it ends at the goal (stop there);
        ``end_yaw_rad``: at the end of a path that is not final, turn on the spot to this heading (a
        plan that only turns the robot: look where the route goes before walking into the unseen)."""
        self.final = final
        self.end_yaw_rad = end_yaw_rad
        self.arrived = False
        """At a final goal and standing (latched; see the module docstring)."""
        self._turning = False
        if path_xy is None or len(path_xy) == 0:
            self.path = None
            return
        path = np.asarray(path_xy, float).reshape(-1, 2)
        keep = np.concatenate([[True], np.linalg.norm(np.diff(path, axis=0), axis=1) > 1e-6])
        self.path = path[keep]
        seg = np.diff(self.path, axis=0)
        self._seg_len = np.linalg.norm(seg, axis=1)
        self._s = np.concatenate([[0.0], np.cumsum(self._seg_len)])
        self._heading = np.arctan2(seg[:, 1], seg[:, 0]) if len(seg) else np.zeros(0)
        self.progress_m = 0.0
        """Arc length of the path point nearest the robot, m."""
        self.cross_track_m = 0.0

    @property
    def length_m(self) -> float:
        return 0.0 if self.path is None else float(self._s[-1])

    @property
    def remaining_m(self) -> float:
        return self.length_m - self.progress_m

    def point_at(self, s_m: float) -> np.ndarray:
        s = min(max(s_m, 0.0), self.length_m)
        k = int(np.clip(np.searchsorted(self._s, s, side="right") - 1, 0, max(0, len(self.path) - 2)))
        if len(self.path) == 1:
            return self.path[0].copy()
        t = (s - self._s[k]) / max(self._seg_len[k], 1e-9)
        return self.path[k] + min(max(t, 0.0), 1.0) * (self.path[k + 1] - self.path[k])

    def path_ahead(self) -> np.ndarray:
        """(K, 2) the path from the point at ``progress_m`` to its end, m (empty without a path)."""
        if self.path is None:
            return np.zeros((0, 2))
        k = int(np.searchsorted(self._s, self.progress_m, side="right"))
        return np.concatenate([[self.point_at(self.progress_m)], self.path[k:]])

    def starts_turning(self, path_xy: np.ndarray, pose_xyyaw: np.ndarray) -> bool:
        """Whether ``command`` would turn on the spot before walking ``path_xy`` (K, 2) m from its start at
        ``pose_xyyaw``: the carrot ``lookahead_m`` along it (its end if shorter) more than
        ``turn_in_place_rad`` off the heading. The path this tracker follows is not changed."""
        probe = PathTracker(self.cfg)
        probe.set_path(path_xy, final=False)
        if probe.path is None or probe.length_m < 1e-6:
            return False
        alpha = _bearing_error(probe.point_at(self.cfg.lookahead_m), np.asarray(pose_xyyaw[:2], float),
                               float(pose_xyyaw[2]))
        return alpha is not None and abs(alpha) > self.cfg.turn_in_place_rad

    def _project(self, xy: np.ndarray) -> None:
        """Update progress: nearest point on the segments within [-0.3, +1.0] m of the last progress."""
        if len(self.path) == 1:
            self.progress_m, self.cross_track_m = 0.0, float(np.linalg.norm(xy - self.path[0]))
            return
        lo = np.searchsorted(self._s, self.progress_m - 0.3, side="right") - 1
        hi = np.searchsorted(self._s, self.progress_m + 1.0, side="right")
        lo, hi = max(0, int(lo)), min(len(self.path) - 1, max(int(hi), int(lo) + 1))
        a, b = self.path[lo:hi], self.path[lo + 1:hi + 1]
        ab = b - a
        t = np.clip(np.einsum("ij,ij->i", xy - a, ab) / np.maximum(np.einsum("ij,ij->i", ab, ab), 1e-12), 0.0, 1.0)
        near = a + t[:, None] * ab
        d = np.linalg.norm(near - xy, axis=1)
        k = int(np.argmin(d))
        self.progress_m = float(self._s[lo + k] + t[k] * self._seg_len[lo + k])
        self.cross_track_m = float(d[k])

    def _bend_ahead(self) -> float:
        """Largest heading change of the path within the window ahead, rad."""
        if len(self._heading) < 2:
            return 0.0
        lo = int(np.clip(np.searchsorted(self._s, self.progress_m, side="right") - 1, 0, len(self._heading) - 1))
        hi = int(np.searchsorted(self._s, self.progress_m + self.cfg.slow_turn_window_m, side="right"))
        h = self._heading[lo:max(hi, lo + 1)]
        diff = np.angle(np.exp(1j * (h - h[0])))
        return float(np.abs(diff).max())

    def command(self, pose_xyyaw: np.ndarray) -> tuple[float, float, float]:
        """(vx m/s, vy m/s, yaw rate rad/s) in the robot's heading frame; zeros with no path or arrived."""
        c = self.cfg
        if self.path is None:
            return 0.0, 0.0, 0.0
        xy, yaw = np.asarray(pose_xyyaw[:2], float), float(pose_xyyaw[2])
        self._project(xy)
        end = self.path[-1]
        to_end = float(np.linalg.norm(end - xy))
        if self.final:
            if self.arrived and to_end > c.rearm_radius_m:
                self.arrived = False
            if not self.arrived and to_end < c.stop_radius_m:
                self.arrived = True
            if self.arrived:
                return 0.0, 0.0, 0.0
        elif self.remaining_m < 0.05 and to_end < c.stop_radius_m:  # the end of a partial path: wait there
            if self.end_yaw_rad is None:
                return 0.0, 0.0, 0.0
            err = math.atan2(math.sin(self.end_yaw_rad - yaw), math.cos(self.end_yaw_rad - yaw))
            if abs(err) < 0.1:
                return 0.0, 0.0, 0.0
            return 0.0, 0.0, float(np.clip(c.yaw_gain_per_s * err, -c.max_yaw_rate_rad_s, c.max_yaw_rate_rad_s))
        target = self.point_at(self.progress_m + c.lookahead_m)
        if self.remaining_m < c.lookahead_m:
            target = end
        alpha = _bearing_error(target, xy, yaw)
        if alpha is None:
            return 0.0, 0.0, 0.0
        yaw_rate = float(np.clip(c.yaw_gain_per_s * alpha, -c.max_yaw_rate_rad_s, c.max_yaw_rate_rad_s))
        if self._turning and abs(alpha) < c.resume_walk_rad:
            self._turning = False
        elif not self._turning and abs(alpha) > c.turn_in_place_rad:
            self._turning = True
        if self._turning:
            return 0.0, 0.0, yaw_rate
        speed = c.cruise_speed_m_s * math.cos(alpha) ** 2
        speed /= 1.0 + self._bend_ahead() / c.slow_turn_rad
        if self.final:
            speed = min(speed, c.goal_gain_per_s * to_end)
        # short of a final goal (or a path's end), keep a walking pace so the gait does not stall
        speed = max(speed, c.min_speed_m_s if (not self.final or to_end > c.stop_radius_m) else 0.0)
        return float(speed), 0.0, yaw_rate


def _bearing_error(target_xy: np.ndarray, xy: np.ndarray, yaw: float) -> float | None:
    """Bearing of ``target_xy`` from ``xy`` relative to the heading ``yaw``, wrapped to [-pi, pi] rad;
    None when the target is where the robot is."""
    to_target = target_xy - xy
    if float(np.linalg.norm(to_target)) < 1e-6:
        return None
    alpha = math.atan2(to_target[1], to_target[0]) - yaw
    return math.atan2(math.sin(alpha), math.cos(alpha))


__all__ = ["PathTracker", "TrackerCfg"]
