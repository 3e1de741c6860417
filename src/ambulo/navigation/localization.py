"""Localizers: where the navigator thinks the robot is.

- ``OracleLocalizer``: the simulator's pose, every physics step (always tracked).
- ``VoLocalizer``: ``perception.vo.RgbdOdometry`` on the head camera's RGB-D frames with the head
  gyro, started at the true first pose (so its estimate lives in the world frame). Each frame is
  **tracked** or not: tracked when the odometry measured the pose from the image (``TRACKING``,
  ``RECOVERED``, the first frame) and **untracked** when it only coasted it (``LOST``) or restarted
  its map at a coasted pose (``REINITIALIZED``, that frame). While untracked the estimate is not
  updated at all: the navigator must neither steer on nor fuse a coasted pose.

- ``LegVoLocalizer`` (full mode's default): the VO fused with leg-inertial odometry
  (``leg_odometry``). The estimate is the last accepted VO pose composed with the legs' motion since
  that frame, renewed every physics step, so it moves between camera frames and goes on while the
  VO is lost (``source`` "legs": a *bridge*; the navigator bounds how far and how long it walks on
  one, ``NavigatorCfg.bridge_max_m`` / ``bridge_max_s``). A tracked VO pose whose motion since the
  last fix disagrees with the legs' beyond ``outlier_gate_m`` (+ ``outlier_gate_fraction`` of the
  distance walked since) or ``outlier_gate_yaw_deg`` is rejected as an outlier while the bridge is
  within its limits. The legs' motion is the VO's motion prior (its prediction and its coasting
  while lost, so a map restarted after a loss starts where the legs say), and an accepted fix gives
  the legs the VO's attitude and gyro bias. The base pose of a VO fix goes from the head to the
  pelvis through the encoders (the torso's joints), not through the pose measured at the start. A
  bridged pose is never fused into the map: only a VO fix carries a ``pose_wc``.

  **The map as witness** (``bind_map``: the navigator's occupancy map; ``relocalize``). When the VO
  and the legs disagree, one of them is wrong, and neither can say which: the frame's depth is
  matched against the map built so far, around both poses. A confident match picks the pose (the
  VO's, the legs', or the map's best fit) and the fix is taken there (``source`` "map" when it is
  not the VO's own): a VO whose frame has slipped (a wrong relocalisation, a map restarted at a
  coasted pose) is corrected by a planar ``map <- VO`` transform (ROS's ``map -> odom``) that
  every later VO pose goes through, so its fixes agree with the legs again instead of being
  refused until the bridge runs out. Checked on every ``check_rejected_every``-th refused fix and
  every ``verify_period_s`` while tracked (``verify``: the navigator may also ask before it
  declares arrival). **Past the bridge's limits** a VO fix that disagrees with the legs (beyond the
  gate, which keeps growing with the distance walked) is taken only when the map confirms it
  (or, with no map bound, as before: the VO is then the only source); otherwise the frame is
  untracked (state "unverified"), so the robot stands and scans (the navigator's recovery) until
  a frame fits the map: apartment 26 (benchmark of 2026-11-28) took such a fix 2.5 m off and
  "arrived" 3.7 m from its goal. **While the VO is lost** (``lost_check_after_s`` into a bridge,
  and past its limits) the legs' pose is checked against the map: a confident match is a fix
  from the depth and the map alone (``source`` "map"), which renews the bridge.

The base pose (x, y, yaw of the pelvis on the floor) comes from the camera pose through the
pelvis's pose in the camera frame measured once at the start (the head turns little on the
pelvis, so the error is the head's sway: a few cm).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from ..nav.footstep_lattice import compose, relative
from ..perception.frames import RgbdFrame
from ..perception.vo.config import TrackState, VoCfg, head_camera_vo_cfg
from ..perception.vo.odometry import RgbdOdometry
from ..utils.validate import Checked
from .leg_odometry import LegOdometry, LegOdometryCfg
from .relocalize import Match, RelocalizeCfg, apply_correction, correction_between, match_scan, scan_xy_m
from .world import NavWorld

TRACKED_STATES = (TrackState.INITIALIZED, TrackState.TRACKING, TrackState.RECOVERED)
"""VO states whose pose was measured from the image (module docstring)."""


@dataclass
class PoseEstimate:
    """One localization result."""

    xyyaw: np.ndarray
    """(3,) base pose estimate (x m, y m, yaw rad), world frame."""
    tracked: bool
    time_s: float
    pose_wc: np.ndarray | None = None
    """(4, 4) the camera-to-world pose the estimate came from (what a mapper fuses at); None for
    estimates between frames."""
    state: str = "tracking"
    """The localizer's own word for it (the VO's ``TrackState`` value; "rejected" for a VO pose
    refused as an outlier)."""
    source: str = "vo"
    """Where ``xyyaw`` came from: "vo" (a VO fix), "legs" (leg odometry since the last fix),
    "oracle" (the simulator), "none" (untracked: the last estimate, held)."""
    since_fix_m: float = 0.0
    """Distance walked by the legs since the last VO fix, m (0 for a fix)."""
    since_fix_s: float = 0.0
    """Time since the last VO fix, s (0 for a fix)."""


def xyyaw_from_matrix(pose: np.ndarray) -> np.ndarray:
    return np.array([pose[0, 3], pose[1, 3], math.atan2(pose[1, 0], pose[0, 0])])


def is_tracked(result) -> bool:
    """A VO result's tracked flag: its own ``tracked`` if it has one, else its state."""
    flag = getattr(result, "tracked", None)
    return bool(flag) if flag is not None else result.state in TRACKED_STATES


