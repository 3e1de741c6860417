"""The gyro of the head-camera walks: clean angular rates from the walk, Kalibr noise added, cut
into one ``GyroSamples`` per camera frame.

The policy walk reads MuJoCo's gyro at the head camera's mount site every physics step
(``Imu.clean_reading``: after a semi-implicit Euler step, the rate the step turned the body at);
the kinematic walk takes its scripted pelvis orientation's mean rate over each sample period
(``root_pose``: the head is rigid on the pelvis there). Both add the same noise model as
``ambulo.sensors.Imu`` (white noise, a random-walk bias and a turn-on bias; EuRoC's ADIS16448 by
default) from a seeded generator, so a restarted walk replays the same readings.
"""

from __future__ import annotations

import numpy as np
import torch
from scipy.spatial.transform import Rotation

from ambulo.sensors.imu_noise import ImuNoiseCfg, KalibrNoise

from ..vo.imu import GyroSamples


class GyroStream:
    """Noisy gyro readings in time order; ``take`` hands out those since the last frame."""

    def __init__(self, noise: ImuNoiseCfg, seed: int):
        self.noise_cfg, self.seed = noise, seed
        self.reset()

    def reset(self) -> None:
        gen = torch.Generator().manual_seed(self.seed)
        c = self.noise_cfg
        self._noise = KalibrNoise(c.gyro_noise_density, c.gyro_random_walk, c.gyro_turn_on_bias_std, 1, gen)
        self._times: list[float] = []
        self._rates: list[np.ndarray] = []

    @property
    def last_time_s(self) -> float:
        return self._times[-1] if self._times else -np.inf

    def add(self, times_s: np.ndarray, clean_rad_s: np.ndarray, dt_s: float) -> None:
        """Readings at ``times_s`` (K,) (after ``last_time_s``, ``dt_s`` apart) of the clean rates
        ``clean_rad_s`` (K, 3)."""
        noisy = self._noise.sample(torch.as_tensor(clean_rad_s, dtype=torch.float64)[:, None], dt_s)[:, 0]
        self._times.extend(float(t) for t in np.atleast_1d(times_s))
        self._rates.extend(noisy.numpy())

    def latest(self) -> tuple[float, np.ndarray] | None:
        """The newest reading ``(time s, (3,) rad/s)`` without taking it, or None before the first: a
        consumer that integrates every physics step (``navigation.leg_odometry``) reads alongside the
        camera frames' ``take``."""
        if not self._times:
            return None
        return self._times[-1], self._rates[-1]

    def take(self) -> GyroSamples | None:
        """The readings since the last ``take``, with the last one kept as the next interval's first;
        None when fewer than two are held (the first frame)."""
        if len(self._times) < 2:
            return None
        out = GyroSamples(np.array(self._times), np.array(self._rates))
        self._times, self._rates = self._times[-1:], self._rates[-1:]
        return out


def mean_body_rates_rad_s(orientation_at, times_s: np.ndarray, dt_s: float) -> np.ndarray:
    """(K, 3) mean angular velocity in the body frame over ``(t - dt_s, t]`` for each of ``times_s``
    (K,), of the orientation ``orientation_at(t) -> (3, 3)`` (body to world):
    ``log(R(t - dt)^T R(t)) / dt`` (the ``GyroSamples`` convention; exact through a rate that jumps)."""
    before = np.stack([orientation_at(t - dt_s) for t in times_s])
    now = np.stack([orientation_at(t) for t in times_s])
    return Rotation.from_matrix(np.transpose(before, (0, 2, 1)) @ now).as_rotvec() / dt_s


__all__ = ["GyroStream", "mean_body_rates_rad_s"]
