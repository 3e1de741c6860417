"""Stereo depth (optional part of issue 13): SGBM on the Middlebury 2014 Motorcycle pair that
scikit-image ships with its ground-truth disparity (Scharstein et al., GCPR 2014)."""

import numpy as np
import pytest

from ambulo.perception.stereo import disparity_to_depth, sgbm_disparity


def test_sgbm_matches_the_middlebury_ground_truth():
    data = pytest.importorskip("skimage.data")
    left, right, truth = data.stereo_motorcycle()
    disparity = sgbm_disparity(left, right)
    known = np.isfinite(truth)
    both = known & np.isfinite(disparity)
    error = np.abs(disparity[both] - truth[both])
    assert both.sum() / known.sum() > 0.8  # density
    assert (error > 2.0).mean() < 0.08  # Middlebury's "bad 2.0" metric: 5.9 % here
    assert np.median(error) < 0.3


def test_disparity_to_depth_is_f_times_baseline_over_disparity():
    disparity = np.array([[10.0, np.nan, 40.0, -1.0]], np.float32)
    depth = disparity_to_depth(disparity, focal_px=500.0, baseline_m=0.1)
    np.testing.assert_allclose(depth, [[5.0, 0.0, 1.25, 0.0]])