class OracleLocalizer:
    """Ground truth (module docstring)."""

    name = "oracle"
    needs_images = False

    def reset(self, world: NavWorld) -> None:
        self.world = world

    def pose(self) -> np.ndarray:
        return self.world.true_pose()

    def on_frame(self, frame: RgbdFrame | None) -> PoseEstimate:
        pose_wc = frame.pose_wc.numpy() if frame is not None else None
        return PoseEstimate(self.world.true_pose(), True, self.world.time_s, pose_wc, "oracle", "oracle")


@dataclass(kw_only=True)
class VoLocalizerCfg(Checked):
    vo: VoCfg = field(default_factory=head_camera_vo_cfg)
    """ORB tuned for the small, low-contrast head camera (the defaults lose track facing the
    apartments' walls; ``head_camera_vo_cfg`` gives the figures)."""
    use_gyro: bool = True


class VoLocalizer:
    """Visual odometry with the gyro (module docstring). ``odometry``: a ready ``RgbdOdometry``-like
    object (``track(rgb, depth, gyro) -> VoResult``) instead of one built at ``reset``."""

    name = "vo"
    needs_images = True

    def __init__(self, cfg: VoLocalizerCfg | None = None, odometry=None):
        self.cfg = cfg or VoLocalizerCfg()
        self._given = odometry

    def reset(self, world: NavWorld) -> None:
        self.world = world
        self.vo = self._given
        self._base_in_cam = world.base_in_camera()
        self._pose_cam_imu = world.pose_cam_imu() if self.cfg.use_gyro else None
        self._xyyaw = world.true_pose()
        self.tracked = True
        self.last = None

    def pose(self) -> np.ndarray:
        """The last tracked estimate (held between frames and while untracked)."""
        return self._xyyaw

    def on_frame(self, frame: RgbdFrame, motion_cam: np.ndarray | None = None) -> PoseEstimate:
        """Track ``frame``; ``motion_cam``: (4, 4) the camera's motion since the last frame from
        another sensor (``T_prev_cur``), the odometry's motion prior."""
        if self.vo is None:
            self.vo = RgbdOdometry(frame.intrinsics.numpy(), self.cfg.vo, initial_pose_wc=frame.pose_wc.numpy(),
                                   pose_cam_imu=self._pose_cam_imu)
        gyro = frame.gyro if self.cfg.use_gyro else None
        prior = {} if motion_cam is None else {"motion_cam": motion_cam}
        result = self.vo.track(frame.rgb.numpy(), frame.depth_m.numpy(), gyro=gyro, **prior)
        self.last = result
        self.tracked = is_tracked(result)
        state = getattr(result.state, "value", str(result.state))
        if not self.tracked:
            return PoseEstimate(self._xyyaw.copy(), False, frame.time_s, None, state, "none")
        pose_wc = np.asarray(result.pose_wc, float)
        self._xyyaw = xyyaw_from_matrix(pose_wc @ self._base_in_cam)
        return PoseEstimate(self._xyyaw.copy(), True, frame.time_s, pose_wc, state)


