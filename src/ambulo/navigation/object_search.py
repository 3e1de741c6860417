"""``ObjectSearch``: walk to an object named by its label ("walk to the chair") with a detector on the
head camera, on top of the ``Navigator``'s public API.

    search = ObjectSearch(nav, Detector(path), "armchair")
    result = search.run(time_limit_s=180)     # found | fell | timeout | not_found
    result.object_xy_m, result.stance_xy_m

The loop, as ObjectNav agents do it with a classical stack:

1. **Look around** where it stands (a full turn on the spot: ``walker.scan``): every
   ``detect_period_s`` the frame goes through the detector; each confident detection of the label
   becomes a world point (``object_goal.localize``: its mask's depths, the frame's estimated camera
   pose) fused into an ``ObjectMap``; every processed frame's depth marks the floor cells its rays
   crossed as seen (``coverage``).
2. **Explore** while no track of the label is confirmed: the nearest reachable cell (known free,
   room for the body) not yet seen, or on the edge of the unknown (online maps), is the next goal;
   the robot walks there (``Navigator.set_goal``/``run``, stopped early when a track is confirmed)
   and looks around again.
3. **Approach** the confirmed track: a stance ``standoff_goal`` away from its point on the side it
   was seen from (renewed if more views move the point), then turn on the spot to face it and stand.

The controller only reads the navigator's snapshots and calls ``set_goal``/``run``/``step`` and the
walker's ``scan``/``stand``: the same code runs in every mode (oracle, mapping, full); in full mode
the points come from the VO's camera pose, never the true one.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
from scipy import ndimage

from ..maps import Grid2D
from ..utils.validate import Checked
from .navigator import Navigator, NavSnapshot
from .object_goal import LocalizeCfg, ObjectMap, ObjectMapCfg, ObjectTrack, localize, standoff_goal, wrap_rad


@dataclass(kw_only=True)
class ObjectSearchCfg(Checked):
    detect_period_s: float = 0.3
    """Simulated time between frames sent to the detector, s."""
    score_threshold: float = 0.5
    """Detections of the label below this score are ignored."""
    localize: LocalizeCfg = field(default_factory=LocalizeCfg)
    objects: ObjectMapCfg = field(default_factory=ObjectMapCfg)
    scan_rate_rad_s: float = 0.8
    """Yaw rate of a look-around, rad/s (the policy turns on the spot at 0.3-0.9 rad/s)."""
    scan_turn_rad: float = 2 * math.pi
    """A look-around turns this far, rad."""
    coverage_range_m: float = 4.5
    """Depth rays mark floor cells seen up to this far, m (the detector finds furniture up to ~5 m)."""
    explore_clearance_m: float = 0.3
    """An exploration goal or stance has this much room to occupied cells, m."""
    explore_min_distance_m: float = 1.5
    """Exploration goals nearer than this are not worth a walk, m."""
    near_seen_m: float = 1.0
    """After a look-around the cells this close to the robot count as seen: the camera (pitched down,
    ~49 deg of view) misses the floor within ~1.6 m but shows anything 0.3 m tall beyond ~0.8 m, so
    without this the ring around every place looked from stayed "unseen" and drew the next goal back, m."""
    explore_unseen_min: int = 12
    """A frontier cell needs this many unseen cells within 0.25 m (not one stray cell)."""
    leg_time_s: float = 40.0
    """Longest walk to one exploration goal or stance before choosing again, s."""
    standoff_range_m: tuple[float, float] = (0.3, 0.6)
    """The stance's distance from the object's point, m (ObjectNav success: within 1 m)."""
    renew_goal_m: float = 0.4
    """The track's point moving this far renews the stance, m."""
    face_tolerance_rad: float = 0.12
    """Facing turns stop within this of the object's bearing, rad."""
    face_gain_per_s: float = 1.5
    settle_s: float = 0.6
    """Standing still this long after facing ends the search, s."""
    max_approach_tries: int = 3
    """Stances tried for one track before it is given up, s."""


@dataclass
class ObjectSearchResult:
    status: str
    """found | fell | timeout | not_found"""
    label: str
    object_xy_m: np.ndarray | None
    """The localized object point the robot went to (world frame), m."""
    views: int
    stance_xy_m: np.ndarray | None
    time_s: float
    detections: int
    """Detections of the label fused over the episode."""
    tracks: list[dict]
    """Every track of the label: point, views, mean score."""
    legs: list[dict] = field(default_factory=list)
    """Each walk: kind (explore/approach), goal and the navigator's status at its end."""


