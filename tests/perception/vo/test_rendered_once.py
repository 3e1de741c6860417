"""The VO tests' shared walks (``rendered_once.RenderedOnce``) replay exactly what a fresh walk renders."""

import numpy as np

from ambulo.perception.sources.head_camera_walk import HeadCameraWalk
from ambulo.scenes.indoor import build_indoor_scene

from .rendered_once import RenderedOnce


def test_a_replayed_frame_is_the_rendered_one():
    """Frames asked out of order and twice equal a fresh walk's in order: images, pose, time, gyro;
    and a test that writes into its frame does not change the next test's."""
    scene = build_indoor_scene()
    fresh = HeadCameraWalk(scene, width=80, height=60)
    expected = [fresh.frame(i) for i in range(6)]
    fresh.close()
    shared = RenderedOnce(HeadCameraWalk(scene, width=80, height=60))
    for order in ([4, 0, 1, 2], [0, 1, 2, 3, 4, 5]):
        for i in order:
            got, want = shared.frame(i), expected[i]
            np.testing.assert_array_equal(got.rgb.numpy(), want.rgb.numpy())
            np.testing.assert_array_equal(got.depth_m.numpy(), want.depth_m.numpy())
            np.testing.assert_array_equal(got.pose_wc.numpy(), want.pose_wc.numpy())
            assert got.time_s == want.time_s
            assert (got.gyro is None) == (want.gyro is None) == (i == 0)  # no interval before frame 0
            if i:
                np.testing.assert_array_equal(got.gyro.time_s, want.gyro.time_s)
                np.testing.assert_array_equal(got.gyro.ang_vel_rad_s, want.gyro.ang_vel_rad_s)
            got.rgb.zero_()  # a consumer writing into its frame
            got.depth_m.fill_(0.5)
    # the walk takes its extrinsic from the first frame it renders (4 here): equal up to rounding
    np.testing.assert_allclose(shared.pose_cam_imu, fresh.pose_cam_imu, rtol=0, atol=1e-12)
    shared.release()
