"""RGB-D visual odometry: features, matching against a local map of recent keyframes, RANSAC for
the pose, then a joint reprojection + depth refinement, keyframes, and relocalisation after
tracking loss.

Per frame: keypoints and descriptors (``VoCfg.features``: OpenCV ORB on the host, or kornia
Shi-Tomasi + RootSIFT on any torch device, ``vo.features``); matches (Lowe's ratio test) to the 3-D
points of the last ``local_map_keyframes`` keyframes (world frame, from their depth); RANSAC
(``VoCfg.pnp``: OpenCV's minimal-set ``solvePnPRansac``, AP3P, on the host, or 3-point RGB-D
hypotheses batched in torch, ``vo.pnp_torch``), never seeded with the motion prior; then
Gauss-Newton on SE(3) over the inliers with two residuals each: the reprojection error (px /
``pixel_sigma``) and, where the current depth is valid, the 3-D difference to the back-projected
current point (m / ``depth_sigma(z)``), robustly weighted (``vo.refine``). Depth pins translation
far better than pixels alone on short baselines.

Threads: ``track`` runs its CPU torch ops on one thread (``perception.torch_threads``; a busy 2-core
machine took 222 ms a frame with torch's 2 threads, against 59 quiet).

Where the data lives: keypoints, descriptors, the keyframes' descriptors and 3-D points, matching,
the rigidity check, RANSAC (``pnp="torch"``) and the refinement are torch tensors on
``VoCfg.device``; poses, the motion model and the keyframe policy are 4x4 numpy matrices on the
host. A frame reads the device a handful of times (counts for the decisions, the final pose), never
per feature. With ``pnp="opencv"`` the matched points (a few hundred) go to the host for
``solvePnPRansac`` and the refinement runs on the device again.

Tracking is *lost* when too few inliers remain (covered lens, textureless wall, a turn faster
than the keyframes overlap). ``VoResult.tracked`` is then False: the pose is a guess a consumer must
not fuse into a map or steer on (``pipeline.run_mapping`` skips such frames). The pose coasts on the constant-velocity model (decaying), and
every frame tries to relocalise: RANSAC without a prior against each of the last
``relocalize_keyframes`` keyframes, newest first; keyframes are in world coordinates, so the
first success gives the absolute pose back and tracking resumes on the next frame. When the
camera moved on while blind and relocalisation keeps failing on textured frames, a new map starts
at the coasted pose (``VoCfg.reinit_after_lost_frames``).

With an IMU (``track(..., gyro=...)``, ``vo.imu``) the gyro turns the prediction and the coasting
pose, gates solved rotations (``VoCfg.gyro_gate_deg``), and its bias is estimated while tracking;
lost, the IMU moves on at its mean velocity of the last stride with the camera rigid on it.
"""

from __future__ import annotations

import collections
from dataclasses import dataclass

import numpy as np
import torch

from ..torch_threads import one_torch_thread
from .config import TrackState, VoCfg
from .features import FrameFeatures, make_features
from .imu import GyroAid, GyroSamples
from .pnp_torch import ransac_pose_rgbd, reprojection_error_px
from .refine import refine_pose_torch
from .refine_graph import GraphRefiner


@dataclass
class Keyframe:
    index: int
    pose_wc: np.ndarray
    """(4, 4) camera-to-world pose when the keyframe was made."""
    descriptors: torch.Tensor
    """(N, D) descriptors (``FrameFeatures.descriptors``) of the keypoints with valid depth, on the device."""
    points_w: torch.Tensor
    """(N, 3) float64 their 3-D points in the world, m, on the device."""
    dynamic: torch.Tensor
    """(N,) bool: points seen to move (no longer matched)."""


@dataclass
class VoResult:
    """One frame's odometry output. Only a ``tracked`` pose may be acted on (fused into a map,
    steered on, scored): an untracked one is a guess."""

    pose_wc: np.ndarray
    """(4, 4) float64 estimated camera-to-world pose (OpenCV axes); while not ``tracked`` the coasted
    prediction (constant velocity or the gyro), which drifts (33.6 cm after a 1 s covered lens)."""
    state: TrackState
    """Why the pose is what it is (``TrackState``); ``tracked`` says whether to use it."""
    inliers: int
    num_keyframes: int
    tracked: bool
    """True when this frame's pose was measured from the image: ``state`` TRACKING or RECOVERED, or
    INITIALIZED on the frame that made the first keyframe (the pose given to the odometry). False
    while LOST (coasted), on a REINITIALIZED frame (a new map started at the coasted pose: tracking
    goes on from the next frame, relative to that pose, which keeps the error coasted into) and
    before the odometry starts (too few features with depth: the pose is still the initial one)."""


