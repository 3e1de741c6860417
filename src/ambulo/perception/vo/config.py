"""The odometry's configuration: ``VoCfg`` (features, matching, RANSAC, keyframe policy),
its kornia front end's ``KorniaFeaturesCfg``, the all-torch preset ``kornia_vo_cfg``, and the
``TrackState`` a frame reports.

Its own module so the parts of the odometry (``features``, ``refine``, ``refine_graph``,
``odometry``) all read the config from below instead of from the tracker that uses them.
"""

from __future__ import annotations

import enum
from dataclasses import dataclass, field
from typing import Literal

from ambulo.utils.checks import InvalidValueError, check_int, check_positive
from ambulo.utils.validate import Checked


class TrackState(enum.Enum):
    INITIALIZED = "initialized"
    TRACKING = "tracking"
    LOST = "lost"
    RECOVERED = "recovered"
    """Relocalised against the keyframes: the absolute pose is back."""
    REINITIALIZED = "reinitialized"
    """Relocalisation failed for ``VoCfg.reinit_after_lost_frames``: a new map started at the coasted pose."""


@dataclass(kw_only=True)
class KorniaFeaturesCfg(Checked):
    """The kornia front end. The defaults were chosen on the seeded head-camera walk (300 frames,
    640x480, CPU; benchmarks/results/cpu-2026-11-24-vo.md): every Shi-Tomasi variant tried (NMS
    window, quality, corner count, ratio, oriented or 32 px patches) tracked within 0.11-0.20 cm
    ATE, so the cheapest won: upright 16 px patches take half the time of oriented or 32 px ones."""

    response: Literal["gftt", "harris"] = "gftt"
    """Corner response: Shi-Tomasi's min eigenvalue (``gftt_response``) or Harris. Harris measured
    worse (0.31 cm ATE against 0.13, with ``min_response`` lowered to 1e-8 for its ~80x smaller
    response; at 1e-6 it keeps ~140 corners and loses track)."""
    nms_window_px: int = 3
    """Non-maximum suppression window (odd), px."""
    quality: float = 0.001
    """Corners weaker than this fraction of the frame's strongest are dropped (OpenCV's
    ``goodFeaturesToTrack`` calls it ``qualityLevel``)."""
    min_response: float = 1e-6
    """Absolute floor of the response (image in [0, 1], kornia's normalised Sobel): keeps a black or
    uniform frame, whose strongest response is round-off, from yielding corners."""
    border_px: int = 16
    """Corners this close to the image border are dropped (their patch would leave the image)."""
    patch_radius_px: float = 16.0
    """Half the side of the square image region a descriptor describes, px (ORB's patch is 31 px)."""
    descriptor_patch_px: int = 16
    """SIFT patch side, px. The region (2 x ``patch_radius_px``) is sampled from the pyramid level
    that gives it this many pixels: 16 of a 32 px region reads the half-resolution level, smoothed
    by ``pyrdown`` rather than aliased."""
    orient: bool = False
    """Rotate each patch to its dominant gradient (``LAFOrienter``) for roll invariance. A walking
    head camera barely rolls: upright descriptors match better and cost less."""


