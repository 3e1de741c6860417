"""``box_kernel``: the compiled loose-box and 3D-extent loops give the NumPy path's floats bit for bit
(a dataset is the same with and without numba), on hand-made boxes whose answers are known and on
random ones crossing the near plane and the image's edges."""

import numpy as np
import pytest

from ambulo.sensors import annotators, box_kernel

needs_numba = pytest.mark.skipif(not box_kernel.HAVE_NUMBA, reason="numba is not installed (the data extra)")
K_MATRIX = np.array([[200.0, 0.0, 159.5], [0.0, 200.0, 119.5], [0.0, 0.0, 1.0]])
WIDTH, HEIGHT, NEAR_M = 320, 240, 0.05


def cube_corners(center_c, half) -> np.ndarray:
    """(8, 3) corners of an axis-aligned box in the camera frame (x right, y down, z forward), m."""
    return np.asarray(center_c, float) + annotators._CUBE * np.asarray(half, float)


def hand_made() -> tuple[np.ndarray, np.ndarray]:
    """Four instances: a box in view, one straddling the near plane, one behind the camera, and two
    geoms of one instance, one of them beyond the image's right edge."""
    geoms = [cube_corners((0.0, 0.0, 2.0), (0.1, 0.1, 0.1)),      # 0: in view, centred
             cube_corners((0.0, 0.0, 0.0), (0.2, 0.2, 0.5)),      # 1: crosses the near plane
             cube_corners((0.0, 0.0, -3.0), (0.2, 0.2, 0.2)),     # 2: behind the camera
             cube_corners((-0.5, 0.0, 1.0), (0.05, 0.05, 0.05)),  # 3: with 4, one instance
             cube_corners((5.0, 0.2, 1.0), (0.05, 0.05, 0.05))]
    return np.stack(geoms), np.array([0, 1, 2, 3])


def random_cases(count=40):
    rng = np.random.default_rng(7)
    for _ in range(count):
        g = int(rng.integers(1, 12))
        centers = rng.normal(0.0, 1.0, (g, 1, 3)) + (0.0, 0.0, rng.uniform(-0.5, 3.0))
        corners = centers + rng.normal(0.0, 0.4, (g, 8, 3))  # any eight points, near and far
        starts = np.flatnonzero(np.concatenate(([True], rng.random(g - 1) < 0.5)))
        yield corners, starts


@needs_numba
def test_hand_made_loose_boxes_are_the_projected_corners_clipped_and_cut_at_the_near_plane():
    corners, starts = hand_made()
    got = box_kernel.loose_boxes_of_corners(corners, starts, NEAR_M, K_MATRIX, WIDTH, HEIGHT)
    np.testing.assert_array_equal(got, annotators._loose_boxes_numpy(corners, starts, NEAR_M, K_MATRIX,
                                                                     WIDTH, HEIGHT))
    # in view: the nearest face (z = 1.9) spans +-0.1 m, 200 px/m at 1.9 m around the principal point
    half_px = 200 * 0.1 / 1.9
    np.testing.assert_allclose(got[0], [159.5 - half_px, 119.5 - half_px, 159.5 + half_px, 119.5 + half_px])
    # across the near plane: the edges cut at z = 0.05 m project far outside; clipped to the whole image
    np.testing.assert_array_equal(got[1], [-0.5, -0.5, WIDTH - 0.5, HEIGHT - 0.5])
    # behind the camera: no point in front, so no box (lo above hi after the clip)
    assert not np.all(got[2, 2:] > got[2, :2])
    # two geoms: the left one's corners and the other clipped at the right edge
    assert got[3, 0] == pytest.approx(159.5 + 200 * -0.55 / 0.95)
    assert got[3, 2] == WIDTH - 0.5


@needs_numba
def test_random_loose_boxes_equal_the_numpy_path_bit_for_bit():
    for corners, starts in random_cases():
        for near in (NEAR_M, 0.5):
            want = annotators._loose_boxes_numpy(corners, starts, near, K_MATRIX, WIDTH, HEIGHT)
            got = box_kernel.loose_boxes_of_corners(corners, starts, near, K_MATRIX, WIDTH, HEIGHT)
            assert got.tobytes() == want.tobytes()


@needs_numba
def test_extents_are_the_minimum_and_maximum_of_each_instances_corners():
    corners, starts = hand_made()
    lo, hi = box_kernel.extents_of_corners(corners, starts)
    np.testing.assert_array_equal(lo[3], [-0.55, -0.05, 0.95])
    np.testing.assert_array_equal(hi[3], [5.05, 0.25, 1.05])
    for corners, starts in random_cases():
        lo, hi = box_kernel.extents_of_corners(corners, starts)
        assert lo.tobytes() == np.minimum.reduceat(corners.min(1), starts).tobytes()
        assert hi.tobytes() == np.maximum.reduceat(corners.max(1), starts).tobytes()