def moved_by_rigidity(points_w: torch.Tensor, points_c: torch.Tensor, valid: torch.Tensor, cfg: VoCfg,
                      seed: int) -> torch.Tensor:
    """(M,) bool: matches whose 3-D point moved, by rigidity, independent of any pose estimate.

    ``points_w`` (M, 3) map points (world, m), ``points_c`` (M, 3) the matched keypoints' points in
    the current camera frame (m), ``valid`` (M,) bool where they have depth. A rigid motion keeps
    distances: for static points |p_i - p_j| (map) equals |q_i - q_j| (current camera frame). Each
    match is compared with up to 256 anchor matches (drawn with ``seed`` on the host, the same on
    every device); one whose distances disagree (beyond ``dynamic_threshold_m`` +
    ``dynamic_threshold_coeff`` (z_i^2 + z_j^2)) with most anchors, or with fewer than 3/4 as many
    as the best-agreeing tenth of the matches do, has moved: the static scene is the largest rigid
    group of what is matched."""
    idx = torch.nonzero(valid)[:, 0]
    out = torch.zeros(len(points_w), dtype=torch.bool, device=points_w.device)
    if len(idx) < 12:
        return out
    anchors = idx
    if len(idx) > 256:
        anchors = idx[torch.from_numpy(np.random.default_rng(seed).choice(len(idx), 256, replace=False)).to(idx.device)]
    # cdist without its matrix-product shortcut: the same sqrt of summed squares (to round-off) in one
    # kernel, ~3x faster than broadcasting a (M, 256, 3) difference and taking its norm
    d_map = torch.cdist(points_w[idx], points_w[anchors], compute_mode="donot_use_mm_for_euclid_dist")
    d_cur = torch.cdist(points_c[idx], points_c[anchors], compute_mode="donot_use_mm_for_euclid_dist")
    z = points_c[:, 2]
    tol = cfg.dynamic_threshold_m + cfg.dynamic_threshold_coeff * (z[idx, None] ** 2 + z[None, anchors] ** 2)
    agree = ((d_map - d_cur).abs() < tol).double().mean(dim=1)
    # Static matches agree with every other static match, so with each other as often as static
    # matches are among the anchors. Mismatches (noisy images give more of them than right matches)
    # agree with nothing: measured against the best-agreeing tenth, not against a majority of all
    # matches, right matches stay static when most matches are wrong; with few mismatches the
    # threshold is the majority, 0.5.
    best = torch.quantile(agree, 0.9)
    out[idx] = agree < torch.clamp(0.75 * best, max=0.5)
    return out


