"""Velocity commands for locomotion: resampled within episodes, heading control, standing envs.

As mjlab's / Isaac Lab's ``UniformVelocityCommand``: every env draws a planar velocity
command (heading frame) and a yaw rate, and draws again after a random resampling time, so
one episode trains several commands. With heading control a share of envs is given a
target heading instead of a yaw rate, and the yaw rate command steers towards it
(``stiffness * heading error``, clipped to the yaw-rate range). A share of envs is told to
stand (zero command). Everything is (N,) tensors updated with masks.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import torch

from ambulo.core.rows import num_rows, put_rows, select_rows
from ambulo.utils.validate import Checked, rule


@dataclass(kw_only=True)
class VelocityCommandCfg(Checked):
    lin_vel_x_m_s: tuple[float, float] = field(default=(-1.0, 1.0), metadata=rule(pair=True))
    """Forward velocity range, heading frame."""
    lin_vel_y_m_s: tuple[float, float] = field(default=(-0.5, 0.5), metadata=rule(pair=True))
    """Leftward velocity range, heading frame."""
    yaw_rate_rad_s: tuple[float, float] = field(default=(-1.0, 1.0), metadata=rule(pair=True))
    """Yaw-rate range; heading-controlled envs are clipped to it too."""
    heading_rad: tuple[float, float] = field(default=(-math.pi, math.pi), metadata=rule(pair=True))
    """Target heading range for heading-controlled envs."""
    heading_fraction: float = 0.5
    """Share of envs that track a target heading instead of a yaw rate."""
    heading_stiffness: float = 0.5
    """Yaw rate per rad of heading error, 1/s."""
    standing_fraction: float = 0.1
    """Share of envs commanded to stand still."""
    resampling_time_s: tuple[float, float] = field(default=(4.0, 8.0), metadata=rule(pair=True))
    """A new command is drawn after a time uniform in this range."""


def wrap_to_pi(angle: torch.Tensor) -> torch.Tensor:
    return torch.remainder(angle + math.pi, 2.0 * math.pi) - math.pi


class VelocityCommand:
    """(N, 3) commands (vx, vy in the heading frame, m/s; yaw rate, rad/s) for N envs."""

    def __init__(self, cfg: VelocityCommandCfg, num_envs: int, generator: torch.Generator,
                 device: torch.device):
        self.cfg, self.num_envs, self.gen, self.device = cfg, num_envs, generator, device
        f32 = dict(dtype=torch.float32, device=device)
        self.command = torch.zeros(num_envs, 3, **f32)
        """(N, 3): commanded (vx, vy) in the heading frame, m/s, and yaw rate, rad/s."""
        self.heading_target = torch.zeros(num_envs, **f32)
        self.is_heading = torch.zeros(num_envs, dtype=torch.bool, device=device)
        self.is_standing = torch.zeros_like(self.is_heading)
        self.time_left_s = torch.zeros(num_envs, **f32)
        self.range_scale = torch.ones((), **f32)
        """() share of the velocity and yaw-rate ranges drawn from, in (0, 1]: a curriculum
        lowers it at the start of training (a device scalar, so changing it never syncs)."""
        c = cfg
        # ranges of the seven quantities one resample draws: vx, vy, yaw rate, heading, the two
        # share draws (heading-controlled, standing) and the resampling time
        self._low = torch.tensor([c.lin_vel_x_m_s[0], c.lin_vel_y_m_s[0], c.yaw_rate_rad_s[0], c.heading_rad[0],
                                  0.0, 0.0, c.resampling_time_s[0]], **f32)
        self._span = torch.tensor([c.lin_vel_x_m_s[1], c.lin_vel_y_m_s[1], c.yaw_rate_rad_s[1], c.heading_rad[1],
                                   1.0, 1.0, c.resampling_time_s[1]], **f32) - self._low

    def resample(self, rows: torch.Tensor | None) -> None:
        """Draw new commands for the envs ``rows`` selects (``ambulo.core.rows``)."""
        c, n = self.cfg, num_rows(rows, self.num_envs)
        # one draw for all seven quantities of the selected rows
        u = torch.rand(n, 7, generator=self.gen, device=self.device)
        v = torch.addcmul(self._low, self._span, u)
        put_rows(self.command, slice(None), v[:, :3] * self.range_scale, rows)
        put_rows(self.heading_target[:, None], slice(None), v[:, 3:4], rows)
        put_rows(self.is_heading[:, None], slice(None), v[:, 4:5] < c.heading_fraction, rows)
        put_rows(self.is_standing[:, None], slice(None), v[:, 5:6] < c.standing_fraction, rows)
        put_rows(self.time_left_s[:, None], slice(None), v[:, 6:7], rows)

    def update(self, dt_s: float, heading_w: torch.Tensor) -> None:
        """Advance timers by ``dt_s``, resample where due, steer heading envs, zero standing ones.

        ``heading_w``: (N,) current yaw of each robot, rad.
        """
        self.time_left_s -= dt_s
        rows = select_rows(self.time_left_s <= 0.0)
        if rows is not None:
            self.resample(rows)
        low, high = self.cfg.yaw_rate_rad_s
        steer = self.cfg.heading_stiffness * wrap_to_pi(self.heading_target - heading_w.float())
        steer = torch.minimum(torch.maximum(steer, low * self.range_scale), high * self.range_scale)
        self.command[:, 2] = torch.where(self.is_heading, steer, self.command[:, 2])
        self.command.masked_fill_(self.is_standing[:, None], 0.0)


__all__ = ["VelocityCommand", "VelocityCommandCfg", "wrap_to_pi"]