@dataclass(kw_only=True)
class VoCfg(Checked):
    """Features, matching, RANSAC and keyframe policy of ``RgbdOdometry`` (``kornia_vo_cfg`` gives
    the all-torch variant)."""

    features: Literal["orb", "kornia"] = "orb"
    """``"orb"``: OpenCV ORB on the host; ``"kornia"``: kornia corners + RootSIFT on ``device``."""
    pnp: Literal["opencv", "torch"] = "opencv"
    """RANSAC: OpenCV's ``solvePnPRansac`` (AP3P) on the host, or 3-point RGB-D hypotheses batched
    in torch on ``device`` (``vo.pnp_torch``)."""
    device: str = "cpu"
    """Torch device of the features, the map, matching and the refinement. With ``features="orb"``
    ORB, its matching and ``solvePnPRansac`` run in OpenCV on the host whatever this is; the keyframes'
    points, the rigidity check and the refinement (captured as CUDA graphs) run on it."""
    kornia: KorniaFeaturesCfg = field(default_factory=KorniaFeaturesCfg)
    """Detector and descriptor of ``features="kornia"``."""
    num_features: int = 1500
    """Features per frame (ORB-SLAM uses 1000-2000 ORB features at 640x480)."""
    fast_threshold: int = 12
    """ORB's FAST corner threshold (OpenCV's default 20 misses low-contrast texture)."""
    orb_patch_px: int = 31
    """ORB's descriptor patch side at the finest level, px (OpenCV's ``patchSize``; 31 is its default,
    sized for 640x480)."""
    orb_edge_px: int = 31
    """ORB's border without keypoints at every pyramid level, px (OpenCV's ``edgeThreshold``; keep it
    >= ``orb_patch_px``). At 320x240 the default 31 px border leaves 60 % of the image and far less
    of the coarse levels."""
    ratio_test: float = 0.8
    """Lowe's ratio: best descriptor distance < ratio * second best."""
    max_hamming: int = 64
    """ORB only: matches further apart than this many bits (of 256) are dropped."""
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
    match_window_px: float | None = None
    """Guided matching (``vo.guided``): a keypoint is matched only against the local map's points that
    the predicted pose projects within this many pixels of it; when the pose solved from those
    matches fails, the frame is matched against the whole local map again. None: always the whole
    local map (brute force). ``head_camera_vo_cfg`` sets it."""
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
    depth_edge_fraction: float = 0.02
    """A keypoint's 3x3 depth neighbourhood spanning more than this fraction of its depth is a depth
    edge (no point). A sensor with per-pixel depth noise sigma needs ~4 sigma (the range of 9 normal
    samples is ~3 sigma, often more): ``head_camera_vo_cfg`` allows 6 % for 1 % depth noise."""
    pixel_sigma: float = 1.0
    """Keypoint position noise, px (ORB keypoints and kornia corners sit on a pixel grid)."""
    depth_sigma_coeff: float = 0.002
    """Depth noise sigma = coeff * z^2 (m) in the refinement (Kinect-like; simulated depth is better)."""
    depth_sigma_min_m: float = 0.002
    refine_iterations: int = 6
    refine_stop_step: float | None = None
    """On the CPU, the refinement stops once an iteration's step is below this in every component
    (rad, m); None: always ``refine_iterations``. GPUs always run the full count (``vo.refine``)."""
    cuda_graphs: bool = True
    """On CUDA, replay the refinement from captured graphs (``vo.refine_graph``): one launch instead of
    ~35 an iteration; False runs it eagerly."""
    dynamic_threshold_m: float = 0.01
    """Rigidity tolerance (see ``moved_by_rigidity``): a match whose distances to the others changed
    by more is on a moving object; its map point is never matched again and its keypoint stays out
    of new keyframes."""
    dynamic_threshold_coeff: float = 0.001
    use_depth_residual: bool = True
    """Add the 3-D (depth) residual to the refinement; False refines on reprojection alone."""
    robust_loss: str = "tukey"
    """'tukey' (redescending: points on a moving object drop out) or 'huber'."""
    reinit_after_lost_frames: int = 15
    """Lost this many frames in a row, and the frame has texture (``relocalize_min_inliers`` points
    with depth) but relocalises against no keyframe: the camera moved on while blind (1 s of covered
    lens while walking round a corner), so start a new map at the coasted pose rather than stay
    lost. 15 frames: half a second of trying to relocalise at 30 Hz."""
    coast_window_frames: int = 33
    """With a gyro, lost frames move the IMU on at its mean velocity over this many tracked frames
    (one stride of a human walk, 1.1 s at 30 Hz: the head's bob and sway average out)."""
    gyro_gate_deg: float = 3.0
    """With a gyro (``track(..., gyro=...)``): a solved pose whose rotation since the previous frame
    differs from the gyro's by more than this is refused (replaces ``max_rotation_per_frame_deg``).
    The bias-corrected gyro drifts ~0.01 deg over a frame, the odometry's rotation errs ~0.05 deg; a
    wrong consensus is off by degrees."""
    gyro_bias_gain: float = 0.02
    """Weight of each tracked frame in the gyro bias estimate (exponential average: ~50 frames,
    under 2 s at 30 Hz, to converge; see ``vo.imu``)."""

    def __post_init__(self):
        check_int("num_features", self.num_features, "pass a count > 0, e.g. 1500", minimum=1)
        check_int("orb_patch_px", self.orb_patch_px, "pass a side in pixels >= 3, e.g. 31", minimum=3)
        if self.orb_edge_px < self.orb_patch_px:
            raise InvalidValueError("VoCfg.orb_edge_px", self.orb_edge_px, f"is under orb_patch_px={self.orb_patch_px}",
                                    "pass orb_edge_px >= orb_patch_px (a patch must fit inside the image)")
        check_int("min_inliers", self.min_inliers, "pass a count >= 6 (PnP needs 4+)", minimum=6)
        check_positive("ransac_reprojection_px", self.ransac_reprojection_px, "pass pixels > 0, e.g. 2")
        if self.match_window_px is not None:
            check_positive("match_window_px", self.match_window_px, "pass pixels > 0, e.g. 16, or None (brute force)")
        check_int("reinit_after_lost_frames", self.reinit_after_lost_frames, "pass a count of frames >= 1, e.g. 15",
                  minimum=1)
        check_int("coast_window_frames", self.coast_window_frames, "pass a count of frames >= 1, e.g. 33", minimum=1)
        check_positive("depth_edge_fraction", self.depth_edge_fraction, "pass a fraction > 0, e.g. 0.02")
        check_positive("gyro_gate_deg", self.gyro_gate_deg, "pass degrees > 0, e.g. 3")
        if not 0.0 <= self.gyro_bias_gain < 1.0:
            raise InvalidValueError("VoCfg.gyro_bias_gain", self.gyro_bias_gain, "must be in [0, 1)",
                                    "pass e.g. 0.02 (0 keeps the bias at zero)")
        if self.features not in ("orb", "kornia"):
            raise InvalidValueError("VoCfg.features", self.features, "unknown front end", "pass 'orb' or 'kornia'")
        if self.pnp not in ("opencv", "torch"):
            raise InvalidValueError("VoCfg.pnp", self.pnp, "unknown RANSAC", "pass 'opencv' or 'torch'")
        super().__post_init__()