@dataclass(kw_only=True)
class LegVoLocalizerCfg(Checked):
    """The fusion's settings (the VO's own are a ``VoLocalizerCfg``)."""

    legs: LegOdometryCfg = field(default_factory=LegOdometryCfg)
    outlier_gate_m: float = 0.15
    """A VO fix farther than this from where the legs put the robot is an outlier, m (the legs drift
    2-3 % of the distance walked; ``benchmarks/leg_odometry.py``)..."""
    outlier_gate_fraction: float = 0.1
    """... plus this share of the distance the legs walked since the last fix."""
    outlier_gate_yaw_deg: float = 10.0
    """A VO fix whose heading differs from the legs' by more than this is an outlier, deg."""
    motion_prior: bool = True
    """Give the VO the legs' camera motion as its prediction (and its coast while lost)."""
    relocalize: RelocalizeCfg = field(default_factory=RelocalizeCfg)
    check_rejected_every: int = 3
    """A refused VO fix is checked against the map on the first and every this-many-th refusal in a
    row (a check costs ~0.1 s of CPU)."""
    verify_period_s: float | None = 2.0
    """While tracked, the fix is checked against the map this often (None: never), s."""
    lost_check_after_s: float = 1.0
    """While the VO is lost (untracked), the legs' pose is checked against the map (every
    ``check_rejected_every``-th frame) once the bridge is this old or past its limits: a confident
    match is a fix from the depth and the map alone, which renews the bridge (a VO lost in a bare
    place, apartments 30 and 84, walked 3 m / 10 s on the legs and then stood lost), s."""
    correct_min_m: float = 0.1
    """A confident match moves an agreeing fix only when it is this far from it, m (the map's
    cells are 5 cm: nearer corrections are its quantisation)..."""
    correct_min_deg: float = 3.0
    """... or turns it by this much, deg."""


