"""Gyro aid of the visual odometry: the IMU's angular rates between two frames, integrated to the
camera's rotation, with the gyro bias estimated from the odometry while it tracks.

Loosely coupled: the odometry still solves every pose from the images. The gyro gives
- the rotation of the motion prediction (instead of the last frame's, which a head turn that
  starts or stops makes wrong),
- a gate on the solved pose: a rotation that disagrees with the gyro by more than
  ``VoCfg.gyro_gate_deg`` is refused (a wrong consensus),
- the rotation while tracking is lost (covered lens, textureless wall, a turn too fast for the
  images), when the pose would otherwise coast on a decaying guess.

The bias: a MEMS gyro reads ``w + b`` with a turn-on bias ``b`` of ~0.5 deg/s (ADIS16448), i.e.
15 deg of heading a minute if integrated alone. While tracking, the odometry's rotation over a
frame is far better than that, so the rotation left between the two, divided by the frame's
duration, is the bias error; an exponential average (``VoCfg.gyro_bias_gain``) of it converges
in a few seconds and is what is subtracted from the rates.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.spatial.transform import Rotation

from ambulo.utils.checks import Described, InvalidValueError


@dataclass
class GyroSamples:
    """Gyro readings spanning one frame interval, both ends included (the sample at the previous
    frame's time is the first, the one at this frame's time the last)."""

    time_s: np.ndarray
    """(N,) float64 sample times, increasing, s (N >= 2)."""
    ang_vel_rad_s: np.ndarray
    """(N, 3) float64 angular velocity in the IMU frame, rad/s (bias and noise included). Sample ``k``
    is the mean rate over ``(time_s[k-1], time_s[k]]``, as MEMS IMUs that average internally report
    it (and MuJoCo's gyro after a semi-implicit Euler step is exactly that); the first sample's
    rate belongs to the interval before the span and is not used."""

    def __post_init__(self):
        self.time_s = np.asarray(self.time_s, np.float64).reshape(-1)
        self.ang_vel_rad_s = np.asarray(self.ang_vel_rad_s, np.float64).reshape(-1, 3)
        if len(self.time_s) != len(self.ang_vel_rad_s) or len(self.time_s) < 2:
            raise InvalidValueError("GyroSamples", f"{len(self.time_s)} times, {len(self.ang_vel_rad_s)} rates",
                                    "needs as many times as rates, at least 2 (both ends of the frame interval)",
                                    "pass the samples from the previous frame's time to this frame's")
        if not (np.all(np.isfinite(self.time_s)) and np.all(np.isfinite(self.ang_vel_rad_s))):
            raise InvalidValueError("GyroSamples.time_s / ang_vel_rad_s", Described("not all finite"),
                                    "a NaN or inf would poison the pose", "drop the IMU's invalid samples first")
        if not np.all(np.diff(self.time_s) > 0):
            raise InvalidValueError("GyroSamples.time_s", self.time_s[:4].tolist(), "times must increase",
                                    "sort the samples by time and drop duplicates")

    @property
    def duration_s(self) -> float:
        return float(self.time_s[-1] - self.time_s[0])


def integrate_gyro(samples: GyroSamples, bias_rad_s: np.ndarray | None = None) -> np.ndarray:
    """(3, 3) rotation of the IMU frame from the first sample's time to the last's, ``R_first_last``:
    the product of ``exp((w_k - b) dt_k)`` over the intervals, each with the mean rate reported at
    its end (``GyroSamples.ang_vel_rad_s``); exact for that convention however the rate varies."""
    rates = samples.ang_vel_rad_s[1:]
    if bias_rad_s is not None:
        rates = rates - np.asarray(bias_rad_s, np.float64)
    steps = Rotation.from_rotvec(rates * np.diff(samples.time_s)[:, None])
    rot = np.eye(3)
    for step in steps.as_matrix():  # body-frame increments compose on the right
        rot = rot @ step
    return rot


class GyroAid:
    """The gyro's rotation of the camera between frames, and the online bias estimate.

    ``pose_cam_imu``: the IMU's pose in the camera frame from the extrinsic calibration, (4, 4)
    (``p_cam = R p_imu + t``), or its (3, 3) rotation alone (the IMU at the camera's origin). The
    IMU may sit anywhere on the same rigid body as the camera: the lever arm ``t`` matters when the
    pose is predicted through a fast turn (``RgbdOdometry``).
    """

    def __init__(self, pose_cam_imu: np.ndarray, bias_gain: float):
        pose = np.asarray(pose_cam_imu, np.float64)
        if pose.shape == (3, 3):
            pose = np.block([[pose, np.zeros((3, 1))], [np.zeros((1, 3)), np.ones((1, 1))]])
        rot = pose[:3, :3] if pose.shape == (4, 4) else None
        if rot is None or not np.allclose(rot @ rot.T, np.eye(3), atol=1e-6) or np.linalg.det(rot) < 0:
            raise InvalidValueError("pose_cam_imu", pose.round(4).tolist(), "not a (4, 4) pose or (3, 3) rotation",
                                    "pass the IMU's pose in the camera frame from the extrinsic calibration")
        self.pose_cam_imu = pose
        self.rot_cam_imu = pose[:3, :3]
        self.bias_gain = float(bias_gain)
        self.bias_rad_s = np.zeros(3)
        """(3,) current gyro bias estimate in the IMU frame, rad/s."""

    def camera_rotation(self, samples: GyroSamples) -> np.ndarray:
        """(3, 3) the camera's rotation over the samples' interval, ``R_prev_cur`` in the camera
        frame, from the bias-corrected rates."""
        rot_imu = integrate_gyro(samples, self.bias_rad_s)
        return self.rot_cam_imu @ rot_imu @ self.rot_cam_imu.T

    def update_bias(self, samples: GyroSamples, rot_prev_cur_cam: np.ndarray) -> None:
        """Move the bias estimate toward agreeing with the odometry's rotation ``rot_prev_cur_cam``
        (3, 3) over the samples' interval: with bias error ``e``, the corrected gyro over-rotates by
        ``e * duration``, which is the residual rotation vector."""
        rot_imu_vo = self.rot_cam_imu.T @ rot_prev_cur_cam @ self.rot_cam_imu
        residual = Rotation.from_matrix(rot_imu_vo.T @ integrate_gyro(samples, self.bias_rad_s)).as_rotvec()
        self.bias_rad_s = self.bias_rad_s + self.bias_gain * residual / samples.duration_s


__all__ = ["GyroAid", "GyroSamples", "integrate_gyro"]
