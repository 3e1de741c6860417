"""Sensors that read an engine's state (never step it), batched over worlds.

Every sensor is created with a prim path (its mount body or site) and follows the
component lifecycle (``ambulo.core.Component``): ``build(spec)`` before compilation,
``initialize(engine)`` after, ``update(dt_s)`` after physics, ``reset(world_ids)``.
"""

from .base import Mount, Sensor, resolve_mount
from .camera import ANNOTATORS, Camera, CameraCfg
from .contact import ContactData, ContactSensor, ContactSensorCfg
from .imu import Imu, ImuCfg, ImuData
from .imu_noise import ImuNoiseCfg, KalibrNoise, euroc_adis16448, noiseless
from .lidar import Lidar, LidarCfg, LidarData, lidar_2d, lidar_vlp16
from .tiled_camera import TiledCamera, TiledCameraCfg, TiledCameraData

__all__ = [
    "ANNOTATORS", "Camera", "CameraCfg", "ContactData", "ContactSensor", "ContactSensorCfg",
    "Imu", "ImuCfg", "ImuData", "ImuNoiseCfg", "KalibrNoise", "Lidar", "LidarCfg", "LidarData",
    "Mount", "Sensor", "TiledCamera", "TiledCameraCfg", "TiledCameraData", "euroc_adis16448", "lidar_2d",
    "lidar_vlp16", "noiseless", "resolve_mount",
]
