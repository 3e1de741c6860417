"""Ray-cast lidar: 2D scans and 3D multi-channel point clouds, batched with mujoco's ray casts.

Sensor frame: x forward, y left, z up. A ray of azimuth a (from +x towards +y)
and elevation e (up from the xy plane) points along
(cos e cos a, cos e sin a, sin e).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import torch

from ambulo.utils.checks import (
    InvalidValueError,
    check_int,
    check_positive,
    check_quat,
    check_range,
    check_vector,
)
from ambulo.utils.rotations import quat_to_mat
from ambulo.utils.validate import Checked

from .base import MountPose, Sensor


@dataclass(kw_only=True)
class LidarCfg(Checked):
    prim_path: str
    """Mount body or site (the lidar's own path below it also works)."""
    offset_pos: tuple[float, float, float] = (0.0, 0.0, 0.0)
    """Position (m) in the mount frame."""
    offset_quat: tuple[float, float, float, float] = (1.0, 0.0, 0.0, 0.0)
    """Orientation (w, x, y, z) in the mount frame."""
    horizontal_fov_deg: float = 360.0
    horizontal_resolution_deg: float = 1.0
    elevations_deg: tuple[float, ...] = (0.0,)
    """Channel elevations (deg); one channel at 0 is a 2D scan."""
    min_range_m: float = 0.1
    max_range_m: float = 30.0
    range_noise_std_m: float = 0.0
    """Gaussian range noise (m)."""
    seed: int = 0
    rate_hz: float | None = None
    exclude_mount_body: bool = True
    """Rays ignore the body the lidar is mounted on."""

    def __post_init__(self):
        """Refuse angles and ranges no scanner can have (one line: the field, why, the fix)."""
        fov = check_positive("horizontal_fov_deg", self.horizontal_fov_deg, "pass degrees in (0, 360], e.g. 360")
        if fov > 360:
            raise InvalidValueError("horizontal_fov_deg", fov, "a scan covers at most a full circle",
                                    "pass degrees in (0, 360], e.g. 360")
        step = check_positive("horizontal_resolution_deg", self.horizontal_resolution_deg,
                              "pass degrees > 0 between rays, e.g. 1.0")
        if step > fov:
            raise InvalidValueError("horizontal_resolution_deg", step, f"coarser than the {fov:g} deg field of view",
                                    "pass a step no larger than horizontal_fov_deg")
        fix = "pass (min, max) m with 0 <= min < max, e.g. min_range_m=0.1, max_range_m=30"
        check_range("(min_range_m, max_range_m)", (self.min_range_m, self.max_range_m), fix)
        check_positive("range_noise_std_m", self.range_noise_std_m, "pass m >= 0 (0: no noise)", allow_zero=True)
        elevations = self.elevations_deg
        if isinstance(elevations, (str, bytes)) or not hasattr(elevations, "__len__") or len(elevations) == 0:
            raise InvalidValueError("elevations_deg", elevations, "expected one angle per channel",
                                    "pass degrees, e.g. (0.0,) for a 2D scan")
        bad = [e for e in check_vector("elevations_deg", elevations, len(elevations), "pass finite degrees")
               if abs(e) > 90]
        if bad:
            raise InvalidValueError("elevations_deg", elevations, f"{bad[0]:g} deg is beyond straight up or down",
                                    "pass degrees in [-90, 90]")
        if self.rate_hz is not None:
            check_positive("rate_hz", self.rate_hz, "pass Hz > 0, or None to scan on every read")
        check_vector("offset_pos", self.offset_pos, 3, "pass (x, y, z) m in the mount frame")
        check_quat("offset_quat", self.offset_quat)
        check_int("seed", self.seed, "pass a whole number")
        super().__post_init__()


def lidar_2d(prim_path: str, **kwargs) -> LidarCfg:
    """A planar 360 deg scanner, 1 deg steps, 0.1-30 m (RPLidar-like)."""
    return LidarCfg(prim_path=prim_path, **kwargs)


def lidar_vlp16(prim_path: str, **kwargs) -> LidarCfg:
    """Velodyne VLP-16: 16 channels from -15 to +15 deg, 0.2 deg azimuth steps, 100 m."""
    defaults = {"elevations_deg": tuple(np.linspace(-15, 15, 16)), "horizontal_resolution_deg": 0.2,
                    "min_range_m": 0.5, "max_range_m": 100.0, "range_noise_std_m": 0.03}
    defaults.update(kwargs)
    return LidarCfg(prim_path=prim_path, **defaults)


@dataclass
class LidarData:
    ranges: torch.Tensor
    """(N, V, H) float64 m; ``max_range_m`` where nothing was hit."""
    hit: torch.Tensor
    """(N, V, H) bool: a return within [min_range_m, max_range_m]."""
    points_s: torch.Tensor
    """(N, V*H, 3) float64 m, sensor frame (misses at max range)."""
    points_w: torch.Tensor
    """(N, V*H, 3) float64 m, world frame."""
    geom_ids: torch.Tensor
    """(N, V, H) int32: geom hit, -1 for none."""


class Lidar(Sensor):
    def __init__(self, cfg: LidarCfg | None = None, **kwargs):
        cfg = cfg or LidarCfg(**kwargs)
        super().__init__(cfg.prim_path, 0.0 if not cfg.rate_hz else 1.0 / cfg.rate_hz)
        self.cfg = cfg
        fov, step = cfg.horizontal_fov_deg, cfg.horizontal_resolution_deg
        count = max(1, round(fov / step))
        # a full circle would repeat its first ray at 360 deg; a sector includes both edges
        azimuths = np.arange(count) * step if fov >= 360 else -fov / 2 + np.arange(count + 1) * step
        self.azimuths_rad = np.radians(azimuths)
        self.elevations_rad = np.radians(np.asarray(cfg.elevations_deg, float))
        ce, se = np.cos(self.elevations_rad)[:, None], np.sin(self.elevations_rad)[:, None]
        ca, sa = np.cos(self.azimuths_rad)[None], np.sin(self.azimuths_rad)[None]
        self.directions_s = np.stack(np.broadcast_arrays(ce * ca, ce * sa, se), -1).reshape(-1, 3)
        """(V*H, 3) unit ray directions in the sensor frame."""

    @property
    def shape(self) -> tuple[int, int]:
        return len(self.elevations_rad), len(self.azimuths_rad)

    def initialize(self, engine) -> None:
        super().initialize(engine)
        self._mount_pose = MountPose(engine, self.mount)
        f64 = dict(dtype=engine.dtype, device=engine.device)
        self._rot_ms = torch.as_tensor(quat_to_mat(np.asarray(self.cfg.offset_quat, float)), **f64)
        self._offset_m = torch.as_tensor(self.cfg.offset_pos, **f64)
        self._dirs_s = torch.as_tensor(self.directions_s, **f64)
        self._gen = torch.Generator(device=engine.device).manual_seed(self.cfg.seed)
        self._data = None

    @property
    def last_frame(self) -> LidarData | None:
        """The last scan (None before the first) without scanning: what a watcher shows at no cost."""
        return getattr(self, "_data", None)

    def get_current_frame(self) -> LidarData:
        self._require_initialized()
        if self._data is not None and not bool(self._due().any()):
            return self._data
        n = self.engine.num_worlds
        mount_pos, mount_rot = self._mount_pose.pos_w(), self._mount_pose.rot_w()
        origin = mount_pos + mount_rot @ self._offset_m          # (N, 3) world frame
        rot_ws = mount_rot @ self._rot_ms                        # (N, 3, 3) sensor axes in world
        dirs_w = torch.einsum("nij,rj->nri", rot_ws, self._dirs_s)
        exclude = self._mount_pose.body_id if self.cfg.exclude_mount_body and self._mount_pose.body_id > 0 else -1
        dist, geom = self.engine.ray(origin[:, None].expand_as(dirs_w), dirs_w, bodyexclude=exclude)
        dist, geom = dist.to(origin.device), geom.to(origin.device)
        if self.cfg.range_noise_std_m > 0:
            dist = dist + self.cfg.range_noise_std_m * torch.randn(
                dist.shape, generator=self._gen, dtype=dist.dtype, device=dist.device)
        hit = (geom >= 0) & (dist >= self.cfg.min_range_m) & (dist <= self.cfg.max_range_m)
        ranges = torch.where(hit, dist, torch.full_like(dist, self.cfg.max_range_m))
        points_s = ranges[..., None] * self._dirs_s
        points_w = origin[:, None] + torch.einsum("nij,nrj->nri", rot_ws, points_s)
        v, h = self.shape
        geom_ids = torch.where(hit, geom, torch.full_like(geom, -1)).to(torch.int32)
        self._data = LidarData(ranges=ranges.reshape(n, v, h), hit=hit.reshape(n, v, h), points_s=points_s,
                               points_w=points_w, geom_ids=geom_ids.reshape(n, v, h))
        self._mark_updated(torch.ones(n, dtype=torch.bool, device=origin.device))
        return self._data
