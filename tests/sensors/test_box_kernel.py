"""``box_kernel``: the compiled loose-box and 3D-extent loops give the NumPy path's floats bit for bit
(a dataset is the same with and without numba), on hand-made boxes whose answers are known and on
random ones crossing the near plane and the image's edges."""

import subprocess
import sys

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


def hand_made_table() -> annotators.InstanceTable:
    """``hand_made``'s five geoms as four instances (the last two geoms one instance), bodies 1-4."""
    return annotators.InstanceTable(body_ids=np.array([1, 2, 3, 4]), labels=["a", "b", "c", "d"], categories=["a", "b", "c", "d"],
                                    semantic_ids=np.array([0, 1, 2, 3, 4]), names=["1", "2", "3", "4"],
                                    geom_instance=np.array([0, 1, 2, 3, 4, 4], np.int32))


@needs_numba
def test_the_annotators_take_the_kernels_once_warmed_up_with_the_same_outputs(monkeypatch):
    corners, _ = hand_made()
    table = hand_made_table()
    extr = np.eye(4)  # the corners are in the camera frame already
    rng = np.random.default_rng(3)
    body_pos, body_rot = rng.normal(size=(5, 3)), np.linalg.qr(rng.normal(size=(5, 3, 3)))[0]

    def boxes():
        loose = annotators.loose_box_array(table, None, None, None, extr, K_MATRIX, WIDTH, HEIGHT, NEAR_M, corners)
        return *loose, *annotators.instance_boxes_3d(table, None, body_pos, body_rot, None, None, corners)

    monkeypatch.setattr(box_kernel, "_active", False)
    numpy_path = boxes()
    box_kernel.warm_up()
    assert box_kernel.active()
    calls = []
    monkeypatch.setattr(box_kernel, "_loose", lambda *a: calls.append("loose") or box_kernel._loose_py(*a))
    monkeypatch.setattr(box_kernel, "_extents", lambda *a: calls.append("3d") or box_kernel._extents_py(*a))
    kernel_path = boxes()
    assert calls == ["loose", "3d"]
    np.testing.assert_array_equal(numpy_path[0], [1, 2, 4])  # instance 3 is behind the camera
    for got, want in zip(kernel_path, numpy_path):
        assert got.tobytes() == want.tobytes()


def test_a_camera_that_never_warmed_the_kernels_does_not_import_numba():
    code = ("import sys, numpy as np\n"
            "from ambulo.sensors import annotators\n"
            "import test_box_kernel as t\n"
            "corners, _ = t.hand_made()\n"
            "annotators.loose_box_array(t.hand_made_table(), None, None, None, np.eye(4), t.K_MATRIX, 320, 240, 0.05,"
            " corners)\n"
            "assert 'numba' not in sys.modules, 'numba imported'\n")
    done = subprocess.run([sys.executable, "-c", code], cwd=__file__.rsplit("/", 1)[0], capture_output=True, text=True)
    assert done.returncode == 0, done.stderr
