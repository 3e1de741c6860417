"""``mask_kernel``: numba's one pass gives the NumPy path's tight boxes, pixel counts and COCO RLE bytes,
and both equal the per-instance computations (``nonzero`` boxes, ``mask_utils.encode``)."""

import numpy as np
import pytest
from pycocotools import mask as mask_utils
from test_fast_paths import boxes_one_by_one, hand_made_segmentations, random_segmentations

from ambulo.replicator import mask_kernel

needs_numba = pytest.mark.skipif(not mask_kernel.HAVE_NUMBA, reason="numba is not installed (the data extra)")
K = 6


def segmentations() -> list[np.ndarray]:
    rng = np.random.default_rng(5)
    # blocky images (long runs that wrap from the bottom of a column to the top of the next one, as a
    # rendered object's do), a tall and a wide strip, and the hand-made and random ones
    blocky = [np.kron(rng.integers(0, K + 1, (6, 8)), np.ones((5, 4), np.int64)).astype(np.int32)[:h, :w]
              for h, w in ((30, 32), (27, 29), (1, 32), (30, 1))]
    return hand_made_segmentations() + random_segmentations() + blocky


@needs_numba
@pytest.mark.parametrize("seg", segmentations())
def test_the_compiled_pass_equals_the_numpy_path_and_the_per_instance_masks(seg):
    ids = np.arange(1, K + 1)
    got, numpy_path = mask_kernel.numba_masks(seg, K), mask_kernel.numpy_masks(seg, K)
    want_boxes, want_pixels = boxes_one_by_one(seg, K)
    np.testing.assert_array_equal(got.boxes, want_boxes)
    np.testing.assert_array_equal(got.pixels, want_pixels)
    np.testing.assert_array_equal(numpy_path.boxes, want_boxes)
    np.testing.assert_array_equal(numpy_path.pixels, want_pixels)
    encoded = [mask_utils.encode(np.asfortranarray((seg == i).astype(np.uint8))) for i in ids]
    for rles in (got.rles(ids), numpy_path.rles(ids)):
        assert [r["counts"] for r in rles] == [e["counts"] for e in encoded]
        assert [list(r["size"]) for r in rles] == [list(e["size"]) for e in encoded]
    # any subset, in any order, as frame_annotations asks for the instances it keeps
    some = ids[::-2]
    assert [r["counts"] for r in got.rles(some)] == [r["counts"] for r in numpy_path.rles(some)]
    # pycocotools reads the strings back to the same boxes and areas
    visible = [i for i in ids if want_pixels[i - 1]]
    if visible:
        rles = got.rles(visible)
        np.testing.assert_array_equal(mask_utils.area(rles), want_pixels[np.asarray(visible) - 1])
        x0, y0, x1, y1 = want_boxes[np.asarray(visible) - 1].T
        np.testing.assert_array_equal(mask_utils.toBbox(rles), np.stack([x0, y0, x1 - x0 + 1, y1 - y0 + 1], 1))


@needs_numba
def test_ids_outside_the_table_are_refused():
    seg = np.zeros((4, 4), np.int32)
    seg[2, 3] = K + 1
    with pytest.raises(ValueError, match="0..num_instances"):
        mask_kernel.numba_masks(seg, K)
    seg[2, 3] = -1
    with pytest.raises(ValueError, match="0..num_instances"):
        mask_kernel.numba_masks(seg, K)
