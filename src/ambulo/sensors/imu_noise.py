"""Kalibr's IMU noise model, vectorized over time, worlds and axes.

Per axis, a measurement is ``y(t) = x(t) + b(t) + n(t)`` with white noise of
density sigma_n and a bias that random-walks with density sigma_b
(https://github.com/ethz-asl/kalibr/wiki/IMU-Noise-Model). In discrete time at
step dt: ``n[k] ~ N(0, sigma_n^2 / dt)`` and ``b[k] = b[k-1] + N(0, sigma_b^2 dt)``;
the bias starts at a turn-on value ``b[0] ~ N(0, sigma_0^2)``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import torch

from ..utils.validate import Checked


@dataclass(kw_only=True)
class ImuNoiseCfg(Checked):
    """Kalibr ``imu.yaml`` parameters, per axis (continuous-time densities)."""

    gyro_noise_density: float = 0.0
    """sigma_g (rad/s/sqrt(Hz))."""
    gyro_random_walk: float = 0.0
    """sigma_bg (rad/s^2/sqrt(Hz))."""
    gyro_turn_on_bias_std: float = 0.0
    """Std of the initial gyro bias (rad/s)."""
    accel_noise_density: float = 0.0
    """sigma_a (m/s^2/sqrt(Hz))."""
    accel_random_walk: float = 0.0
    """sigma_ba (m/s^3/sqrt(Hz))."""
    accel_turn_on_bias_std: float = 0.0
    """Std of the initial accelerometer bias (m/s^2)."""


def noiseless() -> ImuNoiseCfg:
    return ImuNoiseCfg()


def euroc_adis16448() -> ImuNoiseCfg:
    """The ADIS16448 of the EuRoC MAV dataset (``imu0/sensor.yaml``, 200 Hz).

    Turn-on biases are the RotorS ADIS16448 defaults (0.5 deg/s, 20 mg), since
    EuRoC's yaml does not state them.
    """
    return ImuNoiseCfg(
        gyro_noise_density=1.6968e-4, gyro_random_walk=1.9393e-5,
        gyro_turn_on_bias_std=math.radians(0.5),
        accel_noise_density=2.0e-3, accel_random_walk=3.0e-3,
        accel_turn_on_bias_std=0.020 * 9.81,
    )


class KalibrNoise:
    """White noise plus random-walk bias for (num_worlds, 3) signals.

    Args:
      noise_density: sigma_n per axis, in signal units times sqrt(s) (see ImuNoiseCfg).
      random_walk: sigma_b per axis.
      turn_on_bias_std: std of the initial bias.
      num_worlds: N.
      generator: the torch generator all draws come from (determinism).
      dtype: of the draws and the bias (the engine's).
    """

    def __init__(self, noise_density: float, random_walk: float, turn_on_bias_std: float,
                 num_worlds: int, generator: torch.Generator, dtype: torch.dtype = torch.float64):
        self.noise_density = float(noise_density)
        self.random_walk = float(random_walk)
        self._gen = generator
        self.bias = turn_on_bias_std * torch.randn(num_worlds, 3, generator=generator, dtype=dtype,
                                                   device=generator.device)
        """(N, 3) current bias, in the signal's units."""

    def sample(self, clean: torch.Tensor, dt_s: float | torch.Tensor,
               advance: torch.Tensor | None = None) -> torch.Tensor:
        """Noisy readings (T, N, 3) for clean signals (T, N, 3) sampled every ``dt_s``.

        ``dt_s`` is a float or an (N,) tensor (worlds sampled at different
        intervals). The bias state advances by T steps in the worlds where
        ``advance`` (N,) bool is true (default all).
        """
        steps, n = clean.shape[0], clean.shape[1]
        dev = self.bias.device
        dt = dt_s.to(dev, self.bias.dtype).reshape(-1, 1) if torch.is_tensor(dt_s) else dt_s
        white_std = self.noise_density / (dt ** 0.5)
        walk_std = self.random_walk * (dt ** 0.5)
        shape = (steps, n, 3)
        white = torch.randn(shape, generator=self._gen, dtype=self.bias.dtype, device=dev) * white_std
        walk = torch.randn(shape, generator=self._gen, dtype=self.bias.dtype, device=dev) * walk_std
        bias = self.bias + torch.cumsum(walk, 0)
        last = bias[-1].clone()
        self.bias = last if advance is None else torch.where(advance[:, None], last, self.bias)
        return clean + bias + white