class RgbdOdometry:
    """Visual odometry on a stream of RGB-D frames; ``track`` returns each frame's pose.

    ``intrinsics``: (3, 3) K; ``initial_pose_wc``: the first frame's pose (identity by default,
    or the ground truth to express the estimate in the simulator's world); ``pose_cam_imu``: the IMU's
    (4, 4) pose (or (3, 3) rotation) in the camera frame, needed to pass gyro samples to ``track``
    (``vo.imu.GyroAid``).
    """

    def __init__(self, intrinsics, cfg: VoCfg | None = None, initial_pose_wc=None, pose_cam_imu=None):
        self.cfg = cfg or VoCfg()
        self.device = torch.device(self.cfg.device)
        self.k = np.asarray(intrinsics, np.float64)
        self.k_t = torch.as_tensor(self.k, device=self.device)
        self.features = make_features(self.cfg, self.k_t, self.device)
        self._refine = refine_pose_torch
        if self.device.type == "cuda" and self.cfg.cuda_graphs:
            self._refine = GraphRefiner(self.cfg, self.device)
        self.rng = np.random.default_rng(0)
        """Draws the torch RANSAC's samples (host integers: identical on every device)."""
        self.keyframes: list[Keyframe] = []
        self.pose_wc = np.eye(4) if initial_pose_wc is None else np.asarray(initial_pose_wc, np.float64).copy()
        self.velocity = np.eye(4)
        """(4, 4) last frame-to-frame motion T_prev_cur (camera frame), for prediction."""
        self._lost_frames = 0
        self._imu_trail: collections.deque[np.ndarray] = collections.deque(maxlen=self.cfg.coast_window_frames + 1)
        """IMU positions (world, m) of the last tracked frames, for the coast velocity."""
        self.step_w_m = np.zeros(3)
        """(3,) the IMU's last frame-to-frame translation in the world, m: with a gyro the prediction
        moves the IMU on along it while the gyro turns it, and carries the camera rigidly (a head
        turning while the body walks on; in the camera frame the step would turn with the head, and
        the camera's lever arm would be lost)."""
        self.state = TrackState.INITIALIZED
        self.frame_index = -1
        self.history: list[TrackState] = []
        self.gyro = None if pose_cam_imu is None else GyroAid(pose_cam_imu, self.cfg.gyro_bias_gain)
        """The gyro aid (its ``bias_rad_s`` is the current bias estimate), or None without an IMU."""

    # -- pose -------------------------------------------------------------------
    def _ransac(self, points_w, pix, points_c, valid):
        """``(rot_cw, t_cw, inliers (M,) bool)`` of the best hypothesis on the device, or None."""
        if self.cfg.pnp == "torch":
            return ransac_pose_rgbd(points_w, pix, points_c, valid, self.k_t, self.cfg.ransac_iterations,
                                    self.cfg.ransac_reprojection_px, self.rng)
        import cv2  # perception extra

        # minimal-set RANSAC (AP3P), never seeded with the motion prior: a seeded iterative solver
        # follows a slowly moving object's points together with its own prediction and drifts
        ok, rvec, tvec, inl = cv2.solvePnPRansac(points_w.cpu().numpy(), pix.cpu().numpy(), self.k, None,
                                                 flags=cv2.SOLVEPNP_AP3P, iterationsCount=self.cfg.ransac_iterations,
                                                 reprojectionError=self.cfg.ransac_reprojection_px, confidence=0.999)
        if not ok or inl is None:
            return None
        inliers = torch.zeros(len(points_w), dtype=torch.bool)
        inliers[torch.from_numpy(inl[:, 0])] = True
        rot = torch.from_numpy(cv2.Rodrigues(rvec)[0]).to(self.device)
        return rot, torch.from_numpy(tvec[:, 0]).to(self.device), inliers.to(self.device)

    def _solve(self, points_w, pix, points_c, valid, min_inliers: int):
        """RANSAC, refinement on its inliers, inliers re-selected with the refined pose, refinement
        again: ``(pose_cw (4, 4) numpy, inlier count)`` or None."""
        if len(points_w) < max(6, min_inliers):
            return None
        found = self._ransac(points_w, pix, points_c, valid)
        if found is None or int(found[2].sum()) < min_inliers:
            return None
        rot, t, inliers = found
        rot, t = self._refine(rot, t, points_w, pix, points_c, valid, inliers, self.k_t, self.cfg)
        err, z = reprojection_error_px(rot, t, points_w, pix, self.k_t)
        inliers = (err < self.cfg.ransac_reprojection_px) & (z > 0)
        count = int(inliers.sum())
        if count < min_inliers:
            return None
        rot, t = self._refine(rot, t, points_w, pix, points_c, valid, inliers, self.k_t, self.cfg)
        pose_cw = np.eye(4)
        pose_cw[:3, :3], pose_cw[:3, 3] = rot.cpu().numpy(), t.cpu().numpy()
        return pose_cw, count

    def _track_local_map(self, f: FrameFeatures, prior_cw: np.ndarray):
        """The pose from matches to the local map: guided by the prediction ``prior_cw`` (world to
        camera) when ``VoCfg.match_window_px`` is set, and against the whole local map when that is
        off or its pose fails (the prediction was off by more than the window)."""
        kfs = self.keyframes[-self.cfg.local_map_keyframes:]
        map_pts = torch.cat([kf.points_w for kf in kfs])
        map_des = torch.cat([kf.descriptors for kf in kfs])
        if self.cfg.match_window_px is not None:
            prior = torch.as_tensor(prior_cw, device=self.device)
            pc = map_pts @ prior[:3, :3].T + prior[:3, 3]
            uv = pc[:, :2] / pc[:, 2:] * self.k_t.diagonal()[:2] + self.k_t[:2, 2]
            uv = torch.where(pc[:, 2:] > 1e-6, uv, torch.nan)  # behind the camera: in no window
            pairs = self.features.match_window(f.descriptors, f.pixels, map_des, uv, self.cfg.match_window_px)
            found = self._pose_from_pairs(f, kfs, map_pts, pairs, prior_cw)
            if found is not None:
                return found
        return self._pose_from_pairs(f, kfs, map_pts, self.features.match(f.descriptors, map_des), prior_cw)

    def _pose_from_pairs(self, f: FrameFeatures, kfs: list[Keyframe], map_pts: torch.Tensor, pairs: torch.Tensor,
                         prior_cw: np.ndarray):
        """Rigidity check, RANSAC and refinement on matches ``pairs`` (K, 2) (keypoint, local map
        point), then the prior gate: ``(pose_cw, inliers)`` or None."""
        if len(pairs) == 0:
            return None
        dynamic = torch.cat([kf.dynamic for kf in kfs])
        q, m = pairs[:, 0], pairs[:, 1]
        moved = moved_by_rigidity(map_pts[m], f.points_c[q], f.valid[q], self.cfg, max(self.frame_index, 0)) | dynamic[m]
        hits = torch.zeros(len(map_pts), dtype=torch.long, device=self.device).index_add_(0, m, moved.long())
        for kf, part in zip(kfs, (dynamic | (hits > 0)).split([len(kf.points_w) for kf in kfs]), strict=True):
            kf.dynamic = part
        self._moving[q] = moved  # matched a moving point: left out of new keyframes too
        q, m = q[~moved], m[~moved]
        pts, px, pc, ok = map_pts[m], f.pixels[q], f.points_c[q], f.valid[q]
        found = self._solve(pts, px, pc, ok, self.cfg.min_inliers)
        if found is None:
            return None
        if np.linalg.norm(np.linalg.inv(found[0])[:3, 3] - np.linalg.inv(prior_cw)[:3, 3]) <= self.cfg.prior_gate_m:
            return found
        prior = torch.as_tensor(prior_cw, device=self.device)
        err, z = reprojection_error_px(prior[:3, :3], prior[:3, 3], pts, px, self.k_t)
        agree = (err < self.cfg.prior_gate_px) & (z > 0)
        again = self._solve(pts[agree], px[agree], pc[agree], ok[agree], self.cfg.min_inliers)
        return found if again is None else again

    def _relocalize(self, f: FrameFeatures):
        for kf in reversed(self.keyframes[-self.cfg.relocalize_keyframes:]):
            static = ~kf.dynamic
            points_w = kf.points_w[static]
            pairs = self.features.match(f.descriptors, kf.descriptors[static])
            if len(pairs) < self.cfg.relocalize_min_inliers:
                continue
            q = pairs[:, 0]
            found = self._solve(points_w[pairs[:, 1]], f.pixels[q], f.points_c[q], f.valid[q],
                                self.cfg.relocalize_min_inliers)
            if found is not None:
                return found
        return None

    def _add_keyframe(self, f: FrameFeatures) -> None:
        keep = f.valid & ~self._moving
        pose = torch.as_tensor(self.pose_wc, device=self.device)
        pts_w = f.points_c[keep] @ pose[:3, :3].T + pose[:3, 3]
        self.keyframes.append(Keyframe(self.frame_index, self.pose_wc.copy(), f.descriptors[keep], pts_w,
                                       torch.zeros(len(pts_w), dtype=torch.bool, device=self.device)))

    def _track_next(self, f: FrameFeatures, gyro: GyroSamples | None, motion_cam: np.ndarray | None) -> int:
        """Pose of a frame after the first (sets ``pose_wc``, ``state``); returns the inlier count."""
        prev_wc, was_lost = self.pose_wc, self.state == TrackState.LOST
        gyro_rot = None if gyro is None else self.gyro.camera_rotation(gyro)  # (3, 3) R_prev_cur, camera
        if motion_cam is not None:  # another sensor's motion (leg odometry) beats the models below
            predicted_wc = prev_wc @ np.asarray(motion_cam, np.float64)
        elif gyro_rot is None:
            predicted_wc = prev_wc @ self.velocity
        else:
            predicted_wc = self._imu_coast(prev_wc, gyro_rot)
        if was_lost:
            found = self._relocalize(f) if len(f.pixels) else None
            state = TrackState.RECOVERED
        else:
            found = self._track_local_map(f, np.linalg.inv(predicted_wc)) if len(f.pixels) else None
            state = TrackState.TRACKING
            if found is not None and not self._turn_plausible(prev_wc, np.linalg.inv(found[0]), gyro_rot):
                found = None
        if found is None:
            self.pose_wc = predicted_wc
            self._lost_frames = self._lost_frames + 1 if was_lost else 1
            if not was_lost:  # the IMU walks on at its mean velocity over the last stride
                trail = self._imu_trail
                self.step_w_m = (trail[-1] - trail[0]) / (len(trail) - 1) if len(trail) > 1 else np.zeros(3)
            if gyro_rot is None:
                # no gyro: coast on a decaying velocity (a covered lens usually means the robot slows
                # down or stops, and the turn is a guess)
                self.velocity = _interpolate_identity(self.velocity, 0.9)
            if self._lost_frames >= self.cfg.reinit_after_lost_frames and \
                    int(f.valid.sum()) >= self.cfg.relocalize_min_inliers:
                self._start_new_map(f)
            else:
                self.state = TrackState.LOST
            return 0
        pose_cw, inliers = found
        self.pose_wc = np.linalg.inv(pose_cw)
        if state == TrackState.TRACKING:
            self.velocity = np.linalg.inv(prev_wc) @ self.pose_wc
            self.step_w_m = self._imu_position(self.pose_wc) - self._imu_position(prev_wc)
            if gyro is not None:
                self.gyro.update_bias(gyro, self.velocity[:3, :3])
        else:
            self.velocity, self.step_w_m = np.eye(4), np.zeros(3)
            self._imu_trail.clear()
        self._imu_trail.append(self._imu_position(self.pose_wc))
        self.state = state
        if state == TrackState.RECOVERED or self._needs_keyframe(inliers):
            self._add_keyframe(f)
        return inliers

    def _start_new_map(self, f: FrameFeatures) -> None:
        """Relocalisation kept failing on a frame with texture: the camera has left what the map
        holds. Go on from the coasted pose with a keyframe of this frame, so tracking goes on
        instead of staying lost; the old keyframes stay for relocalising later. The absolute pose
        keeps the error it coasted into (small in rotation with a gyro)."""
        self.state = TrackState.REINITIALIZED
        self._imu_trail.clear()
        self._imu_trail.append(self._imu_position(self.pose_wc))
        self.velocity = np.eye(4)
        self._add_keyframe(f)

    def _imu_position(self, pose_wc: np.ndarray) -> np.ndarray:
        """(3,) where the IMU is in the world when the camera is at ``pose_wc``, m."""
        ext = self.gyro.pose_cam_imu if self.gyro is not None else np.eye(4)
        return pose_wc[:3, :3] @ ext[:3, 3] + pose_wc[:3, 3]

    def _imu_coast(self, prev_wc: np.ndarray, gyro_rot: np.ndarray) -> np.ndarray:
        """(4, 4) the camera pose predicted from ``prev_wc``: turned by the gyro's ``gyro_rot``
        (camera frame), with the IMU moved on by ``step_w_m`` and the camera rigid on it."""
        out = np.eye(4)
        out[:3, :3] = prev_wc[:3, :3] @ gyro_rot
        imu_w = self._imu_position(prev_wc) + self.step_w_m
        out[:3, 3] = imu_w - out[:3, :3] @ self.gyro.pose_cam_imu[:3, 3]
        return out

    def _turn_plausible(self, prev_wc: np.ndarray, found_wc: np.ndarray, gyro_rot: np.ndarray | None) -> bool:
        """Whether the solved pose's rotation since the previous frame is believable: it agrees with
        the gyro's (``VoCfg.gyro_gate_deg``), or without a gyro stays under
        ``VoCfg.max_rotation_per_frame_deg``."""
        turned = prev_wc[:3, :3].T @ found_wc[:3, :3]
        if gyro_rot is None:
            return _angle_deg(turned) <= self.cfg.max_rotation_per_frame_deg
        return _angle_deg(gyro_rot.T @ turned) <= self.cfg.gyro_gate_deg

    def _needs_keyframe(self, inliers: int) -> bool:
        last = self.keyframes[-1].pose_wc
        rel = np.linalg.inv(last) @ self.pose_wc
        return (inliers < self.cfg.keyframe_min_inliers or np.linalg.norm(rel[:3, 3]) > self.cfg.keyframe_max_translation_m
                or _angle_deg(rel[:3, :3]) > self.cfg.keyframe_max_rotation_deg)

    def track(self, rgb, depth, gyro: GyroSamples | None = None, motion_cam: np.ndarray | None = None) -> VoResult:
        """Estimate the pose of the next frame: ``rgb`` (H, W, 3) uint8, ``depth`` (H, W) metres,
        numpy arrays or torch tensors (on any device); ``gyro``: the IMU's rates from the previous
        frame to this one (needs ``pose_cam_imu``; ignored on the first frame); ``motion_cam``: (4, 4)
        the camera's motion since the previous frame measured by another sensor (``T_prev_cur``, e.g.
        leg odometry): the prediction the local map is matched and gated against, and the pose
        coasted on while lost, in place of the constant-velocity / gyro models."""
        if gyro is not None and self.gyro is None:
            raise ValueError("track(gyro=...) needs the IMU's extrinsic: pass pose_cam_imu to RgbdOdometry")
        # the frame's CPU torch ops on this thread only (``torch_threads``: 59 -> 222 ms a frame with 2
        # torch threads on a busy 2-core machine)
        with one_torch_thread(self.device):
            return self._track(rgb, depth, gyro, motion_cam)

    def _track(self, rgb, depth, gyro: GyroSamples | None, motion_cam: np.ndarray | None) -> VoResult:
        self.frame_index += 1
        f = self.features.detect(rgb, depth)
        self._moving = torch.zeros(len(f.pixels), dtype=torch.bool, device=self.device)
        inliers = 0
        if not self.keyframes:
            if motion_cam is not None and self.frame_index > 0:
                # not started yet (too few features with depth): the initial pose moves on with the
                # other sensor, so a late first keyframe is made where the camera is, not where it began
                self.pose_wc = self.pose_wc @ np.asarray(motion_cam, np.float64)
            if int(f.valid.sum()) >= self.cfg.relocalize_min_inliers:
                self._add_keyframe(f)
                self._imu_trail.append(self._imu_position(self.pose_wc))
                self.state = TrackState.INITIALIZED
        else:
            inliers = self._track_next(f, gyro, motion_cam)
        self.history.append(self.state)
        return VoResult(self.pose_wc.copy(), self.state, inliers, len(self.keyframes), tracked=self.tracked)

    @property
    def tracked(self) -> bool:
        """Whether the last frame's pose was measured (``VoResult.tracked``)."""
        if self.state == TrackState.INITIALIZED:
            return bool(self.keyframes)
        return self.state in _TRACKED


_TRACKED = (TrackState.TRACKING, TrackState.RECOVERED)
"""States whose pose was measured from the image (INITIALIZED too once the first keyframe is made)."""


def _angle_deg(rotation: np.ndarray) -> float:
    """The rotation angle of a (3, 3) rotation matrix, degrees."""
    return float(np.degrees(np.arccos(np.clip((np.trace(rotation) - 1) / 2, -1, 1))))


def _interpolate_identity(motion: np.ndarray, factor: float) -> np.ndarray:
    """``motion`` scaled toward identity: translation times ``factor``, rotation angle times ``factor``."""
    import cv2

    rvec, _ = cv2.Rodrigues(motion[:3, :3])
    rot, _ = cv2.Rodrigues(rvec * factor)
    out = np.eye(4)
    out[:3, :3], out[:3, 3] = rot, motion[:3, 3] * factor
    return out


__all__ = ["Keyframe", "RgbdOdometry", "VoResult", "moved_by_rigidity"]
