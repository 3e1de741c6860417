"""RGB-D visual odometry: OpenCV ORB features (Rublee et al. 2011), matching against a local map
of recent keyframes, PnP with RANSAC, then a joint reprojection + depth refinement, keyframes,
and relocalisation after tracking loss.

Per frame: ORB keypoints and descriptors; Hamming matches (Lowe's ratio test) to the 3-D points
of the last ``local_map_keyframes`` keyframes (world frame, from their depth); ``solvePnPRansac``
seeded with a constant-velocity prediction; then Gauss-Newton on SE(3) over the inliers with two
residuals each: the reprojection error (px / ``pixel_sigma``) and, where the current depth is
valid, the 3-D difference to the back-projected current point (m / ``depth_sigma(z)``), Huber
weighted. Depth pins translation far better than pixels alone on short baselines.

Tracking is *lost* when too few inliers remain (covered lens, textureless wall, a turn faster
than the keyframes overlap). The pose then coasts on the constant-velocity model (decaying), and
every frame tries to relocalise: PnP RANSAC without a prior against each of the last
``relocalize_keyframes`` keyframes, newest first; keyframes are in world coordinates, so the
first success gives the absolute pose back and tracking resumes on the next frame.
"""

from __future__ import annotations

import enum
from dataclasses import dataclass

import numpy as np

from ambulo.utils.checks import check_int, check_positive


class TrackState(enum.Enum):
    INITIALIZED = "initialized"
    TRACKING = "tracking"
    LOST = "lost"
    RECOVERED = "recovered"


@dataclass(kw_only=True)
class VoCfg:
    """Features, matching, RANSAC and keyframe policy of ``RgbdOdometry``."""

    num_features: int = 1500
    """ORB features per frame (ORB-SLAM uses 1000-2000 at 640x480)."""
    fast_threshold: int = 12
    """FAST corner threshold (OpenCV's default 20 misses low-contrast texture)."""
    ratio_test: float = 0.8
    """Lowe's ratio: best Hamming distance < ratio * second best."""
    max_hamming: int = 64
    ransac_reprojection_px: float = 2.0
    ransac_iterations: int = 200
    min_inliers: int = 25
    """Fewer PnP inliers than this and the frame is lost."""
    relocalize_min_inliers: int = 40
    """Inliers needed to accept a relocalisation (stricter: there is no motion prior)."""
    keyframe_min_inliers: int = 200
    """A new keyframe is made when fewer inliers than this remain ..."""
    keyframe_max_translation_m: float = 0.25
    """... or the camera moved this far from the last keyframe ..."""
    keyframe_max_rotation_deg: float = 12.0
    """... or turned this much."""
    prior_gate_m: float = 0.03
    """A pose further than this from the constant-velocity prediction is re-solved on the matches
    that agree with the prediction (within ``prior_gate_px``): walking moves the head ~4 mm per
    frame away from constant velocity at 30 Hz (2.5 cm bob at 1.8 Hz: A w^2 dt^2), while a wrong
    consensus (a moving box's points) jumps by centimetres."""
    prior_gate_px: float = 12.0
    local_map_keyframes: int = 3
    """Recent keyframes whose points every frame is matched against."""
    relocalize_keyframes: int = 12
    """Recent keyframes tried, newest first, after tracking is lost."""
    max_rotation_per_frame_deg: float = 30.0
    """A tracked pose that turned more than this since the previous frame is refused (the frame is
    lost, then relocalised): consecutive views then share under half a 60 deg field of view, and PnP
    on a sweep past mapped points was seen to accept a pose 12 cm off and keep it (a 1400 deg/s turn
    at 640x480). 30 deg a frame is 900 deg/s at 30 Hz, about twice a human head's fastest turn."""
    depth_range_m: tuple[float, float] = (0.2, 6.0)
    pixel_sigma: float = 1.0
    """Keypoint position noise, px (ORB keypoints sit on the pixel grid of their pyramid level)."""
    depth_sigma_coeff: float = 0.002
    """Depth noise sigma = coeff * z^2 (m) in the refinement (Kinect-like; simulated depth is better)."""
    depth_sigma_min_m: float = 0.002
    refine_iterations: int = 6
    dynamic_threshold_m: float = 0.01
    """Rigidity tolerance (see ``RgbdOdometry._moved``): a match whose distances to the others changed
    by more is on a moving object; its map point is never matched again and its keypoint stays out
    of new keyframes."""
    dynamic_threshold_coeff: float = 0.001
    use_depth_residual: bool = True
    """Add the 3-D (depth) residual to the refinement; False refines on reprojection alone."""
    robust_loss: str = "tukey"
    """'tukey' (redescending: points on a moving object drop out) or 'huber'."""

    def __post_init__(self):
        check_int("num_features", self.num_features, "pass a count > 0, e.g. 1500", minimum=1)
        check_int("min_inliers", self.min_inliers, "pass a count >= 6 (PnP needs 4+)", minimum=6)
        check_positive("ransac_reprojection_px", self.ransac_reprojection_px, "pass pixels > 0, e.g. 2")


