"""Isaac Sim's ``IMUSensor`` (``isaacsim.sensors.physics`` / ``omni.isaac.sensor``) on ambulo.

A face over ``ambulo.sensors.Imu`` (MuJoCo accelerometer, gyro and frame-orientation sensors at
a site, batched over worlds). Readings are in the IMU frame: ``lin_acc`` m/s^2 (specific force:
+9.81 on the up axis at rest with ``read_gravity=True``, the body's acceleration without it),
``ang_vel`` rad/s, ``orientation`` wxyz in the world; NumPy float32 of world 0, as Isaac's
default backend. The ``*_filter_size`` arguments average that many of the latest samples
(Isaac's rolling-average filters); samples are taken every ``dt`` of simulated time.
"""

from __future__ import annotations

from collections import deque

import numpy as np
import torch

from ambulo.sensors import Imu, ImuCfg
from ambulo.utils.rotations import quat_to_mat

from .base_sensor import BaseSensor, due, period_from


class IMUSensor(BaseSensor):
    """Isaac's ``IMUSensor(prim_path, name, frequency, dt, translation, orientation, ...)``.

    ``prim_path`` is the sensor's path under the body (or site) it rides on, e.g.
    ``/World/robot/pelvis/imu_sensor``; ``translation`` (m) and ``orientation`` (wxyz) place it
    in that parent's frame. Without ``frequency``/``dt`` it samples every physics step.
    """

    def __init__(self, prim_path: str, name: str = "imu_sensor", frequency: float | None = None,
                 dt: float | None = None, translation=None, position=None, orientation=None,
                 linear_acceleration_filter_size: int = 1, angular_velocity_filter_size: int = 1,
                 orientation_filter_size: int = 1):
        if position is not None and translation is not None:
            raise ValueError("IMUSensor: pass translation= (in the parent's frame) or position=, not both")
        offset = translation if translation is not None else position  # Isaac treats both as local
        period = period_from(frequency, dt, "IMUSensor")
        self._period = period
        """s between samples; None: every physics step."""
        cfg = ImuCfg(prim_path=prim_path)
        if offset is not None:
            cfg.offset_pos = tuple(float(v) for v in np.asarray(offset, float).reshape(3))
        if orientation is not None:
            quat = np.asarray(orientation, float).reshape(4)
            cfg.offset_quat = tuple(float(v) for v in quat / np.linalg.norm(quat))
        self._sizes = {key: max(int(size or 1), 1) for key, size in (
            ("lin_acc", linear_acceleration_filter_size), ("ang_vel", angular_velocity_filter_size),
            ("orientation", orientation_filter_size))}
        self._history: dict[str, deque] = {}
        self._last_sample_s: float | None = None
        self._frame = {"time": 0.0, "physics_step": 0.0, "lin_acc": np.zeros(3, np.float32),
                       "ang_vel": np.zeros(3, np.float32),
                       "orientation": np.array([1.0, 0.0, 0.0, 0.0], np.float32), "is_valid": False}
        super().__init__(Imu(cfg), name)

    def _after_initialize(self) -> None:
        self._on_reset()
        self.sensor.update_period_s = 0.0  # the wrapped IMU samples when asked; the schedule is ours

    def _on_reset(self) -> None:
        self._history = {key: deque(maxlen=size) for key, size in self._sizes.items()}
        self._last_sample_s = None

    def update(self, dt_s: float) -> None:
        """After each physics step: sample when a new period began, whether or not anyone reads."""
        super().update(dt_s)
        if not self._paused and due(self._last_sample_s, self._sim_time(), self._period or 0.0):
            self._sample()

    def _sample(self) -> None:
        data = self.sensor.get_current_frame()  # period 0: a fresh (noise-free) sample
        self._last_sample_s = self._sim_time()  # rounded to whole steps (float32 time on a GPU)
        self._history["lin_acc"].append(data.lin_acc_b[0].clone())
        self._history["ang_vel"].append(data.ang_vel_b[0].clone())
        self._history["orientation"].append(data.quat_w[0].clone())

    def get_current_frame(self, read_gravity: bool = True) -> dict:
        """``{"time": s, "physics_step": float, "lin_acc": (3,), "ang_vel": (3,), "orientation":
        (4,) wxyz, "is_valid": bool}``; a paused sensor keeps its last frame (``is_valid`` False)."""
        if not self.initialized:
            return self._frame
        if self._paused:
            self._frame["is_valid"] = False
            return self._frame
        if self._last_sample_s is None:  # read right after a reset: sample the initial state
            self._sample()
        lin_acc = torch.stack(list(self._history["lin_acc"])).mean(0).numpy()
        ang_vel = torch.stack(list(self._history["ang_vel"])).mean(0).numpy()
        quat = _mean_quat(torch.stack(list(self._history["orientation"])).numpy())
        if not read_gravity:
            # the accelerometer reads a - g in the sensor frame: add R^T g back
            gravity = np.asarray(self.sensor.engine.model.opt.gravity, float)
            lin_acc = lin_acc + quat_to_mat(quat).T @ gravity
        self._frame.update(time=float(self._last_sample_s), physics_step=self._physics_step(),
                           lin_acc=lin_acc.astype(np.float32), ang_vel=ang_vel.astype(np.float32),
                           orientation=quat.astype(np.float32), is_valid=True)
        return self._frame

    # -- rates -----------------------------------------------------------------------
    def get_frequency(self) -> int:
        return int(round(1.0 / self.get_dt()))

    def set_frequency(self, value: float) -> None:
        self._period = period_from(value, None, "IMUSensor")

    def get_dt(self) -> float:
        """s between samples (the physics step unless set)."""
        if self._period is None:
            world = self._world
            return world.get_physics_dt() if world is not None else float(self._require_engine().model.opt.timestep)
        return self._period

    def set_dt(self, value: float) -> None:
        self._period = period_from(None, value, "IMUSensor")


def _mean_quat(quats: np.ndarray) -> np.ndarray:
    """Normalized mean of (k, 4) wxyz quaternions, each flipped to the first one's hemisphere."""
    signs = np.where(quats @ quats[0] < 0, -1.0, 1.0)
    mean = (quats * signs[:, None]).mean(0)
    return mean / np.linalg.norm(mean)


__all__ = ["IMUSensor"]
