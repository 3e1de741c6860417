"""RGB-D visual odometry (``RgbdOdometry``) and its parts.

- ``config``: ``VoCfg``, ``KorniaFeaturesCfg``, the all-torch preset ``kornia_vo_cfg`` and ``TrackState``
  (below every other module here, so none imports the tracker for its settings);
- ``odometry``: the tracker (matching to a local map of keyframes, RANSAC, refinement, relocalisation);
- ``features``: the front ends (OpenCV ORB on the host, kornia corners + RootSIFT on any device);
- ``pnp_torch``: batched RGB-D RANSAC in torch; ``refine``: the Gauss-Newton pose refinement;
  ``refine_graph``: that refinement replayed from CUDA graphs;
- ``imu``: gyro aiding (``GyroSamples``, ``GyroAid``);
- ``eval``: the head-camera walk run through the odometry and scored (imports the sim; not loaded here).
"""

from .config import KorniaFeaturesCfg, TrackState, VoCfg, head_camera_vo_cfg, kornia_vo_cfg
from .imu import GyroSamples
from .odometry import RgbdOdometry, VoResult

__all__ = ["GyroSamples", "KorniaFeaturesCfg", "RgbdOdometry", "TrackState", "VoCfg", "VoResult", "head_camera_vo_cfg",
           "kornia_vo_cfg"]