def kornia_vo_cfg(device: str = "cpu") -> VoCfg:
    """The all-torch odometry on ``device``: kornia features, torch RANSAC and refinement.

    1000 corners: the seeded room shows ~500-800 Shi-Tomasi corners above ``quality`` in a 640x480
    view, so more would only add weak ones. Ratio 0.8 is Lowe's (2004) for SIFT distances. Four
    refinement iterations, not six: the 4th step is already under 3 um (``vo.refine``), and on a
    GPU each iteration is ~35 kernel launches, the largest share of a frame's."""
    return VoCfg(features="kornia", pnp="torch", device=device, num_features=1000, ratio_test=0.8,
                 refine_iterations=4)


def head_camera_vo_cfg() -> VoCfg:
    """ORB odometry for a robot's small, low-contrast head camera (the navigator's 320x240 view of
    painted walls and plain floors, ``navigation.world``).

    FAST threshold 5 instead of 12 and an ORB patch and border of 15 px instead of 31 (the 640x480
    patch scaled to 320 px). Measured on two recorded head-camera walks in apartments 0 and 1
    (/tmp replays of oracle episodes, 211 and 134 frames at 10 Hz): the defaults see 0-60 corners
    facing a wall at 1.4 m and track 194/211 and 85/134 frames (0.26 m and 0.57 m ATE); this
    preset tracks 211/211 and 118/134 (0.02 m and 0.10 m). What is left untracked is a plain
    wall filling the view: no corner detector finds anything there.

    A 6 % depth-edge tolerance (``depth_edge_fraction``) for a sensor with 1 % depth noise
    (``navigation.randomization``): at 2 % the 3x3 neighbourhood of nearly every keypoint looks
    like a depth edge (the range of 9 noisy samples is ~3 sigma), and the noisy scripted walk in
    apartment 1000 tracked 75 % of its frames (tests/navigation/test_vo_apartment.py). Gaussian
    pre-smoothing of the grey image against RGB noise was tried and made it worse (sigma 0.8-2 px:
    the walls' faint texture blurs away before the noise does).

    Guided matching in a 16 px window (``match_window_px``): with the legs' motion prior the map
    points that ended as inliers were projected within 11 px (99th percentile 7.5 px) of their
    keypoints on a recorded full-mode episode (apartment 201, 200 frames); 16 px leaves a margin and
    a frame whose prediction is worse falls back on the whole local map. The refinement stops once a
    step is under 10 um / 10 urad (``refine_stop_step``): the next would be ~20x smaller. On the
    recorded episodes of apartments 201 and 203 (``benchmarks/nav_vo.py``) this cut the odometry's
    CPU time a frame from 82 to 53 ms (median) and its ATE from 2.2 to 1.5 cm (likely, not
    measured: among the whole local map a keypoint's nearest two are often one point seen from two
    keyframes, which the ratio test refuses; in the window there are fewer such pairs)."""
    return VoCfg(fast_threshold=5, orb_patch_px=15, orb_edge_px=15, depth_edge_fraction=0.06, match_window_px=16.0,
                 refine_stop_step=1e-5)


__all__ = ["KorniaFeaturesCfg", "TrackState", "VoCfg", "head_camera_vo_cfg", "kornia_vo_cfg"]
