"""The torch box ray caster against a hand-computed view and against Open3D's RaycastingScene."""

import math

import numpy as np
import pytest

from ambulo.perception.box_raycast import box_depth
from ambulo.perception.reference import orbit_poses
from ambulo.scenes.indoor import IndoorSceneCfg, SolidBox, build_indoor_scene

from .conftest import pinhole


def test_a_camera_above_the_floor_looking_down_sees_a_box_top_and_the_floor():
    """Camera 2 m above the floor looking straight down (OpenCV z = world -z); a 0.5 m-tall box
    under the image centre. Depth is 1.5 m on the box top, 2.0 m on the floor, by hand."""
    pose = np.eye(4)
    pose[:3, :3] = np.diag([1.0, -1.0, -1.0])
    pose[:3, 3] = (0.0, 0.0, 2.0)
    k = pinhole(64, 48, 40.0)
    depth = box_depth([SolidBox("b", (0.0, 0.0, 0.25), (0.3, 0.3, 0.25))], k, pose, 64, 48)
    assert depth[24, 32].item() == pytest.approx(1.5, abs=1e-6)
    assert depth[0, 0].item() == pytest.approx(2.0, abs=1e-6)
    # the box's edge: x = 0.3 m on the top face is at u = cx + f * 0.3 / 1.5 = 31.5 + 8 = 39.5 px
    assert depth[24, 39].item() == pytest.approx(1.5) and depth[24, 40].item() == pytest.approx(2.0)


def test_depth_equals_open3d_raycasting_on_the_indoor_scene():
    pytest.importorskip("open3d")
    from ambulo.perception.reference import TruthScene

    scene = build_indoor_scene(IndoorSceneCfg(with_robot=False, num_moving_boxes=0))
    truth = TruthScene(scene.solids)
    k = pinhole(160, 120, 131.25)
    for pose in orbit_poses((0, 0, 0.5), 2.2, 1.0, 4, turns=0.9):
        ours = box_depth(scene.solids, k, pose, 160, 120).numpy()
        ref = truth.depth(k, pose, 160, 120)
        both = (ours > 0) & (ref > 0)
        assert both.mean() > 0.95 and ((ours > 0) == (ref > 0)).mean() > 0.999
        err = np.abs(ours - ref)[both]
        # float32 ray casting in Open3D: agreement to ~1e-6 relative, except pixels whose ray grazes an
        # edge, where the two may hit different faces
        assert np.median(err) < 1e-5 and np.mean(err < 1e-3) > 0.998, (np.median(err), np.mean(err < 1e-3))
        assert math.isfinite(float(ours.max()))