class ObjectSearch:
    """Search for and walk to an object of ``label`` (module docstring)."""

    def __init__(self, nav: Navigator, detector, label: str, cfg: ObjectSearchCfg | None = None):
        self.nav, self.detector, self.label = nav, detector, label
        self.cfg = cfg = cfg or ObjectSearchCfg()
        if label not in detector.categories:
            raise ValueError(f"the detector knows {detector.categories}, not {label!r}")
        if not hasattr(nav.walker, "scan"):
            raise ValueError("object search turns on the spot to look around: the walker needs scan() (the policy walker)")
        self.objects = ObjectMap(cfg.objects)
        grid = nav.occupancy
        self.seen = np.zeros(grid.shape, bool)
        self._geometry = Grid2D(occupancy=np.zeros(grid.shape, np.int8), origin_xy_m=grid.origin_xy_m,
                                resolution_m=grid.resolution_m)
        self._last_detect_s = -math.inf
        self.detections = 0
        self.legs: list[dict] = []
        self._failed_xy: list[np.ndarray] = []
        nav.add_observer(self._observe, images=True)

    # -- perception -------------------------------------------------------------------------------
    def _observe(self, snap: NavSnapshot) -> None:
        est, frame = snap.estimate, snap.frame
        if frame is None or not est.tracked or est.pose_wc is None:
            return  # an untracked or bridged pose has no camera pose to place points with
        if snap.time_s - self._last_detect_s < self.cfg.detect_period_s:
            return
        self._last_detect_s = snap.time_s
        depth = frame.depth_m.numpy()
        k = frame.intrinsics.numpy()
        pose_wc = np.asarray(est.pose_wc, float)
        self._mark_seen(depth, k, pose_wc)
        rgb = frame.rgb.numpy()
        f = self._scale(rgb.shape)
        small = rgb if f == 1 else rgb.reshape(rgb.shape[0] // f, f, rgb.shape[1] // f, f, 3).mean((1, 3)).astype(np.uint8)
        if getattr(self.detector, "needs_depth", False):  # an RGB-D detector: the depth at the same scale,
            # one pixel of each f x f block (a block's mean would blend an object's depth with the floor's)
            small_depth = depth if f == 1 else depth[f // 2::f, f // 2::f][:small.shape[0], :small.shape[1]]
            if getattr(self.detector, "needs_height", False):  # and the height above the floor, the same pixels
                from ambulo.detection.height import height_above_floor_m

                height = height_above_floor_m(depth, k, np.linalg.inv(pose_wc))
                small_height = height if f == 1 else height[f // 2::f, f // 2::f][:small.shape[0], :small.shape[1]]
                det = self.detector(small, small_depth, small_height)
            else:
                det = self.detector(small, small_depth)
        else:
            det = self.detector(small)
        for j, (label, score) in enumerate(zip(det.labels, det.scores)):
            if label != self.label or score < self.cfg.score_threshold:
                continue
            box = det.boxes_px[j] * f
            mask = None if det.masks is None else det.masks[j].repeat(f, 0).repeat(f, 1)
            point = localize(depth, k, pose_wc, box, mask, self.cfg.localize)
            if point is not None and self.objects.add(label, point, float(score)) is not None:
                self.detections += 1

    def _scale(self, shape) -> int:
        """The integer factor that brings a frame within the detector's canvas (2: 320x240 for 160x128)."""
        ch, cw = self.detector.canvas_hw
        f = max(1, math.ceil(shape[0] / ch), math.ceil(shape[1] / cw))
        if shape[0] % f or shape[1] % f:
            raise ValueError(f"a {shape[1]}x{shape[0]} frame does not shrink by a whole factor into the detector's "
                             f"{cw}x{ch} canvas")
        return f

    def _mark_seen(self, depth: np.ndarray, k: np.ndarray, pose_wc: np.ndarray, stride: int = 8) -> None:
        """Floor cells under the rays of every ``stride``-th pixel, camera to hit (or to the range), seen."""
        d = depth[::stride, ::stride].astype(np.float64)
        v, u = np.mgrid[0:depth.shape[0]:stride, 0:depth.shape[1]:stride]
        rng = self.cfg.coverage_range_m
        d = np.where(np.isfinite(d) & (d > 0), d, np.inf)
        cam = np.stack([(u - k[0, 2]) / k[0, 0], (v - k[1, 2]) / k[1, 1], np.ones_like(d, float)], -1).reshape(-1, 3)
        dirs_w = cam @ pose_wc[:3, :3].T
        origin = pose_wc[:3, 3]
        flat = np.hypot(dirs_w[:, 0], dirs_w[:, 1])
        reach = np.minimum(d.reshape(-1) * flat, rng)  # the ray's floor-plane length, m
        ok = flat > 1e-6
        heading = dirs_w[ok, :2] / flat[ok, None]
        r = self.seen.shape
        steps = np.arange(0.0, rng + 1e-9, self._geometry.resolution_m)
        pts = origin[None, None, :2] + heading[:, None, :] * steps[None, :, None]
        keep = steps[None, :] <= reach[ok, None]
        iy, ix = self._geometry.cells_of(pts[keep])
        inside = (iy >= 0) & (iy < r[0]) & (ix >= 0) & (ix < r[1])
        self.seen[iy[inside], ix[inside]] = True

    # -- decisions --------------------------------------------------------------------------------
    def _passable(self) -> tuple[Grid2D, np.ndarray]:
        """The navigator's map and its cells with ``explore_clearance_m`` to occupied cells, connected
        to the robot's cell (unknown cells pass: the navigator plans through them optimistically)."""
        grid = self.nav.occupancy
        occupied = grid.occupied()
        clear = ndimage.distance_transform_edt(~occupied) * grid.resolution_m >= self.cfg.explore_clearance_m
        labels, _ = ndimage.label(clear)
        iy, ix = grid.cell_of(self.nav.estimate.xyyaw[:2])
        if not (0 <= iy < grid.shape[0] and 0 <= ix < grid.shape[1]):
            return grid, np.zeros(grid.shape, bool)
        region = labels[iy, ix]
        if region == 0:  # the robot stands nearer an obstacle than the clearance: its nearest clear component
            dist, (ny, nx) = ndimage.distance_transform_edt(labels == 0, return_indices=True)
            region = labels[ny[iy, ix], nx[iy, ix]]
        return grid, (labels == region) & (region > 0)

    def exploration_goal(self) -> np.ndarray | None:
        """The nearest reachable, known-free cell that is unseen or borders the unknown (module docstring)."""
        grid, reach = self._passable()
        unknown = grid.unknown()
        unseen = ~self.seen | ndimage.binary_dilation(unknown, iterations=2)
        crowd = ndimage.uniform_filter(unseen.astype(np.float32), size=11) * 121
        cand = reach & ~unknown & unseen & (crowd >= self.cfg.explore_unseen_min)
        iy, ix = np.nonzero(cand)
        if not len(iy):
            return None
        xs, ys = grid.cell_center_xy_m(iy, ix)
        here = self.nav.estimate.xyyaw[:2]
        d = np.hypot(xs - here[0], ys - here[1])
        ok = d >= self.cfg.explore_min_distance_m
        for bad in self._failed_xy:
            ok &= np.hypot(xs - bad[0], ys - bad[1]) > 0.6
        if not ok.any():
            return None
        k = int(np.flatnonzero(ok)[np.argmin(d[ok])])
        return np.array([xs[k], ys[k]])

    # -- actions ----------------------------------------------------------------------------------
    def _time_left(self) -> float:
        return self._deadline_s - self.nav.world.time_s

    def _steps_while(self, keep_going) -> None:
        while keep_going() and self._time_left() > 0 and not self.nav.world.fell:
            self.nav.step()

    def look_around(self) -> None:
        """Turn on the spot by ``scan_turn_rad`` (stopping early once a track of the label is confirmed)."""
        nav, c = self.nav, self.cfg
        turned = [0.0, float(nav.estimate.xyyaw[2])]
        t_cap = nav.world.time_s + 1.5 * c.scan_turn_rad / c.scan_rate_rad_s

        def going() -> bool:
            nav.walker.scan(c.scan_rate_rad_s)
            yaw = float(nav.estimate.xyyaw[2])  # held while untracked: the time cap ends the turn then
            turned[0] += abs(wrap_rad(yaw - turned[1]))
            turned[1] = yaw
            return turned[0] < c.scan_turn_rad and nav.world.time_s < t_cap and not self.objects.confirmed(self.label)

        self._steps_while(going)
        nav.walker.stand()
        if turned[0] >= c.scan_turn_rad:
            g = self._geometry
            xy = nav.estimate.xyyaw[:2]
            cx, cy = g.cell_center_xy_m(*np.indices(self.seen.shape))
            self.seen |= np.hypot(cx - xy[0], cy - xy[1]) <= c.near_seen_m

    def _walk(self, goal_xy, yaw, kind: str, until=None) -> str:
        nav = self.nav
        nav.set_goal(goal_xy, yaw)
        limit = min(self.cfg.leg_time_s, self._time_left())
        status = nav.run(until=until, max_time_s=max(limit, 0.0))
        if not nav.done:
            nav.walker.stand()
        self.legs.append({"kind": kind, "goal_xy_m": [float(v) for v in goal_xy], "status": status,
                          "end_s": nav.world.time_s})
        return status

    def face(self, point_xy) -> None:
        """Turn on the spot to face ``point_xy`` (estimated pose), then stand ``settle_s``."""
        nav, c = self.nav, self.cfg

        def error() -> float:
            x, y, yaw = nav.estimate.xyyaw
            return wrap_rad(math.atan2(point_xy[1] - y, point_xy[0] - x) - yaw)

        def turning() -> bool:
            err = error()
            if abs(err) < c.face_tolerance_rad:
                return False
            rate = float(np.clip(c.face_gain_per_s * err, -0.9, 0.9))
            nav.walker.scan(math.copysign(max(abs(rate), 0.3), rate))
            return True

        self._steps_while(turning)
        nav.walker.stand()
        t_end = nav.world.time_s + c.settle_s
        self._steps_while(lambda: nav.world.time_s < t_end or nav.world.base_speed_m_s() > nav.cfg.standing_speed_m_s)

    def approach(self, track: ObjectTrack) -> str:
        """Walk to a stance facing ``track`` and face it: 'found', or why not."""
        c = self.cfg
        tried: list[np.ndarray] = []
        for _ in range(c.max_approach_tries):
            point = track.point_w[:2].copy()
            grid, reach = self._passable()
            for bad in tried:
                reach &= np.hypot(*(np.stack(grid.cell_center_xy_m(*np.indices(grid.shape)), 0)
                                    - bad[:, None, None])) > 0.3
            stance = standoff_goal(point, self.nav.estimate.xyyaw[:2], grid, distance_range_m=c.standoff_range_m,
                                   clearance_m=c.explore_clearance_m, reachable=reach)
            if stance is None:  # an online map that has not seen the floor by the object: plan through the unknown
                stance = standoff_goal(point, self.nav.estimate.xyyaw[:2], grid, distance_range_m=c.standoff_range_m,
                                       clearance_m=c.explore_clearance_m, reachable=reach, avoid_unknown=False)
            if stance is None:
                return "no_stance"
            goal, yaw = stance
            tried.append(goal)
            status = self._walk(goal, yaw, "approach",
                                until=lambda n, p=point: float(np.linalg.norm(track.point_w[:2] - p)) > c.renew_goal_m)
            if self.nav.world.fell:
                return "fell"
            if self._time_left() <= 0:
                return "timeout"
            if status == "arrived":
                self.face(track.point_w[:2])
                return "found" if not self.nav.world.fell else "fell"
            if float(np.linalg.norm(track.point_w[:2] - point)) > c.renew_goal_m:
                tried.pop()  # the point moved: not a failed stance
        return "unreachable"

    def run(self, time_limit_s: float = 180.0) -> ObjectSearchResult:
        nav = self.nav
        t0 = nav.world.time_s
        self._deadline_s = t0 + time_limit_s
        status, target = "not_found", None
        given_up: list[ObjectTrack] = []
        self.look_around()
        while self._time_left() > 0 and not nav.world.fell:
            tracks = [t for t in self.objects.confirmed(self.label) if t not in given_up]
            if tracks:
                here = nav.estimate.xyyaw[:2]
                target = min(tracks, key=lambda t: float(np.linalg.norm(t.point_w[:2] - here)))
                outcome = self.approach(target)
                if outcome in ("found", "fell", "timeout"):
                    status = outcome
                    break
                given_up.append(target)
                continue
            goal = self.exploration_goal()
            if goal is None:
                break
            leg = self._walk(goal, None, "explore", until=lambda n: bool(
                [t for t in self.objects.confirmed(self.label) if t not in given_up]))
            if leg == "arrived" and float(np.linalg.norm(nav.estimate.xyyaw[:2] - goal)) > 0.6:
                self._failed_xy.append(goal)  # stopped short (a stance the navigator moved): not there again
            if leg in ("arrived",):
                self.look_around()
            elif not [t for t in self.objects.confirmed(self.label) if t not in given_up]:
                self._failed_xy.append(goal)
                self.look_around()
        if nav.world.fell:
            status = "fell"
        elif status == "not_found" and self._time_left() <= 0:
            status = "timeout"
        tracks = [{"point_w": t.point_w.tolist(), "views": t.views, "score": t.score}
                  for t in self.objects.tracks if t.label == self.label]
        return ObjectSearchResult(status=status, label=self.label,
                                  object_xy_m=None if target is None else target.point_w[:2].copy(),
                                  views=0 if target is None else target.views,
                                  stance_xy_m=nav.world.true_pose()[:2].copy() if status == "found" else None,
                                  time_s=nav.world.time_s - t0, detections=self.detections, tracks=tracks,
                                  legs=self.legs)


__all__ = ["ObjectSearch", "ObjectSearchCfg", "ObjectSearchResult"]