class LegVoLocalizer:
    """VO fused with leg-inertial odometry (module docstring); ``vo_cfg`` and ``odometry`` as
    ``VoLocalizer``'s. ``bridge_max_m`` / ``bridge_max_s``:
    past these since the last fix the legs no longer gate the VO (the navigator's bridge limits:
    a bridge that long is not trusted over the camera)."""

    name = "vo+legs"
    needs_images = True

    def __init__(self, cfg: LegVoLocalizerCfg | None = None, vo_cfg: VoLocalizerCfg | None = None, odometry=None, *,
                 bridge_max_m: float = 3.0, bridge_max_s: float = 10.0, map_source=None):
        self.cfg = cfg or LegVoLocalizerCfg()
        self.visual = VoLocalizer(vo_cfg, odometry)
        self.legs = LegOdometry(self.cfg.legs)
        self.bridge_max_m, self.bridge_max_s = bridge_max_m, bridge_max_s
        self.map_source = map_source

    def bind_map(self, map_source) -> None:
        """``map_source()``: the map to relocalise against now (a ``maps.Grid2D``, e.g. the
        navigator's ``mapper.grid``; None while there is none). Module docstring."""
        self.map_source = map_source

    def reset(self, world: NavWorld) -> None:
        self.world = world
        self.visual.reset(world)
        self.legs.reset(world)
        self._pose_imu_cam = np.linalg.inv(self.visual._pose_cam_imu if self.visual._pose_cam_imu is not None
                                           else world.pose_cam_imu())
        self._anchor(world.true_pose(), world.time_s)
        self._prior_from = self._legs_camera()
        self.rejected = 0
        """VO fixes refused as outliers."""
        self._rejected_run = 0
        self._lost_run = 0
        self.unverified = 0
        """VO fixes past the bridge's limits that disagreed with the legs and that the map could not confirm."""
        self._map_vo = np.zeros(3)
        """The planar ``map <- VO`` correction (dx m, dy m, dyaw rad about the world origin)."""
        self.map_checks: list[tuple[float, str, str]] = []
        """(time s, why checked, outcome) of each check against the map: outcome "vo", "legs",
        "map" (the pose the fix was taken at) or the match's reason for not being confident."""
        self._last_fix: tuple[RgbdFrame, np.ndarray] | None = None
        self._verified_s = world.time_s
        self._refuted = False
        """``refute_bridge`` since the last fix."""

    def on_step(self) -> None:
        """Every physics step (after ``world.step()``): the legs move on."""
        self.legs.update()

    def pose(self) -> np.ndarray:
        """The last fix composed with the legs' motion since (module docstring)."""
        return compose(self._fix_xyyaw, relative(self._fix_legs, self.legs.xyyaw))

    def since_fix(self) -> tuple[float, float]:
        """(m walked by the legs, s) since the last accepted VO fix."""
        return self.legs.distance_m - self._fix_distance_m, self.world.time_s - self._fix_time_s

    def refute_bridge(self) -> None:
        """The legs' pose since the last fix is wrong (the navigator found the body inside an
        obstacle of the map there): until the next fix the legs no longer gate the VO, as past the
        bridge's limits (an agreeing fix is taken, a disagreeing one when the map confirms it), and
        a lost VO's frames are checked against the map."""
        self._refuted = True

    def _bridged(self, since_m: float, since_s: float) -> bool:
        """Whether the legs' bridge is within its limits and not refuted."""
        return not self._refuted and since_m <= self.bridge_max_m and since_s <= self.bridge_max_s

    def on_frame(self, frame: RgbdFrame) -> PoseEstimate:
        legs_cam = self._legs_camera()
        motion = np.linalg.inv(self._prior_from) @ legs_cam if self.cfg.motion_prior else None
        self._prior_from = legs_cam
        est = self.visual.on_frame(frame, motion)
        since_m, since_s = self.since_fix()
        predicted = self.pose()
        c = self.cfg
        if not est.tracked:
            bridged = self._bridged(since_m, since_s)
            self._lost_run += 1
            if (self.map_source is not None and (not bridged or since_s >= c.lost_check_after_s)
                    and self._lost_run % c.check_rejected_every == 1):
                taken = self._check_map(frame, self._legs_fix(predicted, frame.time_s), None, "vo lost",
                                        correct_vo=False)
                if taken is not None:
                    taken.state, taken.source = "relocalised", "map"
                    self._take_fix(taken, frame)
                    return taken
            return PoseEstimate(predicted, False, frame.time_s, None, est.state, "legs", since_m, since_s)
        self._lost_run = 0
        est.pose_wc = _planar_matrix(self._map_vo) @ est.pose_wc  # the VO's frame -> the map's
        est.xyyaw = self._pelvis_of(est.pose_wc)
        bridged = self._bridged(since_m, since_s)
        off = relative(predicted, est.xyyaw)
        gate_m = c.outlier_gate_m + c.outlier_gate_fraction * since_m
        agrees = math.hypot(off[0], off[1]) <= gate_m and abs(math.degrees(off[2])) <= c.outlier_gate_yaw_deg
        why = None
        if not agrees and (not bridged or self._rejected_run % c.check_rejected_every == 0):
            why = "disagree" if bridged else "bridge ended"
        elif agrees and c.verify_period_s is not None and frame.time_s - self._verified_s >= c.verify_period_s:
            why = "period"
        if why is not None and self.map_source is not None:
            taken = self._check_map(frame, est, None if agrees else predicted, why)
            if taken is not None:
                est, agrees = taken, True
        if not agrees and bridged:
            self.rejected += 1
            self._rejected_run += 1
            return PoseEstimate(predicted, False, frame.time_s, None, "rejected", "legs", since_m, since_s)
        if not agrees and self.map_source is not None:
            self.unverified += 1
            return PoseEstimate(predicted, False, frame.time_s, None, "unverified", "none", since_m, since_s)
        self._take_fix(est, frame)
        return est

    def verify(self) -> bool | None:
        """Check the last fix's frame against the map now (as ``verify_period_s`` does): True when
        the map confirms the pose, False when it found the robot elsewhere (the estimate has moved
        there), None when it cannot tell (no map, no fix, a bare view). What a navigator asks
        before it declares arrival."""
        if self.map_source is None or self._last_fix is None:
            return None
        frame, pose_wc = self._last_fix
        fix = PoseEstimate(self._pelvis_of(pose_wc), True, frame.time_s, pose_wc, "tracking", "vo")
        taken = self._check_map(frame, fix, None, "asked")
        if taken is None:
            return None
        if taken.source == "vo":
            return True
        # the estimate now (the legs' motion since that frame on top) moves with the correction
        moved = self._last_move
        self._anchor(_xyyaw_of_planar(moved @ _planar_matrix(self.pose())), self.world.time_s)
        self.legs.anchor(moved[:3, :3] @ self.legs.pose_w_imu()[:3, :3])
        self._last_fix = (frame, taken.pose_wc)
        return False

    def _legs_fix(self, predicted: np.ndarray, time_s: float) -> PoseEstimate:
        """The legs' pose as a fix to check: their camera pose moved from their own frame into the
        estimate's (the planar motion that takes the legs' pelvis pose onto ``predicted``)."""
        to_estimate = compose(predicted, relative(self.legs.xyyaw, np.zeros(3)))
        pose_wc = _planar_matrix(to_estimate) @ self._legs_camera()
        return PoseEstimate(self._pelvis_of(pose_wc), True, time_s, pose_wc, "tracking", "legs")

    def _check_map(self, frame: RgbdFrame, est: PoseEstimate, legs_xyyaw: np.ndarray | None, why: str, *,
                   correct_vo: bool = True) -> PoseEstimate | None:
        """Match ``frame`` on the map around the fix ``est`` (and the legs' pose, when they
        disagree): the fix to take (``est`` itself, or moved to where the map puts it, with the
        ``map <- VO`` correction renewed), or None when the match is not confident."""
        self._verified_s = frame.time_s
        grid = self.map_source()
        if grid is None:
            self.map_checks.append((frame.time_s, why, "no map"))
            return None
        c = self.cfg
        pivot = est.pose_wc[:2, 3]
        scan = scan_xy_m(frame.depth_m.numpy(), frame.intrinsics.numpy(), est.pose_wc, c.relocalize)
        hyps = [] if legs_xyyaw is None else [correction_between(est.xyyaw, legs_xyyaw, pivot)]
        m: Match = match_scan(grid, scan, pivot, c.relocalize, hyps)
        if not m.confident:
            self.map_checks.append((frame.time_s, why, m.reason))
            return None
        small = math.hypot(*m.correction[:2]) < c.correct_min_m and abs(math.degrees(m.correction[2])) < c.correct_min_deg
        if m.chosen == 0 or small:
            self.map_checks.append((frame.time_s, why, "vo"))
            return est
        # the correction turns about the pivot: as a motion of the world, R p + pivot + t - R pivot
        moved = _planar_matrix(apply_correction(m.correction, pivot, np.zeros(3)))
        self._last_move = moved
        if correct_vo:
            self._map_vo = _xyyaw_of_planar(moved @ _planar_matrix(self._map_vo))
        pose_wc = moved @ est.pose_wc
        self.map_checks.append((frame.time_s, why, "legs" if m.chosen == 1 else "map"))
        return PoseEstimate(self._pelvis_of(pose_wc), True, est.time_s, pose_wc, "relocalised", "map")

    def _take_fix(self, est: PoseEstimate, frame: RgbdFrame) -> None:
        self._rejected_run = 0
        self._refuted = False
        self._anchor(est.xyyaw, frame.time_s)
        self.legs.anchor(est.pose_wc[:3, :3] @ self._pose_imu_cam[:3, :3].T)
        bias = getattr(getattr(self.visual.vo, "gyro", None), "bias_rad_s", None)
        if bias is not None:
            self.legs.gyro_bias_rad_s = np.asarray(bias, float)
        self._last_fix = (frame, est.pose_wc)

    def _pelvis_of(self, pose_wc: np.ndarray) -> np.ndarray:
        """The pelvis pose of a camera pose through the torso's joints now, not the head-to-pelvis
        pose of the start: the torso turns the head by a few degrees with the gait."""
        pose_wi = pose_wc @ np.linalg.inv(self._pose_imu_cam)
        return xyyaw_from_matrix(pose_wi @ np.linalg.inv(self.legs.pose_pelvis_imu()))

    def _anchor(self, xyyaw: np.ndarray, time_s: float) -> None:
        self._fix_xyyaw = np.asarray(xyyaw, float).copy()
        self._fix_legs = self.legs.xyyaw
        self._fix_distance_m = self.legs.distance_m
        self._fix_time_s = time_s

    def _legs_camera(self) -> np.ndarray:
        """(4, 4) the camera's pose by the legs (the IMU's pose and the camera rigid on it)."""
        return self.legs.pose_w_imu() @ self._pose_imu_cam


def _planar_matrix(xyyaw) -> np.ndarray:
    """(4, 4) the rigid motion of a planar pose (turn about the world's z, then shift)."""
    out = np.eye(4)
    c, s = math.cos(xyyaw[2]), math.sin(xyyaw[2])
    out[:2, :2] = [[c, -s], [s, c]]
    out[:2, 3] = xyyaw[:2]
    return out


def _xyyaw_of_planar(m: np.ndarray) -> np.ndarray:
    return np.array([m[0, 3], m[1, 3], math.atan2(m[1, 0], m[0, 0])])


__all__ = ["LegVoLocalizer", "LegVoLocalizerCfg", "OracleLocalizer", "PoseEstimate", "TRACKED_STATES",
           "VoLocalizer", "VoLocalizerCfg", "is_tracked", "xyyaw_from_matrix"]