@dataclass
class Keyframe:
    index: int
    pose_wc: np.ndarray
    """(4, 4) camera-to-world pose when the keyframe was made."""
    descriptors: np.ndarray
    """(N, 32) uint8 ORB descriptors of the keypoints with valid depth."""
    points_w: np.ndarray
    """(N, 3) float64 their 3-D points in the world, m."""
    dynamic: np.ndarray
    """(N,) bool: points seen to move (no longer matched)."""


@dataclass
class VoResult:
    pose_wc: np.ndarray
    """(4, 4) float64 estimated camera-to-world pose (OpenCV axes)."""
    state: TrackState
    inliers: int
    num_keyframes: int


def _so3_exp(w: np.ndarray) -> np.ndarray:
    theta = np.linalg.norm(w)
    k = np.array([[0, -w[2], w[1]], [w[2], 0, -w[0]], [-w[1], w[0], 0]])
    if theta < 1e-12:
        return np.eye(3) + k
    return np.eye(3) + np.sin(theta) / theta * k + (1 - np.cos(theta)) / theta**2 * k @ k


def _skew_batch(p: np.ndarray) -> np.ndarray:
    z = np.zeros(len(p))
    return np.stack([np.stack([z, -p[:, 2], p[:, 1]], -1), np.stack([p[:, 2], z, -p[:, 0]], -1),
                     np.stack([-p[:, 1], p[:, 0], z], -1)], -2)


def _robust_weight(r: np.ndarray, loss: str) -> np.ndarray:
    """IRLS weights of normalised residual norms: Huber (k = 1.345) or Tukey's biweight (c = 4.685),
    the 95 %-efficiency constants for Gaussian noise."""
    a = np.abs(r)
    if loss == "huber":
        return np.where(a <= 1.345, 1.0, 1.345 / np.maximum(a, 1e-12))
    return np.where(a < 4.685, (1 - (a / 4.685) ** 2) ** 2, 0.0)


def refine_pose(rot_cw: np.ndarray, t_cw: np.ndarray, points_w: np.ndarray, pixels: np.ndarray,
                points_c: np.ndarray, has_depth: np.ndarray, k: np.ndarray, cfg: VoCfg) -> tuple[np.ndarray, np.ndarray]:
    """Gauss-Newton on the world-to-camera pose over reprojection and 3-D (depth) residuals."""
    fx, fy, cx, cy = k[0, 0], k[1, 1], k[0, 2], k[1, 2]
    for _ in range(cfg.refine_iterations):
        pc = points_w @ rot_cw.T + t_cw
        z = np.maximum(pc[:, 2], 1e-6)
        proj = np.stack([fx * pc[:, 0] / z + cx, fy * pc[:, 1] / z + cy], -1)
        r_px = (proj - pixels) / cfg.pixel_sigma  # (N, 2)
        jp = np.zeros((len(pc), 2, 3))
        jp[:, 0, 0], jp[:, 0, 2] = fx / z, -fx * pc[:, 0] / z**2
        jp[:, 1, 1], jp[:, 1, 2] = fy / z, -fy * pc[:, 1] / z**2
        d_pc = np.concatenate([-_skew_batch(pc), np.broadcast_to(np.eye(3), (len(pc), 3, 3))], -1)  # (N, 3, 6)
        j_px = jp @ d_pc / cfg.pixel_sigma
        sigma = np.maximum(cfg.depth_sigma_coeff * z**2, cfg.depth_sigma_min_m)[:, None]
        r_3d = (pc - points_c) / sigma
        j_3d = d_pc / sigma[..., None]
        w_px = _robust_weight(np.linalg.norm(r_px, axis=1), cfg.robust_loss)[:, None]
        w_3d = (_robust_weight(np.linalg.norm(r_3d, axis=1), cfg.robust_loss) * has_depth
                * cfg.use_depth_residual)[:, None]
        h = np.einsum("nij,nik->jk", j_px * w_px[..., None], j_px) + np.einsum("nij,nik->jk", j_3d * w_3d[..., None], j_3d)
        g = np.einsum("nij,ni->j", j_px * w_px[..., None], r_px) + np.einsum("nij,ni->j", j_3d * w_3d[..., None], r_3d)
        delta = -np.linalg.solve(h + 1e-9 * np.eye(6), g)
        dr = _so3_exp(delta[:3])
        rot_cw, t_cw = dr @ rot_cw, dr @ t_cw + delta[3:]
        if np.linalg.norm(delta) < 1e-9:
            break
    return rot_cw, t_cw


