"""CPU/CUDA parity of the torch semi-global matcher (``ambulo.perception.stereo.sgm``): its costs
are integers held in float32, so both devices give the same disparities; the CUDA graph replays
what eager CUDA computes. Skipped without a CUDA device.

This folder's conftest needs Open3D; on a machine without it run
``pytest --noconftest tests/perception/stereo/test_cuda.py`` (these tests use no fixture)."""

import numpy as np
import pytest
import torch

from ambulo.perception.stereo.sgm import CudaGraphSgm, SgmCfg, sgm_disparity

pytestmark = pytest.mark.skipif(not torch.cuda.is_available(), reason="no CUDA device")


def textured_pair(seed: int, shape=(120, 200, 3), shift_px: int = 9) -> tuple[torch.Tensor, torch.Tensor]:
    """Random RGB texture and the same texture seen ``shift_px`` further right (left[x] = right[x - shift])."""
    gen = torch.Generator().manual_seed(seed)
    right = (torch.rand(shape, generator=gen) * 256).to(torch.uint8)
    left = torch.cat([right[:, :shift_px].flip(1), right[:, :-shift_px]], 1)
    return left, right


def assert_same_disparity(a: torch.Tensor, b: torch.Tensor) -> None:
    a, b = a.cpu().numpy(), b.cpu().numpy()
    np.testing.assert_array_equal(np.isnan(a), np.isnan(b))
    np.testing.assert_allclose(a, b, rtol=0, atol=1e-5, equal_nan=True)


@pytest.mark.parametrize("paths", [4, 8])
def test_cuda_disparity_equals_the_cpu(paths):
    cfg = SgmCfg(num_disparities=32, paths=paths)
    left, right = textured_pair(0)
    assert_same_disparity(sgm_disparity(left, right, cfg), sgm_disparity(left.cuda(), right.cuda(), cfg))


def test_cuda_equals_the_cpu_on_the_middlebury_pair():
    data = pytest.importorskip("skimage.data")
    left, right, _ = data.stereo_motorcycle()
    left, right = torch.from_numpy(left), torch.from_numpy(right)
    on_cuda = sgm_disparity(left.cuda(), right.cuda())
    assert on_cuda.device.type == "cuda"
    assert_same_disparity(sgm_disparity(left, right), on_cuda)


def test_cuda_graph_replays_eager_cuda_for_new_images():
    cfg = SgmCfg(num_disparities=32)
    first, second = textured_pair(1), textured_pair(2, shift_px=5)
    graphed = CudaGraphSgm(first[0].shape, cfg)
    for left, right in (first, second, first):
        left, right = left.cuda(), right.cuda()
        assert_same_disparity(graphed(left, right), sgm_disparity(left, right, cfg))
