"""The humanoid's head camera walked kinematically through a seeded apartment
(``ambulo.scenes.apartment``) along the geodesic of a sampled start/goal, with ground-truth poses:
what the mapping acceptance (``perception.occupancy_eval``, ``benchmarks/mapping.py``) maps and scores
against the apartment's exact occupancy.

The robot is *played*, as ``head_camera_walk.HeadCameraWalk`` plays it: its root moves along the path
at ``speed_mps`` (heading along the path, the head sweeping ``look_sweep_rad`` either side, as a
person glances around while walking), MuJoCo's forward kinematics places the head camera, and each
frame is rendered from it (RGB, metric depth, the true camera pose).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import torch

from ambulo.core import PhysicsCfg, Simulation
from ambulo.robots.humanoid import PELVIS_HEIGHT_M
from ambulo.scenes.apartment import Apartment
from ambulo.scenes.apartment_paths import StartGoal
from ambulo.utils.rotations import mat_to_quat
from ambulo.utils.validate import Checked

from ..frames import RgbdFrame
from .head_camera_walk import WalkCfg, capture_frame, head_camera


@dataclass(kw_only=True)
class ApartmentWalkCfg(Checked):
    """How the head camera walks the path."""

    speed_mps: float = 0.5
    """Walking speed along the path, m/s."""
    fps: float = 10.0
    """Frames per second of simulated time."""
    look_sweep_rad: float = 0.6
    """Amplitude of the head's sweep left and right of the heading, rad."""
    sweep_period_s: float = 4.0
    """Period of that sweep, s."""
    bob_m: float = 0.025
    """Vertical bob, m, twice per stride of 1.1 s."""


class ApartmentWalk:
    """Frames of the head camera walking ``episode.path_xy_m`` through ``apt`` (start to goal, then
    standing at the goal); ``num_frames`` covers the path once."""

    def __init__(self, apt: Apartment, episode: StartGoal, cfg: ApartmentWalkCfg | None = None, *,
                 width: int = 320, height: int = 240):
        self.apt, self.episode, self.cfg = apt, episode, cfg or ApartmentWalkCfg()
        path = np.asarray(episode.path_xy_m, np.float64)
        seg = np.linalg.norm(np.diff(path, axis=0), axis=1)
        keep = np.concatenate([[True], seg > 1e-9])  # repeated points have no heading
        self._path = path[keep]
        self._s = np.concatenate([[0.0], np.cumsum(seg[seg > 1e-9])])
        """(K,) arc length of each path point, m."""
        self.camera = head_camera(WalkCfg(), width, height)
        self.sim = Simulation(apt.build(robot_pose=episode.start_pose), PhysicsCfg())
        self.sim.add(self.camera)
        self.engine = self.sim.start()
        self._qpos = self.engine.field("qpos")

    @property
    def length_m(self) -> float:
        return float(self._s[-1])

    @property
    def num_frames(self) -> int:
        """Frames from the start to the goal at ``speed_mps``."""
        return int(math.ceil(self.length_m / self.cfg.speed_mps * self.cfg.fps)) + 1

    def root_pose(self, t_s: float) -> tuple[np.ndarray, np.ndarray]:
        """Pelvis position (3,) m and orientation (4,) wxyz at ``t_s``."""
        s = min(self.cfg.speed_mps * t_s, self.length_m)
        x, y = (np.interp(s, self._s, self._path[:, a]) for a in range(2))
        i = int(np.clip(np.searchsorted(self._s, s, side="right") - 1, 0, len(self._path) - 2))
        dx, dy = self._path[i + 1] - self._path[i]
        yaw = math.atan2(dy, dx) + self.cfg.look_sweep_rad * math.sin(2 * math.pi * t_s / self.cfg.sweep_period_s)
        z = PELVIS_HEIGHT_M - 0.02 + self.cfg.bob_m * math.cos(2 * math.pi * t_s / 0.55)
        c, sn = math.cos(yaw), math.sin(yaw)
        return np.array([x, y, z]), mat_to_quat(np.array([[c, -sn, 0.0], [sn, c, 0.0], [0.0, 0.0, 1.0]]))

    def frame(self, index: int) -> RgbdFrame:
        """Render frame ``index`` (at ``index / fps`` s): RGB, metric depth, the true camera pose."""
        t_s = index / self.cfg.fps
        pos, quat = self.root_pose(t_s)
        q = self._qpos[0]
        q[0:3] = torch.from_numpy(pos)
        q[3:7] = torch.from_numpy(quat)
        return capture_frame(self.camera, t_s)

    def close(self) -> None:
        self.camera.close()


__all__ = ["ApartmentWalk", "ApartmentWalkCfg"]