class RgbdOdometry:
    """Visual odometry on a stream of RGB-D frames; ``track`` returns each frame's pose.

    ``intrinsics``: (3, 3) K; ``initial_pose_wc``: the first frame's pose (identity by default,
    or the ground truth to express the estimate in the simulator's world).
    """

    def __init__(self, intrinsics, cfg: VoCfg | None = None, initial_pose_wc=None):
        import cv2  # noqa: PLC0415 - perception extra

        self.cv2 = cv2
        self.cfg = cfg or VoCfg()
        self.k = np.asarray(intrinsics, np.float64)
        self.orb = cv2.ORB_create(nfeatures=self.cfg.num_features, fastThreshold=self.cfg.fast_threshold)
        self.matcher = cv2.BFMatcher(cv2.NORM_HAMMING)
        self.keyframes: list[Keyframe] = []
        self.pose_wc = np.eye(4) if initial_pose_wc is None else np.asarray(initial_pose_wc, np.float64).copy()
        self.velocity = np.eye(4)
        """(4, 4) last frame-to-frame motion T_prev_cur (camera frame), for prediction."""
        self.state = TrackState.INITIALIZED
        self.frame_index = -1
        self.history: list[TrackState] = []

    # -- features ---------------------------------------------------------------
    def _features(self, rgb: np.ndarray, depth: np.ndarray):
        gray = self.cv2.cvtColor(np.ascontiguousarray(rgb), self.cv2.COLOR_RGB2GRAY)
        kps, des = self.orb.detectAndCompute(gray, None)
        if des is None or len(kps) == 0:
            return np.zeros((0, 2)), np.zeros((0, 32), np.uint8), np.zeros((0, 3)), np.zeros(0, bool)
        pix = np.array([kp.pt for kp in kps], np.float64)
        points_c, valid = self._lift(pix, depth)
        return pix, des, points_c, valid

    def _lift(self, pix: np.ndarray, depth: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Camera-frame 3-D points at keypoints (depth at the nearest pixel, rejected across depth
        edges: the 3x3 neighbourhood must agree within 2 %)."""
        h, w = depth.shape
        u = np.clip(np.round(pix[:, 0]).astype(int), 1, w - 2)
        v = np.clip(np.round(pix[:, 1]).astype(int), 1, h - 2)
        patch = np.stack([depth[v + dv, u + du] for dv in (-1, 0, 1) for du in (-1, 0, 1)], -1)
        z = depth[v, u]
        lo, hi = self.cfg.depth_range_m
        valid = (patch.min(-1) > 0) & (patch.max(-1) - patch.min(-1) < 0.02 * z) & (z > lo) & (z < hi)
        x = (pix[:, 0] - self.k[0, 2]) / self.k[0, 0] * z
        y = (pix[:, 1] - self.k[1, 2]) / self.k[1, 1] * z
        return np.stack([x, y, z], -1), valid

    def _match(self, des: np.ndarray, kf_des: np.ndarray) -> np.ndarray:
        """(M, 2) index pairs (query, train) passing the ratio test."""
        if len(des) < 2 or len(kf_des) < 2:
            return np.zeros((0, 2), int)
        pairs = []
        for m in self.matcher.knnMatch(des, kf_des, k=2):
            if len(m) == 2 and m[0].distance < self.cfg.ratio_test * m[1].distance and m[0].distance <= self.cfg.max_hamming:
                pairs.append((m[0].queryIdx, m[0].trainIdx))
        return np.array(pairs, int).reshape(-1, 2)

    # -- pose -------------------------------------------------------------------
    def _solve(self, points_w, pix, points_c, valid, prior_cw: np.ndarray | None, min_inliers: int):
        cv2 = self.cv2
        if len(points_w) < max(6, min_inliers):
            return None
        kwargs = dict(iterationsCount=self.cfg.ransac_iterations, reprojectionError=self.cfg.ransac_reprojection_px,
                      confidence=0.999)
        # minimal-set RANSAC (AP3P), never seeded with the motion prior: a seeded iterative solver
        # follows a slowly moving object's points together with its own prediction and drifts
        ok, rvec, tvec, inl = cv2.solvePnPRansac(points_w, pix, self.k, None, flags=cv2.SOLVEPNP_AP3P, **kwargs)
        if not ok or inl is None or len(inl) < min_inliers:
            return None
        inl = inl[:, 0]
        rot, _ = cv2.Rodrigues(rvec)
        rot, t = refine_pose(rot, tvec[:, 0], points_w[inl], pix[inl], points_c[inl], valid[inl], self.k, self.cfg)
        # re-select inliers with the refined pose, refine once more on them
        pc = points_w @ rot.T + t
        z = np.maximum(pc[:, 2], 1e-6)
        err = np.linalg.norm(np.stack([self.k[0, 0] * pc[:, 0] / z + self.k[0, 2],
                                       self.k[1, 1] * pc[:, 1] / z + self.k[1, 2]], -1) - pix, axis=1)
        inl = np.flatnonzero((err < self.cfg.ransac_reprojection_px) & (pc[:, 2] > 0))
        if len(inl) < min_inliers:
            return None
        rot, t = refine_pose(rot, t, points_w[inl], pix[inl], points_c[inl], valid[inl], self.k, self.cfg)
        pose_cw = np.eye(4)
        pose_cw[:3, :3], pose_cw[:3, 3] = rot, t
        return pose_cw, len(inl)

    def _track_local_map(self, pix, des, points_c, valid, prior_cw):
        kfs = self.keyframes[-self.cfg.local_map_keyframes:]
        owner = np.concatenate([np.full(len(kf.points_w), i) for i, kf in enumerate(kfs)])
        local = np.concatenate([np.arange(len(kf.points_w)) for kf in kfs])
        dynamic = np.concatenate([kf.dynamic for kf in kfs])
        map_des = np.concatenate([kf.descriptors for kf in kfs])
        map_pts = np.concatenate([kf.points_w for kf in kfs])
        pairs = self._match(des, map_des)
        if len(pairs) == 0:
            return None
        q, m = pairs[:, 0], pairs[:, 1]
        moved = self._moved(map_pts[m], points_c[q], valid[q]) | dynamic[m]
        for i in np.flatnonzero(moved):
            kfs[owner[m[i]]].dynamic[local[m[i]]] = True
        self._moving_keypoints = q[moved]  # matched a moving point: left out of new keyframes too
        keep = np.flatnonzero(~moved)
        pts, px, pc, ok = map_pts[m[keep]], pix[q[keep]], points_c[q[keep]], valid[q[keep]]
        found = self._solve(pts, px, pc, ok, prior_cw, self.cfg.min_inliers)
        if found is None or prior_cw is None:
            return found
        if np.linalg.norm(np.linalg.inv(found[0])[:3, 3] - np.linalg.inv(prior_cw)[:3, 3]) <= self.cfg.prior_gate_m:
            return found
        cam = pts @ prior_cw[:3, :3].T + prior_cw[:3, 3]
        z = np.maximum(cam[:, 2], 1e-6)
        err = np.linalg.norm(cam[:, :2] / z[:, None] * self.k[[0, 1], [0, 1]] + self.k[:2, 2] - px, axis=1)
        agree = np.flatnonzero((err < self.cfg.prior_gate_px) & (cam[:, 2] > 0))
        again = self._solve(pts[agree], px[agree], pc[agree], ok[agree], prior_cw, self.cfg.min_inliers)
        return found if again is None else again

    def _moved(self, points_w: np.ndarray, points_c: np.ndarray, valid: np.ndarray) -> np.ndarray:
        """(M,) bool: matches whose 3-D point moved, by rigidity, independent of any pose estimate.

        A rigid motion keeps distances: for static points |p_i - p_j| (map) equals |q_i - q_j|
        (current camera frame). Each match is compared with up to 256 anchor matches; one whose
        distances disagree (beyond ``dynamic_threshold_m`` + ``dynamic_threshold_coeff`` (z_i^2 +
        z_j^2)) with most anchors has moved: the static scene is the majority of what is seen."""
        idx = np.flatnonzero(valid)
        out = np.zeros(len(points_w), bool)
        if len(idx) < 12:
            return out
        rng = np.random.default_rng(max(self.frame_index, 0))  # anchors: deterministic per frame
        anchors = idx if len(idx) <= 256 else rng.choice(idx, 256, replace=False)
        d_map = np.linalg.norm(points_w[idx, None] - points_w[None, anchors], axis=-1)
        d_cur = np.linalg.norm(points_c[idx, None] - points_c[None, anchors], axis=-1)
        z = points_c[:, 2]
        tol = self.cfg.dynamic_threshold_m + self.cfg.dynamic_threshold_coeff * (z[idx, None] ** 2 + z[None, anchors] ** 2)
        agree = (np.abs(d_map - d_cur) < tol).mean(axis=1)
        out[idx] = agree < 0.5
        return out

    def _relocalize(self, pix, des, points_c, valid):
        for kf in reversed(self.keyframes[-self.cfg.relocalize_keyframes:]):
            static = np.flatnonzero(~kf.dynamic)
            pairs = self._match(des, kf.descriptors[static])
            if len(pairs) < self.cfg.relocalize_min_inliers:
                continue
            found = self._solve(kf.points_w[static[pairs[:, 1]]], pix[pairs[:, 0]], points_c[pairs[:, 0]],
                                valid[pairs[:, 0]], None, self.cfg.relocalize_min_inliers)
            if found is not None:
                return found
        return None

    def _add_keyframe(self, des, points_c, valid) -> None:
        keep = valid.copy()
        keep[self._moving_keypoints] = False
        pts_w = points_c[keep] @ self.pose_wc[:3, :3].T + self.pose_wc[:3, 3]
        self.keyframes.append(Keyframe(self.frame_index, self.pose_wc.copy(), des[keep].copy(), pts_w,
                                       np.zeros(len(pts_w), bool)))

    def _needs_keyframe(self, inliers: int) -> bool:
        last = self.keyframes[-1].pose_wc
        rel = np.linalg.inv(last) @ self.pose_wc
        return (inliers < self.cfg.keyframe_min_inliers or np.linalg.norm(rel[:3, 3]) > self.cfg.keyframe_max_translation_m
                or _angle_deg(rel[:3, :3]) > self.cfg.keyframe_max_rotation_deg)

    def track(self, rgb, depth) -> VoResult:
        """Estimate the pose of the next frame: ``rgb`` (H, W, 3) uint8, ``depth`` (H, W) metres."""
        self.frame_index += 1
        self._moving_keypoints = np.zeros(0, int)
        rgb = np.asarray(rgb.cpu() if hasattr(rgb, "cpu") else rgb)
        depth = np.asarray(depth.cpu() if hasattr(depth, "cpu") else depth, np.float32)
        pix, des, points_c, valid = self._features(rgb, depth)
        inliers = 0
        if not self.keyframes:
            if valid.sum() >= self.cfg.relocalize_min_inliers:
                self._add_keyframe(des, points_c, valid)
                self.state = TrackState.INITIALIZED
        else:
            prev_wc = self.pose_wc
            predicted_wc = prev_wc @ self.velocity
            if self.state == TrackState.LOST:
                found = self._relocalize(pix, des, points_c, valid) if len(des) else None
                state = TrackState.RECOVERED
            else:
                found = self._track_local_map(pix, des, points_c, valid, np.linalg.inv(predicted_wc)) if len(des) else None
                state = TrackState.TRACKING
                if found is not None and _angle_deg(prev_wc[:3, :3].T @ np.linalg.inv(found[0])[:3, :3]) > \
                        self.cfg.max_rotation_per_frame_deg:
                    found = None
            if found is None:
                self.state = TrackState.LOST
                self.pose_wc = predicted_wc
                # coast on a decaying velocity: a covered lens usually means the robot slows down or stops
                self.velocity = _interpolate_identity(self.velocity, 0.9)
            else:
                pose_cw, inliers = found
                self.pose_wc = np.linalg.inv(pose_cw)
                if state == TrackState.TRACKING:
                    self.velocity = np.linalg.inv(prev_wc) @ self.pose_wc
                else:
                    self.velocity = np.eye(4)
                self.state = state
                if state == TrackState.RECOVERED or self._needs_keyframe(inliers):
                    self._add_keyframe(des, points_c, valid)
        self.history.append(self.state)
        return VoResult(self.pose_wc.copy(), self.state, inliers, len(self.keyframes))


def _angle_deg(rotation: np.ndarray) -> float:
    """The rotation angle of a (3, 3) rotation matrix, degrees."""
    return float(np.degrees(np.arccos(np.clip((np.trace(rotation) - 1) / 2, -1, 1))))


def _interpolate_identity(motion: np.ndarray, factor: float) -> np.ndarray:
    """``motion`` scaled toward identity: translation times ``factor``, rotation angle times ``factor``."""
    import cv2  # noqa: PLC0415

    rvec, _ = cv2.Rodrigues(motion[:3, :3])
    rot, _ = cv2.Rodrigues(rvec * factor)
    out = np.eye(4)
    out[:3, :3], out[:3, 3] = rot, motion[:3, 3] * factor
    return out


__all__ = ["Keyframe", "RgbdOdometry", "TrackState", "VoCfg", "VoResult", "refine_pose"]
