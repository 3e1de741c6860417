"""``OnlineMapper.refresh`` re-slices only the columns the fused frames changed: after every refresh
its map is, cell for cell, the body-band slice of the whole TSDF (what slicing everything would give)."""

import math
import types

import numpy as np
import pytest

from ambulo.maps import FREE, OCCUPIED, UNKNOWN, Grid2D
from ambulo.navigation.mapping import OnlineMapper, OnlineMapperCfg
from ambulo.perception.box_raycast import raycast_frames
from ambulo.perception.slices import OCCUPIED as SLICE_OCCUPIED
from ambulo.perception.slices import UNKNOWN as SLICE_UNKNOWN
from ambulo.perception.slices import occupancy_slice
from ambulo.scenes.indoor import SolidBox

ROOM = [SolidBox("north", (0.0, 2.0, 0.75), (3.0, 0.05, 0.75)), SolidBox("south", (0.0, -2.0, 0.75), (3.0, 0.05, 0.75)),
        SolidBox("east", (3.0, 0.0, 0.75), (0.05, 2.0, 0.75)), SolidBox("crate", (1.2, 0.8, 0.3), (0.3, 0.2, 0.3)),
        SolidBox("books", (0.8, -1.0, 0.06), (0.15, 0.1, 0.06), 0.4), SolidBox("post", (-1.0, 1.2, 0.5), (0.1, 0.1, 0.5))]
"""A 6 m x 4 m room open to the west: walls, a crate, a low pile of books, a post."""


def _head_poses(count: int) -> np.ndarray:
    """(count, 4, 4) camera-to-world (OpenCV axes) of a head camera 1.5 m up, pitched 18 deg down,
    walking from (-2, 0) east while turning left and right."""
    poses = []
    pitch = math.radians(18.0)
    for i in range(count):
        x, yaw = -2.0 + 3.0 * i / count, 0.9 * math.sin(2.5 * math.pi * i / count)
        forward = np.array([math.cos(yaw) * math.cos(pitch), math.sin(yaw) * math.cos(pitch), -math.sin(pitch)])
        right = np.array([math.sin(yaw), -math.cos(yaw), 0.0])
        pose = np.eye(4)
        pose[:3, :3] = np.stack([right, np.cross(forward, right), forward], -1)
        pose[:3, 3] = (x, 0.1 * math.sin(i), 1.5)
        poses.append(pose)
    return np.array(poses)


def _whole_map_slice(mapper: OnlineMapper) -> np.ndarray:
    """The mapper's cells as the slice of the whole TSDF gives them (the expected map)."""
    c, vs = mapper.cfg, mapper.cfg.tsdf.voxel_size_m
    dense = mapper.tsdf.dense(z_range_m=(c.band_m[0] - vs, c.band_m[1] + vs), color=False)
    sl = occupancy_slice(dense, *c.band_m, floor_seen_m=c.floor_seen_m).data.numpy()
    ny, nx = mapper.grid.shape
    pad = max(sl.shape) + 1
    expected = np.full((ny + 2 * pad, nx + 2 * pad), UNKNOWN, np.int8)
    sx, sy = int(dense.origin_index[0]) - mapper._k0[0] + pad, int(dense.origin_index[1]) - mapper._k0[1] + pad
    expected[sy:sy + sl.shape[0], sx:sx + sl.shape[1]] = np.where(
        sl == SLICE_OCCUPIED, OCCUPIED, np.where(sl == SLICE_UNKNOWN, UNKNOWN, FREE))
    return expected[pad:pad + ny, pad:pad + nx]


@pytest.fixture(scope="module")
def frames():
    width, height = 120, 90
    f = 525.0 * width / 640
    k = np.array([[f, 0, width / 2 - 0.5], [0, f, height / 2 - 0.5], [0, 0, 1.0]])
    return raycast_frames(ROOM, _head_poses(12), k, width, height, noise_seed=3)


@pytest.mark.parametrize("floor_seen_m", [None, 0.3])
def test_each_refresh_equals_the_slice_of_the_whole_map(frames, floor_seen_m):
    truth = Grid2D(occupancy=np.zeros((80, 120), np.int8), origin_xy_m=(-3.0, -2.0), resolution_m=0.05)
    # start_blind_radius_m and start_seen_low_radius_m 0: one slice everywhere, as the whole map's slice below is cut
    mapper = OnlineMapper(OnlineMapperCfg(update_hz=1e6, floor_seen_m=floor_seen_m, start_blind_radius_m=0.0,
                                          start_seen_low_radius_m=0.0))
    mapper.reset(types.SimpleNamespace(occupancy=truth, start_pose=(-2.0, 0.0, 0.0)))
    changes = 0
    for i, frame in enumerate(frames):
        mapper.fuse(frame, frame.pose_wc.numpy())
        if i % 2 == 1:  # frames between refreshes, as the navigator's 2 Hz against 10 Hz
            changes += mapper.refresh(float(i))
            np.testing.assert_array_equal(mapper.grid.occupancy, _whole_map_slice(mapper), err_msg=f"frame {i}")
    occ = mapper.grid.occupancy
    assert changes >= 4 and (occ == OCCUPIED).sum() > 100 and (occ == FREE).sum() > 500
