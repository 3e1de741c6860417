"""``device_rle``: the batch's COCO RLE counts found on the device give ``coco.instance_rles``' bytes.

The masks of a dataset made on the GPU must be the CPU path's strings, byte for byte: checked on
hand-made images (an instance at the first pixel, one at the last, one absent, one split into
many runs) and on noise over many instances, through pycocotools' decode too.
"""

from __future__ import annotations

import numpy as np
import pytest
import torch
from pycocotools import mask as mask_utils

from ambulo.replicator.coco import instance_rles
from ambulo.replicator.device_rle import frame_rles, rle_counts


def _images() -> np.ndarray:
    rng = np.random.default_rng(3)
    images = np.zeros((4, 9, 13), np.int32)
    images[0, 0, 0] = 1  # the first pixel (no leading zeros)
    images[0, 2:5, 3:9] = 2
    images[0, 8, 12] = 3  # the last pixel (no zeros after it)
    images[1] = rng.integers(0, 6, size=(9, 13))  # noise: many runs of every instance
    images[2, :, 4] = 4  # a full column: one run
    images[3] = 5  # every pixel one instance
    return images


@pytest.mark.parametrize("device", ["cpu", pytest.param("cuda", marks=pytest.mark.skipif(
    not torch.cuda.is_available(), reason="needs CUDA"))])
def test_device_counts_compress_to_the_hosts_rles(device):
    images, k = _images(), 5
    counts, offsets, lengths = (t.cpu().numpy() for t in rle_counts(torch.as_tensor(images, device=device), k))
    compared = 0
    for n, image in enumerate(images):
        ids = np.arange(1, k + 1)
        present = ids[[bool((image == i).any()) for i in ids]]
        want = instance_rles(image, present)
        got = frame_rles(counts, offsets, lengths, n, k, present, *image.shape)
        assert [r["counts"] for r in got] == [r["counts"] for r in want], n
        for rle, iid in zip(got, present.tolist()):
            np.testing.assert_array_equal(mask_utils.decode(rle), (image == iid).astype(np.uint8))
            compared += 1
    assert compared == 3 + 5 + 1 + 1
    # an instance with no pixel is one run of zeros (the whole image)
    assert lengths[2 * k + 0] == 1 and counts[offsets[2 * k]] == images[2].size


def test_device_counts_of_a_rendered_sized_batch():
    rng = np.random.default_rng(8)
    images = np.zeros((3, 48, 64), np.int32)
    for n in range(3):  # boxes over each other, like objects on a floor
        for iid in rng.permutation(np.arange(1, 9)):
            y, x = rng.integers(0, 40), rng.integers(0, 56)
            images[n, y:y + rng.integers(2, 20), x:x + rng.integers(2, 30)] = iid
    counts, offsets, lengths = (t.numpy() for t in rle_counts(torch.as_tensor(images), 8))
    for n, image in enumerate(images):
        present = np.unique(image[image > 0])
        want = instance_rles(image, present)
        assert [r["counts"] for r in frame_rles(counts, offsets, lengths, n, 8, present, 48, 64)] == \
            [r["counts"] for r in want]


class _Pool:
    """What ``batched_disk._submit_parts`` hands a draw pool: the calls, kept."""

    workers = 3

    def __init__(self):
        self.calls = []

    def submit_call(self, fn, *args):
        self.calls.append(args)


def test_each_process_gets_its_frames_run_lengths():
    from ambulo.replicator import batched_disk

    images = _images()[[1, 0, 3, 2, 1]]  # 5 frames over 3 processes: parts of 2, 2 and 1
    rle = tuple(t.numpy() for t in rle_counts(torch.as_tensor(images), 5))
    pool = _Pool()
    block = type("Block", (), {"spec": None})()
    small = {"boxes": np.zeros((5, 5, 4))}
    batched_disk._submit_parts(pool, block, list(range(5)), [{}] * 5, small, None, rle=rle, out="out", writer_cfg=None,
                               fsync_files=False)
    assert [call[1] for call in pool.calls] == [0, 2, 4]  # each part's first world
    for call in pool.calls:
        start, part_rle = call[1], call[6]
        for i, image in enumerate(images[start:start + len(call[2])]):
            present = np.unique(image[image > 0])
            got = frame_rles(*part_rle, i, 5, present, *image.shape)
            assert [r["counts"] for r in got] == [r["counts"] for r in instance_rles(image, present)]
