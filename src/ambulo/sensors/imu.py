"""IMU: specific force, angular velocity and orientation at a site, with Kalibr noise.

Readings come from MuJoCo's accelerometer, gyro and framequat sensors that
``build`` adds at the IMU site; the accelerometer includes gravity, so an IMU at
rest with z up reads (0, 0, +9.81) m/s^2, as a real one (and Isaac's
``readGravity``) does.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import mujoco
import torch

from ambulo.utils.rotations import mat_to_quat, quat_to_mat
from ambulo.utils.validate import Checked

from .base import Sensor, spec_body
from .imu_noise import ImuNoiseCfg, KalibrNoise, noiseless


@dataclass(kw_only=True)
class ImuCfg(Checked):
    prim_path: str
    """A site (used as is) or a body (a site is added at the offset); e.g. '/World/robot/pelvis/imu'."""
    offset_pos: tuple[float, float, float] = (0.0, 0.0, 0.0)
    """Position (m) in the mount frame, when a site is added."""
    offset_quat: tuple[float, float, float, float] = (1.0, 0.0, 0.0, 0.0)
    """Orientation (w, x, y, z) in the mount frame, when a site is added."""
    rate_hz: float | None = None
    """Sample rate in simulated time; None samples on every read (at the physics rate)."""
    noise: ImuNoiseCfg = field(default_factory=noiseless)
    seed: int = 0
    """Seed of the noise generator (same seed, same noise)."""
    include_gravity: bool = True
    """Report specific force (with gravity, like a real IMU) or acceleration without it."""


@dataclass
class ImuData:
    lin_acc_b: torch.Tensor
    """(N, 3) float64 m/s^2: specific force in the IMU frame (noise and bias included)."""
    ang_vel_b: torch.Tensor
    """(N, 3) float64 rad/s: angular velocity in the IMU frame (noise and bias included)."""
    quat_w: torch.Tensor
    """(N, 4) float64 wxyz: IMU frame orientation in the world (noiseless)."""
    time_s: torch.Tensor
    """(N,) float64 s: simulated time of the sample."""


class Imu(Sensor):
    def __init__(self, cfg: ImuCfg | None = None, **kwargs):
        cfg = cfg or ImuCfg(**kwargs)
        super().__init__(cfg.prim_path, 0.0 if not cfg.rate_hz else 1.0 / cfg.rate_hz)
        self.cfg = cfg
        self.site_name: str | None = None

    def build(self, spec: mujoco.MjSpec) -> None:
        super().build(spec)
        default_offset = tuple(self.cfg.offset_pos) == (0, 0, 0) and tuple(self.cfg.offset_quat) == (1, 0, 0, 0)
        if self.mount.site is not None and default_offset:
            self.site_name = self.mount.site
        else:
            pos, quat = list(self.cfg.offset_pos), list(self.cfg.offset_quat)
            if self.mount.site is not None:
                site = spec.site(self.mount.site)
                site_rot = quat_to_mat(site.quat)
                pos = site.pos + site_rot @ pos
                quat = mat_to_quat(site_rot @ quat_to_mat(quat))
            self.site_name = self.prim_path
            spec_body(spec, self.mount).add_site(name=self.site_name, pos=pos, quat=quat)
        for kind, stype in (("acc", mujoco.mjtSensor.mjSENS_ACCELEROMETER),
                            ("gyro", mujoco.mjtSensor.mjSENS_GYRO),
                            ("quat", mujoco.mjtSensor.mjSENS_FRAMEQUAT)):
            spec.add_sensor(name=f"{self.prim_path}:{kind}", type=stype,
                            objtype=mujoco.mjtObj.mjOBJ_SITE, objname=self.site_name)

    def initialize(self, engine) -> None:
        super().initialize(engine)
        model = engine.model
        self._adr = {k: int(model.sensor_adr[model.sensor(f"{self.prim_path}:{k}").id])
                     for k in ("acc", "gyro", "quat")}
        self._site_id = model.site(self.site_name).id
        n, dev = engine.num_worlds, engine.device
        gen = torch.Generator(device=dev).manual_seed(self.cfg.seed)
        c = self.cfg.noise
        self.accel_noise = KalibrNoise(c.accel_noise_density, c.accel_random_walk,
                                       c.accel_turn_on_bias_std, n, gen, engine.dtype)
        self.gyro_noise = KalibrNoise(c.gyro_noise_density, c.gyro_random_walk,
                                      c.gyro_turn_on_bias_std, n, gen, engine.dtype)
        f64 = dict(dtype=engine.dtype, device=dev)
        self._gravity = torch.as_tensor(model.opt.gravity, **f64)
        zeros = torch.zeros(n, 3, **f64)
        self._data = ImuData(zeros.clone(), zeros.clone(), torch.zeros(n, 4, **f64), torch.zeros(n, **f64))
        self._timestep = float(model.opt.timestep)

    def clean_reading(self) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
        """Noiseless (specific force (N, 3), angular velocity (N, 3), quat_w (N, 4)) from the engine."""
        self._require_initialized()
        s = self.engine.field("sensordata")
        acc = s[:, self._adr["acc"]:self._adr["acc"] + 3].clone()
        gyro = s[:, self._adr["gyro"]:self._adr["gyro"] + 3].clone()
        quat = s[:, self._adr["quat"]:self._adr["quat"] + 4].clone()
        if not self.cfg.include_gravity:
            rot = self.engine.field("site_xmat")[:, self._site_id].reshape(-1, 3, 3)
            acc = acc + torch.einsum("nji,j->ni", rot, self._gravity)  # R^T g removes gravity
        return acc, gyro, quat

    def get_current_frame(self) -> ImuData:
        """The latest sample; worlds whose sample period elapsed get a new noisy sample."""
        self._require_initialized()
        due = self._due()
        if due.any():
            now = self.engine.field("time")
            last = self._last_update_s
            first_dt = self.update_period_s or self._timestep
            dt = torch.where(torch.isfinite(last), now - last, torch.full_like(now, first_dt))
            dt = dt.clamp_min(1e-9)
            acc, gyro, quat = self.clean_reading()
            noisy_acc = self.accel_noise.sample(acc[None], dt, due)[0]
            noisy_gyro = self.gyro_noise.sample(gyro[None], dt, due)[0]
            d = self._data
            d.lin_acc_b[due], d.ang_vel_b[due] = noisy_acc[due], noisy_gyro[due]
            d.quat_w[due], d.time_s[due] = quat[due], now[due]
            self._mark_updated(due)
        return self._data
