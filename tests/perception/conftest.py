"""Shared fixtures of the perception tests: a small box scene with exact Open3D ground truth."""

import numpy as np
import pytest
import torch

try:  # a skip raised while a conftest imports is a collection error for the whole run (the GPU suite's)
    import open3d  # noqa: F401  (the reference every test here checks against)
except ImportError:
    collect_ignore_glob = ["*"]


@pytest.fixture(scope="session")
def room():
    """The seeded indoor scene's solids without the robot (static geometry only)."""
    from ambulo.scenes.indoor import IndoorSceneCfg, build_indoor_scene

    return build_indoor_scene(IndoorSceneCfg(with_robot=False, num_moving_boxes=0))


@pytest.fixture(scope="session")
def truth(room):
    from ambulo.perception.reference import TruthScene

    return TruthScene(room.solids)


def pinhole(width: int, height: int, focal: float) -> np.ndarray:
    return np.array([[focal, 0, width / 2 - 0.5], [0, focal, height / 2 - 0.5], [0, 0, 1.0]])


OFFSET = np.array([0.013, 0.021, 0.017])
"""A world shift so that no wall or floor plane falls exactly on voxel centres (a scene aligned with
the grid favours whichever grid convention happens to match it)."""


def shifted(frames, offset=OFFSET):
    """Frames with camera poses moved by ``offset`` (the whole world shifted)."""
    out = []
    for f in frames:
        pose = f.pose_wc.clone()
        pose[:3, 3] += torch.from_numpy(offset)
        out.append(type(f)(f.depth_m, f.rgb, f.intrinsics, pose, f.time_s))
    return out
