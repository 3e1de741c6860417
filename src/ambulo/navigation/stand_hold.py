"""Standing still with a walking policy: a position-hold loop on the pose estimate.

The shipped walking policy never stands still: told (0, 0, 0) it steps in place and creeps, about
4 cm/s in a direction of its own (0.41 m in 10 s on the test room's floor), so a robot told to stand
at its goal walks off it. ``PositionHold`` latches the pose where standing begins and commands
the velocity that brings the robot back to it, a PI loop in the robot's heading frame:

    v_b = kp * e_b + ki * integral(e_b dt)          (clipped to ``max_speed_m_s``)
    yaw_rate = k_yaw * e_yaw                         (clipped to ``max_yaw_rate_rad_s``)

The proportional term pulls the robot back; the integral term learns the policy's creep (a
constant velocity bias: with P alone the robot settles where ``kp * e`` cancels it, 2 cm at
``kp`` = 2 /s) and is clipped to ``max_bias_m_s`` so a stale pose (no estimate while the camera is
lost) cannot wind it up. It holds whatever pose it is given: the navigator's estimate.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..utils.validate import Checked


@dataclass(kw_only=True)
class StandHoldCfg(Checked):
    gain_per_s: float = 2.0
    """Proportional gain: commanded m/s per m of position error, 1/s."""
    integral_gain_per_s2: float = 1.0
    """Integral gain: commanded m/s per m s of accumulated error, 1/s^2 (the creep, ~0.04 m/s, is
    learned in a few seconds)."""
    max_bias_m_s: float = 0.1
    """The integral term's command stays within this, m/s (anti-windup; the creep is ~0.04)."""
    max_speed_m_s: float = 0.25
    """Commanded speed at most, m/s: a gentle step back, not a walk."""
    yaw_gain_per_s: float = 1.0
    """Yaw rate per rad of heading error, 1/s."""
    max_yaw_rate_rad_s: float = 0.5


class PositionHold:
    """Velocity commands that keep a walking policy on one pose (module docstring)."""

    def __init__(self, cfg: StandHoldCfg | None = None):
        self.cfg = cfg or StandHoldCfg()
        self.release()

    def release(self) -> None:
        """Forget the held pose: the next ``command`` latches a new one."""
        self.hold_xyyaw: np.ndarray | None = None
        """(3,) the pose held (x m, y m, yaw rad, world frame), or None."""
        self._integral_b = np.zeros(2)

    def command(self, pose_xyyaw: np.ndarray, dt_s: float) -> tuple[float, float, float]:
        """(vx m/s, vy m/s, yaw rate rad/s) in the heading frame of ``pose_xyyaw`` (the robot now),
        one control period ``dt_s`` after the last call; the first call after ``release`` holds
        ``pose_xyyaw`` itself."""
        c = self.cfg
        pose = np.asarray(pose_xyyaw, float)
        if self.hold_xyyaw is None:
            self.hold_xyyaw = pose.copy()
        e_w = self.hold_xyyaw[:2] - pose[:2]
        cos, sin = math.cos(pose[2]), math.sin(pose[2])
        e_b = np.array([cos * e_w[0] + sin * e_w[1], -sin * e_w[0] + cos * e_w[1]])
        if c.integral_gain_per_s2 > 0:
            limit = c.max_bias_m_s / c.integral_gain_per_s2
            self._integral_b = np.clip(self._integral_b + e_b * dt_s, -limit, limit)
        v_b = c.gain_per_s * e_b + c.integral_gain_per_s2 * self._integral_b
        speed = float(np.linalg.norm(v_b))
        if speed > c.max_speed_m_s:
            v_b *= c.max_speed_m_s / speed
        e_yaw = math.atan2(math.sin(self.hold_xyyaw[2] - pose[2]), math.cos(self.hold_xyyaw[2] - pose[2]))
        yaw_rate = float(np.clip(c.yaw_gain_per_s * e_yaw, -c.max_yaw_rate_rad_s, c.max_yaw_rate_rad_s))
        return float(v_b[0]), float(v_b[1]), yaw_rate

    def turn_command(self, pose_xyyaw: np.ndarray, dt_s: float, yaw_rate_rad_s: float) -> tuple[float, float, float]:
        """Turn on the spot at ``yaw_rate_rad_s`` while holding the position (module docstring): the
        first call after ``release`` latches ``pose_xyyaw``'s position; the held heading follows
        the robot's, so standing after the turn keeps the heading turned to."""
        pose = np.asarray(pose_xyyaw, float)
        if self.hold_xyyaw is not None:
            self.hold_xyyaw[2] = pose[2]
        vx, vy, _ = self.command(pose, dt_s)
        return vx, vy, float(yaw_rate_rad_s)


__all__ = ["PositionHold", "StandHoldCfg"]
