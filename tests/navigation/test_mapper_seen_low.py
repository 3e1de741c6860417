"""Near its start, the navigator's map reads a cell free only where the body band was seen free low
enough to show the furniture a humanoid's thighs and arms meet (``OnlineMapperCfg.start_seen_low_m``):
a column seen free only at head height, by rays passing over a bed or a table the head camera never
saw (beside the robot, or nearer than its view of that height), is unknown there, not free."""

import math
import types

import numpy as np
import torch

from ambulo.maps import FREE, Grid2D
from ambulo.navigation.mapping import OnlineMapper, OnlineMapperCfg
from ambulo.perception import slices
from ambulo.perception.box_raycast import raycast_frames
from ambulo.perception.tsdf.map import DenseGrid
from ambulo.scenes.indoor import SolidBox

VOXEL_M, TRUNCATION_M = 0.05, 0.2


def _grid(columns: list[tuple[float | None, float]]) -> DenseGrid:
    """(len(columns), 1, 36) voxels, centres at z = 0 ... 1.75 m; column i: ``(surface_z_m, seen_from_z_m)``:
    observed from ``seen_from_z_m`` up (free above ``surface_z_m``, a solid below it; None: no surface),
    unobserved below."""
    z = torch.arange(36, dtype=torch.float32) * VOXEL_M
    tsdf = torch.ones(len(columns), 1, 36)
    weight = torch.zeros(len(columns), 1, 36)
    for i, (surface_z_m, seen_from_z_m) in enumerate(columns):
        sdf_m = torch.full_like(z, TRUNCATION_M) if surface_z_m is None else z - surface_z_m
        seen = z >= seen_from_z_m - 1e-6
        tsdf[i, 0, seen] = (sdf_m[seen] / TRUNCATION_M).clamp(-1.0, 1.0)
        weight[i, 0, seen] = 5.0
    return DenseGrid(tsdf, weight, torch.zeros(len(columns), 1, 36, 3, dtype=torch.uint8),
                     torch.zeros(3, dtype=torch.int64), VOXEL_M, TRUNCATION_M)


SEEN_LOW_M = 0.9
"""The rule's height (off by default): what the device run measured."""


def test_the_start_slice_calls_a_column_seen_free_only_at_head_height_unknown():
    cfg = OnlineMapperCfg(start_seen_low_m=SEEN_LOW_M)
    grid = _grid([
        (None, 1.35),  # apartment 72: rays passed over a 0.55 m bed at 1.35-1.55 m only; a thigh met it
        (None, 1.05),  # apartment 11: over a 0.75 m table top, seen free from 1.05 m up; a forearm met it
        (None, 0.5),  # open floor seen at thigh height
        (0.55, 0.4),  # a bed's top seen from above
    ])
    data = slices.occupancy_slice(grid, *cfg.band_m, floor_seen_m=cfg.start_seen_low_m).data[0].tolist()
    assert data == [slices.UNKNOWN, slices.UNKNOWN, slices.FREE, slices.OCCUPIED]


def _camera_at(x_m: float, yaw_rad: float) -> np.ndarray:
    """(4, 4) camera-to-world (OpenCV axes) of the head camera 1.5 m up at (x_m, 0), pitched 18 deg down."""
    pitch = math.radians(18.0)
    forward = np.array([math.cos(yaw_rad) * math.cos(pitch), math.sin(yaw_rad) * math.cos(pitch), -math.sin(pitch)])
    right = np.array([math.sin(yaw_rad), -math.cos(yaw_rad), 0.0])
    pose = np.eye(4)
    pose[:3, :3] = np.stack([right, np.cross(forward, right), forward], -1)
    pose[:3, 3] = (x_m, 0.0, 1.5)
    return pose


def test_a_bed_beside_the_start_under_the_camera_view_is_not_free():
    # the robot starts 0.3 m from a 0.55 m bed and turns to face it: its head camera's lowest rays
    # reach 0.94 m (the top of floor_seen_m) 0.6 m ahead, so the bed's near part (0.3-0.6 m) is seen
    # free only by rays passing over it at head height; the floor beyond (> 0.6 m from the start) stays
    # free where seen at any height of the band
    bed = SolidBox("bed", (0.7, 0.0, 0.275), (0.4, 0.5, 0.275))
    wall = SolidBox("wall", (3.5, 0.0, 1.0), (0.05, 3.0, 1.0))
    width, height = 96, 72
    f = 525.0 * width / 640
    k = np.array([[f, 0, width / 2 - 0.5], [0, f, height / 2 - 0.5], [0, 0, 1.0]])
    poses = np.array([_camera_at(0.0, yaw) for yaw in np.linspace(-0.3, 0.3, 5)])
    frames = raycast_frames([bed, wall], poses, k, width, height, noise_seed=1)
    truth = Grid2D(occupancy=np.zeros((80, 100), np.int8), origin_xy_m=(-1.0, -2.0), resolution_m=0.05)
    mapper = OnlineMapper(OnlineMapperCfg(update_hz=1e6, start_seen_low_m=SEEN_LOW_M))
    mapper.reset(types.SimpleNamespace(occupancy=truth, start_pose=(0.0, 0.0, 0.0)))
    for frame in frames:
        mapper.fuse(frame, frame.pose_wc.numpy())
    mapper.refresh(1.0)
    g = mapper.grid
    cx, cy = g.cell_center_xy_m(*np.mgrid[0:g.shape[0], 0:g.shape[1]])
    on_bed = (cx > 0.3) & (cx < 0.55) & (np.abs(cy) < 0.25)  # the near part, within 0.6 m of the start
    beyond = (cx > 1.2) & (cx < 3.3) & (np.abs(cy) < 0.4)  # the bed's far end and the floor, before the wall
    assert (g.occupancy[on_bed] != FREE).all(), "a bed cell seen only over its top at head height reads free"
    assert (g.occupancy[beyond] == FREE).mean() > 0.9
